"""Reading and writing pipeline files (``.json`` or MeshLab ``.mlx``).

This module sits above :mod:`.runner`, :mod:`.json_format` and :mod:`.mlx` (which import
the runner, never the other way round), so the pipeline package has no import cycle.

A pipeline file must be a regular file (not a FIFO, a device or a directory) of at most
:data:`~meshopt_toolkit.pipeline.limits.MAX_PIPELINE_BYTES`; it is read once, bounded,
and parsed from memory.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import FilterError
from . import json_format, mlx
from .limits import read_bounded
from .runner import Pipeline

__all__ = ["load_pipeline", "save_pipeline"]


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
    if suffix == ".mlx" or (suffix != ".json" and data.lstrip()[:1] == b"<"):
        return mlx.loads(data, str(p))
    return json_format.loads(data, str(p))


def save_pipeline(pipeline: Pipeline, path, *, overwrite: bool = False,
                  diameter: float | None = None) -> None:
    """Write a pipeline as ``.json`` or ``.mlx`` (by extension), atomically."""
    p = Path(path)
    if p.suffix.lower() == ".mlx":
        mlx.write_mlx(pipeline, p, overwrite=overwrite, diameter=diameter)
    elif p.suffix.lower() == ".json":
        json_format.write_json(pipeline, p, overwrite=overwrite)
    else:
        raise FilterError(f"{p}: pipeline files end in .json or .mlx")
