"""Routing pipeline steps to pymeshlab.

- :func:`resolve` maps a MeshLab GUI label (``<filter name="Laplacian Smooth">`` in a
  .mlx) or a pymeshlab name to the current pymeshlab filter name. pymeshlab's own script
  loader snake-cases the label (``laplacian_smooth``); the ``keys.txt`` file shipped
  inside the pymeshlab package maps those names to today's method names
  (``apply_coord_laplacian_smoothing``). MeshLab's camelCase ``Param`` names are
  pymeshlab's parameter names lowercased.
- :func:`parameter_list` gives a filter's parameters as pymeshlab documents them.
- :func:`to_pymeshlab_value` turns JSON-friendly values into what ``apply_filter`` wants.
- :data:`UNSAFE_FILTERS` / :func:`check_safe`: filters known to abort the whole process on
  a headless machine (GPU filters), and :data:`FILE_FILTERS` that read or write files (or
  the network) at paths of their own, are refused before anything runs.
- :data:`READ_PATH_PARAMS`: parameters naming a file a filter reads; the runner confines
  them like ``load_mesh`` paths (:mod:`.paths`).
- :func:`validate_params` checks names and types (:mod:`.meshlab_values`).

pymeshlab is imported lazily (only when a pipeline has a MeshLab step).
"""

from __future__ import annotations

import functools
import os
import re
import sys
import tempfile
from pathlib import Path
from typing import Any

from ..errors import FilterError
from .limits import check_name
from .meshlab_values import check_value
from .params import did_you_mean

__all__ = [
    "snake_case",
    "keys_table",
    "filter_names",
    "resolve",
    "parameter_list",
    "check_safe",
    "to_pymeshlab_value",
    "from_pymeshlab_value",
    "apply",
    "UNSAFE_FILTERS",
    "FILE_FILTERS",
    "READ_PATH_PARAMS",
]

#: filters that abort the Python process (uncatchable) on a machine without a GPU/display
UNSAFE_FILTERS = frozenset({
    "compute_scalar_ambient_occlusion_gpu",
    "compute_scalar_by_volumetric_obscurance_gpu",
    "compute_scalar_by_shape_diameter_function_per_vertex_gpu",
})

#: filters that write or read files at paths of their own, or talk to the network: a
#: pipeline cannot confine them to the output directory, so they are refused
FILE_FILTERS = frozenset({
    "nxs_build",
    "nxs_compress",
    "save_snapshot",
    "save_active_raster_cameras",
    "load_active_raster_cameras",
    "export_mesh_to_sketchfab",
})

#: (filter, parameter) naming a file the filter reads (confined like load_mesh paths)
READ_PATH_PARAMS = frozenset({
    ("compute_color_from_scalar_using_transfer_function_per_vertex", "csvfilename"),
    ("set_texture_per_mesh", "textname"),
})


def _pymeshlab():
    try:
        import pymeshlab
    except ImportError as exc:  # pragma: no cover - a hard dependency
        raise FilterError(f"MeshLab filters need pymeshlab, which cannot be imported: {exc}")
    return pymeshlab


def snake_case(label: str) -> str:
    """MeshLab label → the snake_case name pymeshlab derives from it.

    >>> snake_case("Subdivision Surfaces: Midpoint")
    'subdivision_surfaces_midpoint'
    """
    return re.sub(r"[^0-9a-z]+", "_", label.lower()).strip("_")


@functools.lru_cache(maxsize=1)
def keys_table() -> dict[str, str]:
    """pymeshlab's ``keys.txt``: snake-cased MeshLab label → current filter name."""
    pm = _pymeshlab()
    path = Path(pm.__file__).with_name("keys.txt")
    table: dict[str, str] = {}
    if path.exists():
        for line in path.read_text().splitlines():
            parts = line.split()
            if len(parts) == 2:
                table[parts[0]] = parts[1]
    return table


@functools.lru_cache(maxsize=1)
def filter_names() -> tuple[str, ...]:
    """All pymeshlab filter names (``pymeshlab.filter_list()``)."""
    return tuple(_pymeshlab().filter_list())


def resolve(name_or_label: str) -> str | None:
    """The pymeshlab filter name for a pymeshlab name or a MeshLab GUI label, or None."""
    names = set(filter_names())
    if name_or_label in names:
        return name_or_label
    key = snake_case(name_or_label)
    new = keys_table().get(key)
    if new in names:
        return new
    return key if key in names else None


def suggestions(name_or_label: str) -> str:
    """A "did you mean" over pymeshlab names and snake-cased labels."""
    key = snake_case(name_or_label)
    cands = list(filter_names()) + list(keys_table())
    hint = did_you_mean(key, cands)
    if hint:
        close = hint.split("'")[1]
        new = keys_table().get(close, close)
        return f" (did you mean {new!r}?)"
    return ""


def check_safe(name: str) -> None:
    """Raise FilterError for a filter known to abort the process here, or one that reads
    or writes files (or the network) outside the pipeline's control."""
    if name in UNSAFE_FILTERS:
        raise FilterError(
            f"MeshLab filter {name!r} needs a GPU/OpenGL context and aborts the whole process "
            "on a headless machine; refused"
        )
    if name in FILE_FILTERS:
        raise FilterError(
            f"MeshLab filter {name!r} reads or writes files (or the network) at paths of its "
            "own, which a pipeline cannot confine to its output directory; refused"
        )


