"""Which cell kind a mesh is: the one place where it is decided (:func:`kind_of`).

Our meshes decide by their class (:class:`..mesh.TetMesh`, :class:`..mesh.SurfaceMesh`,
:class:`..mesh.TriangleMesh` and its :class:`..mesh.PlanarMesh`: planar in its plane's
coordinates, a surface when its points are on no plane); ``trimesh.Trimesh`` and
``pymeshlab.Mesh`` are surfaces in space; a ``meshio.Mesh`` by its cells (tetrahedra, with
any triangles, lines and vertices beside them, or triangles, with lines and vertices;
triangles are planar when the points are 2D or every z is 0). The foreign packages are
recognized by the object's module, never imported here.
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError, OptionError
from ..mesh import SurfaceMesh, TetMesh, TriangleMesh
from .base import CellKind
from .planar import PLANAR
from .surface import SURFACE
from .tetrahedra import TETRAHEDRA

__all__ = ["KINDS", "cells_of", "kind_of", "metric_for"]

#: every cell kind, by name
KINDS: dict[str, CellKind] = {k.name: k for k in (PLANAR, SURFACE, TETRAHEDRA)}

#: meshio cell types beside the cells of a kind (boundary elements, tags)
_BESIDE = {"tetra": ("triangle", "line", "vertex"), "triangle": ("line", "vertex")}
#: plural names of the meshio cell types no kind takes
_PLURAL = {"quad": "quadrilaterals", "hexahedron": "hexahedra", "wedge": "wedges (prisms)",
           "pyramid": "pyramids", "polygon": "polygons", "line": "only lines",
           "vertex": "only vertices"}


def _package(mesh) -> str:
    return type(mesh).__module__.split(".")[0]


def _meshio_cells(mesh, what: str) -> tuple[CellKind, FloatArray, IntArray]:
    blocks = [(b.type, np.asarray(b.data)) for b in mesh.cells if len(b.data)]
    types = {t for t, _ in blocks}
    main = "tetra" if "tetra" in types else "triangle" if "triangle" in types else None
    other = sorted(types - ({main, *_BESIDE[main]} if main else set()))
    if main is None or other:
        names = ", ".join(_PLURAL.get(t, f"{t} cells") for t in (other or sorted(types)))
        raise InvalidMeshError(f"the mesh has {names or 'no cells'}; {what} supports "
                               "triangles and tetrahedra")
    cells = np.concatenate([c for t, c in blocks if t == main])
    points = np.asarray(mesh.points, dtype=float)
    if main == "tetra":
        return TETRAHEDRA, points, cells
    if points.shape[1] == 2 or not np.any(points[:, 2]):
        return PLANAR, points[:, :2], cells
    return SURFACE, points, cells


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
    OptionError
        ``mesh`` is none of these objects.
    InvalidMeshError
        A ``meshio.Mesh`` with cells no kind takes (quadrilaterals, hexahedra, …) or with
        none.
    """
    if isinstance(mesh, TetMesh):
        return TETRAHEDRA, mesh.points, mesh.tets
    if isinstance(mesh, SurfaceMesh):
        return SURFACE, mesh.points, mesh.triangles
    if isinstance(mesh, TriangleMesh):
        try:
            planar = mesh.as_planar()
        except InvalidMeshError:  # points off every plane: a surface in space
            return SURFACE, mesh.points, mesh.triangles
        return PLANAR, planar.points, planar.triangles
    package = _package(mesh)
    if package == "trimesh" and type(mesh).__name__ == "Trimesh":
        return SURFACE, np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces)
    if package == "pymeshlab" and type(mesh).__name__ == "Mesh":
        points = np.asarray(mesh.vertex_matrix(), dtype=float)
        return SURFACE, points, np.asarray(mesh.face_matrix())
    if package == "meshio" and type(mesh).__name__ == "Mesh":
        return _meshio_cells(mesh, what)
    raise OptionError(f"{what} takes a PlanarMesh, TriangleMesh, SurfaceMesh, TetMesh, "
                      f"trimesh.Trimesh, pymeshlab.Mesh or meshio.Mesh, got "
                      f"{type(mesh).__module__}.{type(mesh).__name__}")


def kind_of(mesh, what: str = "meshopt") -> CellKind:
    """The :class:`.base.CellKind` of ``mesh`` (:func:`cells_of` says which objects are
    meshes and what it raises)."""
    return cells_of(mesh, what)[0]


def metric_for(mesh):
    """The default metric of ``mesh``'s kind at ``mesh`` (the one ``mt.morph`` uses):
    a :class:`..riemannian.metrics.Metric` on ``(N, d)`` points."""
    kind, points, cells = cells_of(mesh, "metric_for")
    return kind.default_metric(points, cells)
