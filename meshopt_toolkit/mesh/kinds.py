"""The one decider of a mesh's cell kind, by name: what every layer asks (``fem/``,
``io/``, ``pipeline/``, ``cli/``, the motions) and what :mod:`..cells.registry` maps to a
:class:`..cells.base.CellKind`. It sits in the mesh layer, so every layer above may ask it.

The rule, one for every mesh:

- tetrahedra make a mesh :data:`TETS` (with any triangles, lines and vertices beside them);
- a :class:`~.surface.SurfaceMesh`, ``trimesh.Trimesh`` and ``pymeshlab.Mesh`` are
  :data:`SURFACE` (a surface in space by the caller's choice of object);
- other triangles are :data:`PLANAR` when their points lie on one plane, any plane
  (:attr:`~.core.TriangleMesh.is_planar`: a :class:`~.core.TriangleMesh`, and the
  cells of a file, :func:`cells_kind`, whose plane the workpiece maps and writes back),
  else :data:`SURFACE`. An in-memory ``meshio.Mesh`` is handed back at its own
  coordinates, so it is planar only when those are the plane's (2D points or every z 0).
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidMeshError, OptionError
from .core import TriangleMesh
from .surface import SurfaceMesh
from .volume import TetMesh

__all__ = ["KIND_NAMES", "PLANAR", "SURFACE", "TETS", "cells_kind", "class_kind",
           "foreign_package", "is_surface", "is_tets", "mesh_kind", "meshio_blocks"]

#: the kinds' names (the ``name`` of each :class:`..cells.base.CellKind`, and what
#: ``meshopt info`` prints as ``cell_kind``)
PLANAR, SURFACE, TETS = "planar triangles", "surface triangles", "tetrahedra"
KIND_NAMES = (PLANAR, SURFACE, TETS)

#: meshio cell types beside the cells of a kind (boundary elements, tags)
_BESIDE = {"tetra": ("triangle", "line", "vertex"), "triangle": ("line", "vertex")}
#: plural names of the meshio cell types no kind takes
_PLURAL = {"quad": "quadrilaterals", "hexahedron": "hexahedra", "wedge": "wedges (prisms)",
           "pyramid": "pyramids", "polygon": "polygons", "line": "only lines",
           "vertex": "only vertices"}
#: the cell types of a file that a kind reads
_SIMPLICES = ("tetra", "triangle", "line", "vertex")


def foreign_package(mesh) -> str | None:
    """``"trimesh"``, ``"pymeshlab"`` or ``"meshio"`` for those packages' mesh classes
    (recognized by module, never imported here), else None."""
    package = type(mesh).__module__.split(".")[0]
    name = type(mesh).__name__
    if (package, name) in (("trimesh", "Trimesh"), ("pymeshlab", "Mesh"), ("meshio", "Mesh")):
        return package
    return None


def _in_xy(points: np.ndarray) -> bool:
    return points.shape[1] == 2 or not np.any(points[:, 2])


def mesh_kind(mesh, what: str = "meshopt") -> str:
    """The kind (:data:`KIND_NAMES`) of one of our meshes or a trimesh, pymeshlab or
    meshio mesh.

    Raises
    ------
    OptionError
        ``mesh`` is none of these objects.
    InvalidMeshError
        A ``meshio.Mesh`` with cells no kind takes, or none (:func:`meshio_blocks`).
    """
    kind = class_kind(mesh)
    if kind is not None:
        return kind
    if isinstance(mesh, TriangleMesh):
        return PLANAR if mesh.is_planar else SURFACE
    package = foreign_package(mesh)
    if package == "meshio":
        main, _ = meshio_blocks(mesh, what)
        return TETS if main == "tetra" else \
            PLANAR if _in_xy(np.asarray(mesh.points)) else SURFACE
    if package is not None:
        return SURFACE
    raise OptionError(f"{what} takes a PlanarMesh, TriangleMesh, SurfaceMesh, TetMesh, "
                      f"trimesh.Trimesh, pymeshlab.Mesh or meshio.Mesh, got "
                      f"{type(mesh).__module__}.{type(mesh).__name__}")


def class_kind(mesh) -> str | None:
    """The kind that one of our meshes has by its class alone: :data:`TETS` for a
    :class:`~.volume.TetMesh`, :data:`SURFACE` for a :class:`~.surface.SurfaceMesh`, None
    for anything else (triangles whose kind follows from their points, other objects)."""
    return TETS if isinstance(mesh, TetMesh) else SURFACE if isinstance(mesh, SurfaceMesh) \
        else None


def is_tets(mesh) -> bool:
    """Whether ``mesh`` (one of ours) is a tetrahedral mesh."""
    return class_kind(mesh) == TETS


def is_surface(mesh) -> bool:
    """Whether ``mesh`` (one of ours) is a :class:`~.surface.SurfaceMesh`, the object that
    makes triangles a surface in space whatever their points."""
    return class_kind(mesh) == SURFACE


def meshio_blocks(mesh, what: str) -> tuple[str, list]:
    """The main cell type (``"tetra"`` or ``"triangle"``) of a ``meshio.Mesh`` and its
    ``(type, data)`` blocks with cells.

    Raises
    ------
    InvalidMeshError
        Cells no kind takes beside them (quadrilaterals, hexahedra, …), or no cells.
    """
    blocks = [(b.type, np.asarray(b.data)) for b in mesh.cells if len(b.data)]
    types = {t for t, _ in blocks}
    main = "tetra" if "tetra" in types else "triangle" if "triangle" in types else None
    other = sorted(types - ({main, *_BESIDE[main]} if main else set()))
    if main is None or other:
        names = ", ".join(_PLURAL.get(t, f"{t} cells") for t in (other or sorted(types)))
        raise InvalidMeshError(f"the mesh has {names or 'no cells'}; {what} supports "
                               "triangles and tetrahedra")
    return main, blocks


def cells_kind(cm) -> str:
    """The kind of the mesh an operation reads from a file's cells ``cm`` (a
    :class:`~..io.cells.CellMesh`: ``points`` and ``(type, data)`` ``cells``): any
    tetrahedron makes it :data:`TETS`; triangles are :data:`PLANAR` on any one plane (2D
    points, every z 0, or another plane), else :data:`SURFACE`. With no triangle, or with
    cell types beside them that no kind takes, it is :data:`PLANAR`: the planar reading
    names what is wrong."""
    if any(t == "tetra" and len(c) for t, c in cm.cells):
        return TETS
    pts = np.asarray(cm.points)
    if _in_xy(pts):
        return PLANAR
    tris = [c for t, c in cm.cells if t == "triangle" and len(c)]
    if not tris or any(t not in _SIMPLICES and len(c) for t, c in cm.cells):
        return PLANAR
    from ..orientation import plane_of

    tri = np.concatenate(tris)
    used = np.unique(tri)
    emb, _ = plane_of(pts[used], tri if len(used) == len(pts) else None)
    return PLANAR if emb is not None else SURFACE
