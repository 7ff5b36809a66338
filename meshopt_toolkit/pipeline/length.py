"""Lengths given as an absolute value or a percentage of the bounding-box diagonal
(MeshLab's ``RichAbsPerc``), and how MeshLab writes floats."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Length", "meshlab_float"]


def meshlab_float(x: float) -> str:
    """Floats as MeshLab writes them (6 significant digits) unless more are needed."""
    short = f"{x:.6g}"
    return short if float(short) == x else repr(float(x))


@dataclass(frozen=True)
class Length:
    """An absolute length or a percentage of the bounding-box diagonal (MeshLab AbsPerc).

    Parameters
    ----------
    value : float
        The length, or the percentage when ``percent``.
    percent : bool
        Whether ``value`` is a percentage of the diagonal.

    Examples
    --------
    >>> Length.parse("5%").resolve(diameter=2.0)
    0.1
    """

    value: float
    percent: bool = False

    @classmethod
    def parse(cls, raw: Any) -> Length:
        """From a number (absolute), ``"5%"`` (percentage), ``"0.1"`` or a Length."""
        if isinstance(raw, Length):
            return raw
        if isinstance(raw, bool):
            raise ValueError("a length must be a number or a percentage like '5%'")
        if isinstance(raw, (int, float)):
            return cls(float(raw))
        if isinstance(raw, str):
            text = raw.strip()
            pct = text.endswith("%")
            try:
                val = float(text[:-1] if pct else text)
            except ValueError:
                raise ValueError(f"{raw!r} is not a length (a number or a percentage like '5%')")
            return cls(val, pct)
        raise ValueError(f"{raw!r} is not a length (a number or a percentage like '5%')")

    def resolve(self, diameter: float) -> float:
        """The absolute length for a mesh with bounding-box diagonal ``diameter``."""
        return self.value * diameter / 100.0 if self.percent else self.value

    def to_json(self):
        return f"{meshlab_float(self.value)}%" if self.percent else self.value

    def __str__(self) -> str:
        return f"{meshlab_float(self.value)}%" if self.percent else meshlab_float(self.value)
