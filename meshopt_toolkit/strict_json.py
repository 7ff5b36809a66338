"""Strict JSON for everything we print or write: ``null`` where a number is NaN or infinite.

Python's ``json`` writes ``NaN`` and ``Infinity`` by default, which is not JSON (``jq``,
browsers and most parsers refuse it). :func:`dumps` and :func:`dump` first turn every
non-finite float into ``None`` and numpy scalars and arrays into Python values, then
serialize with ``allow_nan=False``, so a value that slips past the conversion fails
loudly instead of writing invalid JSON.
"""

from __future__ import annotations

import json
import math
from pathlib import PurePath
from typing import IO, Any

import numpy as np

__all__ = ["dump", "dumps", "strict"]


def strict(obj: Any) -> Any:
    """``obj`` with non-finite floats as None, numpy values and paths as plain Python.

    Dicts, lists and tuples are converted recursively (tuples become lists); anything
    else is returned as is, for ``json`` to accept or refuse.
    """
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        return value if math.isfinite(value) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return strict(obj.tolist())
    if isinstance(obj, dict):
        return {k: strict(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict(v) for v in obj]
    if isinstance(obj, PurePath):
        return str(obj)
    return obj


def dumps(obj: Any, **kwargs) -> str:
    """``json.dumps`` of :func:`strict` ``(obj)`` with ``allow_nan=False``."""
    return json.dumps(strict(obj), allow_nan=False, **kwargs)


def dump(obj: Any, fh: IO[str], **kwargs) -> None:
    """``json.dump`` of :func:`strict` ``(obj)`` with ``allow_nan=False``."""
    json.dump(strict(obj), fh, allow_nan=False, **kwargs)
