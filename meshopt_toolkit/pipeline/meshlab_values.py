"""MeshLab's parameter values: lengths, floats as MeshLab writes them, and type checks
of pymeshlab parameter values before anything runs.

:class:`Length` is an absolute length or a percentage of the bounding-box diagonal
(MeshLab's ``RichAbsPerc``); :func:`meshlab_float` writes floats as MeshLab does.

pymeshlab documents each filter parameter with a type (``print_filter_parameter_list``):
``bool``, ``int``, ``float``, ``float (bounded)``, ``str`` (also enums: a label or an
index), ``PercentageValue``, ``Color``, ``numpy.ndarray[numpy.float64[3]]`` or
``[4, 4]``, ``Shotf``. :func:`check_value` checks a JSON or .mlx value against it, so a
wrong type (``"stepsmoothnum": "lots"``) or a non-finite number fails at ``--dry-run``
with a one-line :class:`FilterError` naming the filter and the parameter instead of every
file failing later inside pymeshlab.

This module imports nothing of pymeshlab.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..errors import FilterError

__all__ = ["check_value", "Length", "meshlab_float"]


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _finite_numbers(values: Any, n: int | tuple[int, ...]) -> bool:
    counts = (n,) if isinstance(n, int) else n
    return (isinstance(values, (list, tuple)) and len(values) in counts
            and all(_number(v) and math.isfinite(v) for v in values))


def _problem(ptype: str, value: Any) -> str | None:
    """What is wrong with ``value`` for a parameter of pymeshlab type ``ptype`` (or None)."""
    if ptype == "bool":
        return None if isinstance(value, bool) else "expected true or false"
    if ptype == "int":
        if isinstance(value, float) and math.isfinite(value) and value.is_integer():
            return None
        if not (_number(value) and isinstance(value, int)):
            return "expected an integer"
        return None if -2**31 <= value < 2**31 else "integer out of range"
    if ptype.startswith("float"):
        if not _number(value):
            return "expected a number"
        return None if math.isfinite(value) else "expected a finite number"
    if ptype == "str":  # plain strings and enums (a label or an index)
        ok = isinstance(value, str) or (isinstance(value, int) and not isinstance(value, bool))
        return None if ok else "expected a string (or an enum index)"
    if ptype.startswith("PercentageValue"):
        return _length_problem(value)
    if ptype.startswith("Color"):
        ok = (isinstance(value, (list, tuple)) and len(value) in (3, 4)
              and all(isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 255
                      for c in value))
        return None if ok else "expected a color [r, g, b, a] of integers 0..255"
    if ptype.startswith("numpy.ndarray[numpy.float64[3]]"):
        return None if _finite_numbers(value, 3) else "expected 3 finite numbers"
    if ptype.startswith("numpy.ndarray[numpy.float64[4, 4]]"):
        flat = value
        if isinstance(value, (list, tuple)) and len(value) == 4 and all(
                isinstance(r, (list, tuple)) for r in value):
            flat = [x for r in value for x in r]
        return None if _finite_numbers(flat, 16) else "expected a 4×4 matrix of finite numbers"
    if ptype.startswith("Shotf"):
        return "camera (Shotf) parameters are not supported"
    return None  # a type this version does not know: pymeshlab decides


def _length_problem(value: Any) -> str | None:
    """An absolute-or-percentage length: a number, ``"5%"``, ``{"abs": x}``, ``{"percent": p}``."""
    what = 'expected a length: a number, "5%", {"abs": x} or {"percent": p}'
    if isinstance(value, dict):
        if len(value) != 1 or next(iter(value)) not in ("abs", "percent"):
            return what
        value = next(iter(value.values()))
    elif isinstance(value, str):
        text = value.strip()
        if not text.endswith("%"):
            return what
        try:
            value = float(text[:-1])
        except ValueError:
            return what
    if not _number(value):
        return what
    if not math.isfinite(value):
        return "expected a finite length"
    return None if value >= 0 else "expected a non-negative length"


def check_value(filter_name: str, key: str, ptype: str, value: Any) -> None:
    """Raise FilterError if ``value`` does not suit the pymeshlab type ``ptype``.

    Examples
    --------
    >>> check_value("apply_coord_laplacian_smoothing", "stepsmoothnum", "int", 3)
    >>> check_value("apply_coord_laplacian_smoothing", "stepsmoothnum", "int", "lots")
    Traceback (most recent call last):
    ...
    meshopt_toolkit.errors.FilterError: MeshLab filter 'apply_coord_laplacian_smoothing', parameter 'stepsmoothnum' (int): expected an integer, got 'lots'
    """
    problem = _problem(ptype, value)
    if problem is not None:
        shown = repr(value)
        if len(shown) > 60:
            shown = shown[:57] + "..."
        raise FilterError(f"MeshLab filter {filter_name!r}, parameter {key!r} ({ptype}): "
                          f"{problem}, got {shown}")


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
