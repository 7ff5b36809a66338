"""Which cell kind a mesh is, as a :class:`.base.CellKind` (:func:`kind_of`), with its points
and cells (:func:`cells_of`). The kind is decided by :func:`..mesh.kinds.mesh_kind` (the rule
is there); here each name becomes its kind and the mesh its arrays: a planar
:class:`..mesh.TriangleMesh` in its plane's coordinates, a ``meshio.Mesh`` by its main
cells (tetrahedra with any triangles, lines and vertices beside them, or triangles with
lines and vertices).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..mesh.kinds import PLANAR as PLANAR_NAME
from ..mesh.kinds import TETS as TETS_NAME
from ..mesh.kinds import class_kind, foreign_package, mesh_kind, meshio_blocks
from .base import CellKind
from .planar import PLANAR
from .surface import SURFACE
from .tetrahedra import TETRAHEDRA

__all__ = ["KINDS", "cells_of", "kind_of", "metric_for"]

#: every cell kind, by name
KINDS: dict[str, CellKind] = {k.name: k for k in (PLANAR, SURFACE, TETRAHEDRA)}


def _arrays(mesh, name: str, what: str) -> tuple[FloatArray, IntArray]:
    """The points and cells of ``mesh``, of kind ``name``."""
    if class_kind(mesh) is not None:
        return mesh.points, (mesh.tets if name == TETS_NAME else mesh.triangles)
    package = foreign_package(mesh)
    if package == "trimesh":
        return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces)
    if package == "pymeshlab":
        return np.asarray(mesh.vertex_matrix(), dtype=float), np.asarray(mesh.face_matrix())
    if package == "meshio":
        main, blocks = meshio_blocks(mesh, what)
        points = np.asarray(mesh.points, dtype=float)
        cells = np.concatenate([c for t, c in blocks if t == main])
        return (points[:, :2] if name == PLANAR_NAME else points), cells
    if name == PLANAR_NAME:  # a TriangleMesh on a plane: in its plane's coordinates
        planar = mesh.as_planar()
        return planar.points, planar.triangles
    return mesh.points, mesh.triangles


def cells_of(mesh, what: str = "meshopt") -> tuple[CellKind, FloatArray, IntArray]:
    """The cell kind of ``mesh`` with its points ``(N, d)`` and cells ``(C, k)``.

    Parameters
    ----------
    mesh : PlanarMesh, TriangleMesh, SurfaceMesh, TetMesh, trimesh.Trimesh,
        pymeshlab.Mesh or meshio.Mesh
    what : str
        Who asks, named in the error (``"move"``, ``"morph"``).

    Raises
    ------
    OptionError, InvalidMeshError
        As :func:`..mesh.kinds.mesh_kind`, the one decider of a mesh's kind.
    """
    name = mesh_kind(mesh, what)
    return (KINDS[name], *_arrays(mesh, name, what))


def kind_of(mesh, what: str = "meshopt") -> CellKind:
    """The :class:`.base.CellKind` of ``mesh`` (:func:`cells_of` says which objects are
    meshes and what it raises)."""
    return KINDS[mesh_kind(mesh, what)]


def metric_for(mesh):
    """The default metric of ``mesh``'s kind at ``mesh`` (the one ``mt.morph`` uses):
    a :class:`..riemannian.metrics.Metric` on ``(N, d)`` points."""
    kind, points, cells = cells_of(mesh, "metric_for")
    return kind.default_metric(points, cells)
