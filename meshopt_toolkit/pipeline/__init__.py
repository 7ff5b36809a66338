"""Filter API, registry, documents and pipelines (JSON and MeshLab .mlx).

- :class:`Filter` and typed parameters (:mod:`.params`); :data:`registry` of built-in
  filters (``meshopt_toolkit.filters``) and plugins (entry-point group
  ``meshopt_toolkit.filters``).
- :class:`Document`: meshes with a current one and per-vertex/per-face attributes,
  convertible to and from ``pymeshlab.MeshSet``.
- :class:`Pipeline`: steps mixing meshopt filters and MeshLab filters (routed to
  pymeshlab), read and written as JSON or MeshLab .mlx.

Running a pipeline over many files is :mod:`meshopt_toolkit.batch`.
"""

from __future__ import annotations

from .document import Document, MeshEntry
from .filter import (
    ENTRY_POINT_GROUP,
    MESH_KINDS,
    PLANAR,
    SURFACE,
    TETS,
    Filter,
    FilterRegistry,
    PluginWarning,
    register,
    registry,
)
from .formats import load_pipeline, save_pipeline
from .params import (
    BoolParam,
    EnumParam,
    FloatParam,
    IntParam,
    Length,
    LengthParam,
    Param,
    PathParam,
    StringParam,
)
from .runner import Pipeline, Step, make_step

__all__ = [
    "Filter", "FilterRegistry", "PluginWarning", "registry", "register", "ENTRY_POINT_GROUP",
    "MESH_KINDS", "PLANAR", "SURFACE", "TETS",
    "Param", "BoolParam", "IntParam", "FloatParam", "EnumParam", "StringParam", "PathParam",
    "LengthParam", "Length",
    "Document", "MeshEntry",
    "Pipeline", "Step", "make_step", "load_pipeline", "save_pipeline",
]