def _capture_stdout(fn, *args) -> str:
    """Run ``fn`` and return what it wrote to file descriptor 1 (C++ std::cout)."""
    sys.stdout.flush()
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        saved = os.dup(1)
        try:
            os.dup2(tmp.fileno(), 1)
            fn(*args)
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)
        tmp.seek(0)
        return tmp.read().decode("utf-8", "replace")


_PARAM_LINE = re.compile(r"^\t([A-Za-z0-9_]+) : (.*?) = (.*)$")


@functools.lru_cache(maxsize=None)
def parameter_list(name: str) -> tuple[dict, ...]:
    """The parameters of a pymeshlab filter: ``({"name", "type", "default"}, ...)``.

    Parsed from ``pymeshlab.print_filter_parameter_list`` (defaults are those of
    pymeshlab's sample cube; mesh-dependent defaults are recomputed on the real mesh).
    """
    pm = _pymeshlab()
    if name not in filter_names():
        raise FilterError(f"unknown MeshLab filter {name!r}{suggestions(name)}")
    text = _capture_stdout(pm.print_filter_parameter_list, name)
    out = []
    for line in text.splitlines():
        m = _PARAM_LINE.match(line)
        if m:
            out.append({"name": m.group(1), "type": m.group(2).strip(), "default": m.group(3).strip()})
    return tuple(out)


def validate_params(name: str, params: dict[str, Any]) -> None:
    """Check the parameters of a MeshLab filter: known names and values of the right type.

    Raises
    ------
    FilterError
        An unknown name (with a suggestion), or a value that does not suit the type
        pymeshlab documents (see :func:`.meshlab_values.check_value`), e.g. a string for an
        integer or a non-finite number.
    """
    types = {p["name"]: p["type"] for p in parameter_list(name)}
    for key, value in params.items():
        check_name(key, "parameter")
        if key not in types:
            known = list(types)
            raise FilterError(
                f"MeshLab filter {name!r} has no parameter {key!r}{did_you_mean(key, known)}; "
                f"parameters: {', '.join(known) or 'none'}"
            )
        check_value(name, key, types[key], value)


def to_pymeshlab_value(name: str, key: str, value: Any):
    """A JSON-friendly value → what ``MeshSet.apply_filter`` accepts for that parameter.

    ``{"abs": x}`` or a number for a ``PercentageValue`` parameter → ``PureValue(x)``;
    ``"5%"`` or ``{"percent": 5}`` → ``PercentageValue(5)``; 4 numbers for a Color;
    3 or 16 numbers for a position or matrix.
    """
    import numpy as np

    pm = _pymeshlab()
    ptype = next((p["type"] for p in parameter_list(name) if p["name"] == key), "")
    try:
        if isinstance(value, dict):
            if "abs" in value:
                return pm.PureValue(float(value["abs"]))
            if "percent" in value:
                return pm.PercentageValue(float(value["percent"]))
            raise ValueError(f"unknown value object {value!r}")
        if ptype.startswith("PercentageValue"):
            if isinstance(value, str) and value.strip().endswith("%"):
                return pm.PercentageValue(float(value.strip()[:-1]))
            return pm.PureValue(float(value))
        if ptype.startswith("Color") and isinstance(value, (list, tuple)):
            return pm.Color(*[int(v) for v in value])
        if ptype.startswith("numpy") and isinstance(value, (list, tuple)):
            arr = np.asarray(value, dtype=np.float64)
            return arr.reshape(4, 4) if arr.size == 16 else arr
        if ptype.startswith("float") and isinstance(value, int) and not isinstance(value, bool):
            return float(value)
        if ptype == "int" and isinstance(value, float) and value.is_integer():
            return int(value)
    except (TypeError, ValueError) as exc:
        raise FilterError(f"MeshLab filter {name!r}, parameter {key!r}: bad value {value!r}: {exc}")
    return value


def from_pymeshlab_value(value: Any) -> Any:
    """The inverse of :func:`to_pymeshlab_value` for JSON output."""
    import numpy as np

    pm = _pymeshlab()
    if isinstance(value, pm.PureValue):
        return {"abs": value.value()}
    if isinstance(value, pm.PercentageValue):
        return {"percent": value.value()}
    if isinstance(value, np.ndarray):
        return value.ravel().tolist()
    return value


def apply(ms, name: str, params: dict[str, Any]) -> dict | None:
    """Apply a pymeshlab filter to a MeshSet, with clear errors.

    Returns
    -------
    dict or None
        What pymeshlab returned (measures), made JSON-friendly.
    """
    pm = _pymeshlab()
    check_safe(name)
    kwargs = {k: to_pymeshlab_value(name, k, v) for k, v in params.items()}
    try:
        res = ms.apply_filter(name, **kwargs)
    except pm.PyMeshLabException as exc:
        raise FilterError(f"MeshLab filter {name!r} failed: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise FilterError(f"MeshLab filter {name!r}: {exc}") from None
    if not res:
        return None
    return {k: _jsonable(v) for k, v in dict(res).items()}


def _jsonable(v):
    import numpy as np

    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, (int, float, str, bool)) or v is None:
        return v
    return str(v)
