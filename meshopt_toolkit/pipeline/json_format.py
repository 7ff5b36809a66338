"""Pipelines as JSON: ``{"filters": [{"name": ..., "params": {...}}, ...]}``."""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import FilterError
from ..io import atomic_path
from .runner import Pipeline

__all__ = ["read_json", "write_json", "loads", "dumps"]

MAX_BYTES = 16 * 1024 * 1024


def loads(text: str, source: str | None = None) -> Pipeline:
    """Parse JSON text into a :class:`Pipeline` (clear errors with line and column)."""
    where = f"{source}: " if source else ""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FilterError(f"{where}not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    return Pipeline.from_dict(data, source)


def dumps(pipeline: Pipeline) -> str:
    return json.dumps(pipeline.to_dict(), indent=2) + "\n"


def read_json(path) -> Pipeline:
    p = Path(path)
    if p.stat().st_size > MAX_BYTES:
        raise FilterError(f"{p}: pipeline file larger than {MAX_BYTES} bytes")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise FilterError(f"{p}: not UTF-8 text: {exc}") from None
    return loads(text, str(p))


def write_json(pipeline: Pipeline, path, *, overwrite: bool = False) -> None:
    _write_text(path, dumps(pipeline), overwrite=overwrite)


def _write_text(path, text: str, *, overwrite: bool) -> None:
    with atomic_path(path, overwrite=overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
