"""Pipelines as JSON: ``{"filters": [{"name": ..., "params": {...}}, ...]}``.

The text is bounded before parsing (size, nesting depth: :mod:`.limits`), and the
non-standard constants ``NaN``, ``Infinity`` and ``-Infinity`` that Python's parser accepts
are refused, so every problem is a one-line :class:`FilterError` naming the file.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import FilterError
from .. import strict_json
from ..io import atomic_path
from .limits import MAX_PIPELINE_BYTES, check_json_text, read_bounded
from .runner import Pipeline

__all__ = ["read_json", "write_json", "loads", "dumps", "MAX_BYTES"]

#: JSON pipelines larger than this are refused before parsing
MAX_BYTES = MAX_PIPELINE_BYTES


def _no_constant(name: str):
    raise FilterError(f"{name} is not a number a pipeline may hold (finite numbers only)")


def loads(text: str | bytes, source: str | None = None) -> Pipeline:
    """Parse JSON text into a :class:`Pipeline` (clear errors with line and column).

    Raises
    ------
    FilterError
        Too large, nested too deep, not UTF-8, not JSON, ``NaN``/``Infinity``, or not a
        valid pipeline; the message names ``source``.
    """
    where = f"{source}: " if source else ""
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else bytes(text)
    if len(data) > MAX_BYTES:
        raise FilterError(f"{where}pipeline file larger than {MAX_BYTES} bytes; refused")
    check_json_text(data, where)
    try:
        decoded = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FilterError(f"{where}not UTF-8 text: {exc.reason} at byte {exc.start}") from None
    try:
        parsed = json.loads(decoded, parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise FilterError(f"{where}not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    except FilterError as exc:
        raise FilterError(f"{where}{exc}") from None
    except RecursionError:  # pragma: no cover - check_json_text bounds the depth first
        raise FilterError(f"{where}JSON nested too deep") from None
    return Pipeline.from_dict(parsed, source)


def dumps(pipeline: Pipeline) -> str:
    return strict_json.dumps(pipeline.to_dict(), indent=2) + "\n"


def read_json(path) -> Pipeline:
    """Read a JSON pipeline file (a regular file, bounded; see :func:`loads`)."""
    p = Path(path)
    return loads(read_bounded(p, MAX_BYTES), str(p))


def write_json(pipeline: Pipeline, path, *, overwrite: bool = False) -> None:
    _write_text(path, dumps(pipeline), overwrite=overwrite)


def _write_text(path, text: str, *, overwrite: bool) -> None:
    with atomic_path(path, overwrite=overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
