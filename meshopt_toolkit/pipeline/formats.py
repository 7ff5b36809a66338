"""Pipeline files: JSON (``{"filters": [{"name": ..., "params": {...}}, ...]}``) and
MeshLab ``.mlx`` (the text in :mod:`.mlx`), read and written by extension.

A pipeline file must be a regular file (not a FIFO, a device or a directory) of at most
:data:`~meshopt_toolkit.pipeline.limits.MAX_PIPELINE_BYTES`; it is read once, bounded,
and parsed from memory. JSON text is bounded before parsing (size, nesting depth:
:mod:`.limits`), and the non-standard constants ``NaN``, ``Infinity`` and ``-Infinity``
that Python's parser accepts are refused, so every problem is a one-line
:class:`FilterError` naming the file.

This module sits above :mod:`.runner` and :mod:`.mlx` (which import the runner, never
the other way round), so the pipeline package has no import cycle.
"""

from __future__ import annotations

import json
from pathlib import Path

from .. import strict_json
from ..errors import FilterError
from ..io import atomic_path
from . import mlx
from .limits import MAX_PIPELINE_BYTES, check_json_text, read_bounded
from .runner import Pipeline

__all__ = ["load_pipeline", "save_pipeline", "loads_json", "dumps_json"]


def load_pipeline(path) -> Pipeline:
    """Read a pipeline from ``.json`` or ``.mlx`` (by extension; content sniffed otherwise).

    Raises
    ------
    FilterError
        One line naming the file (and the step, from 1) for every problem: size, nesting,
        syntax, unknown filters or parameters.
    """
    p = Path(path)
    data = read_bounded(p)
    suffix = p.suffix.lower()
    start = data.lstrip()[:1]
    if suffix == ".mlx" or (suffix != ".json" and start == b"<"):
        return mlx.loads(data, str(p))
    if suffix != ".json" and start not in (b"{", b"["):  # a mesh given first, say
        raise FilterError(f"{p}: not a pipeline: a pipeline is a .json or MeshLab .mlx "
                          "file, given before the inputs (meshopt run PIPELINE INPUT ...)")
    return loads_json(data, str(p))


def save_pipeline(pipeline: Pipeline, path, *, overwrite: bool = False,
                  diameter: float | None = None) -> None:
    """Write a pipeline as ``.json`` or ``.mlx`` (by extension), atomically.

    ``diameter`` (the bounding-box diagonal) resolves percentage lengths in ``.mlx``.
    """
    p = Path(path)
    if p.suffix.lower() == ".mlx":
        text = mlx.dumps(pipeline, diameter)
    elif p.suffix.lower() == ".json":
        text = dumps_json(pipeline)
    else:
        raise FilterError(f"{p}: pipeline files end in .json or .mlx")
    with atomic_path(p, overwrite=overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _no_constant(name: str):
    raise FilterError(f"{name} is not a number a pipeline may hold (finite numbers only)")


def loads_json(text: str | bytes, source: str | None = None) -> Pipeline:
    """Parse JSON text into a :class:`Pipeline` (clear errors with line and column).

    Raises
    ------
    FilterError
        Too large, nested too deep, not UTF-8, not JSON, ``NaN``/``Infinity``, or not a
        valid pipeline; the message names ``source``.
    """
    where = f"{source}: " if source else ""
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else bytes(text)
    if len(data) > MAX_PIPELINE_BYTES:
        raise FilterError(f"{where}pipeline file larger than {MAX_PIPELINE_BYTES} bytes; "
                          "refused")
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


def dumps_json(pipeline: Pipeline) -> str:
    """The JSON text of a pipeline (strict JSON: finite numbers only)."""
    return strict_json.dumps(pipeline.to_dict(), indent=2) + "\n"
