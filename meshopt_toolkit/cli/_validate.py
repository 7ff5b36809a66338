"""Checks of numeric command-line options: finite, in range, one line naming the option.

Each subcommand checks all its numbers before it reads a file, so ``--time nan``,
``--rtol -1`` or ``--frames 1000000`` fail at once (exit 1) instead of running, or doing
nothing, silently. The bounds shared with the pipeline filters are in
:mod:`meshopt_toolkit.bounds`.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterable

from ..errors import OptionError

__all__ = ["OptionError", "check_int", "check_number", "check_numbers"]


def bound_text(low, high, low_open: bool = False, high_open: bool = False) -> str:
    """The range in words, e.g. ``"> 0 and <= 0.1"`` (a None bound left out)."""
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    return " and ".join(parts)


def check_number(option: str, value, *, low: float | None = None, high: float | None = None,
                 low_open: bool = False, high_open: bool = False):
    """Return ``value`` if it is None or a finite number in the range, else raise.

    Parameters
    ----------
    option : the option as the user typed it, e.g. ``"--time"``
    value : float or None (None: the option was not given)
    low, high : bounds (None: unbounded); ``low_open``/``high_open`` make them strict

    Raises
    ------
    OptionError
        ``"--rtol must be a finite number > 0 and <= 0.1, got -1"``.
    """
    if value is None:
        return None
    v = float(value)
    ok = (math.isfinite(v)
          and (low is None or (v > low if low_open else v >= low))
          and (high is None or (v < high if high_open else v <= high)))
    if not ok:
        rng = bound_text(low, high, low_open, high_open)
        raise OptionError(f"{option} must be a finite number{' ' + rng if rng else ''}, "
                          f"got {v:g}")
    return value


def check_int(option: str, value, low: int, high: int):
    """Return ``value`` if it is None or an integer in ``[low, high]``, else raise.

    Raises
    ------
    OptionError
        ``"--frames must be between 2 and 1000, got 1000000"``.
    """
    if value is None:
        return None
    if not low <= value <= high:
        raise OptionError(f"{option} must be between {low} and {high}, got {value}")
    return value


def check_numbers(option: str, values: Iterable[float] | None, *, low: float | None = 0.0):
    """Return ``values`` if None or all finite and ``>= low``; for lists such as ``--beta``.

    Raises
    ------
    OptionError
        ``"--beta must be finite numbers >= 0, got nan,1,1,1"``.
    """
    if values is None:
        return None
    vals = tuple(values)
    if not all(math.isfinite(v) and (low is None or v >= low) for v in vals):
        rng = bound_text(low, None)
        shown = ",".join(f"{v:g}" for v in vals)
        raise OptionError(f"{option} must be finite numbers{' ' + rng if rng else ''}, got {shown}")
    return values


def int_at_least(low: int, expected: str):
    """An argparse type: an integer ``>= low``; anything else ``"expected EXPECTED, got
    'TEXT'"`` (``expected`` says the range in words)."""

    def parse(text: str) -> int:
        from ..expressions import quoted

        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if value < low:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {quoted(text)}")
        return value

    return parse
