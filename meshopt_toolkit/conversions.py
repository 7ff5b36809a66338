"""Conversions between :class:`~meshopt_toolkit.mesh.TriangleMesh` and meshio, trimesh and
pymeshlab objects, keeping the vertex order and connectivity exactly.

A :class:`~meshopt_toolkit.mesh.SurfaceMesh` goes to the same ``to_*`` functions (its
points are ``(N, 3)``); :func:`surface_from_trimesh` and :func:`surface_from_pymeshlab`
bring a surface back as a ``SurfaceMesh``, planar or not.

trimesh and pymeshlab are imported only when their converter is called. A converted-back
mesh is a :class:`~meshopt_toolkit.mesh.PlanarMesh` when its points are 2D or every z is
exactly 0, else a :class:`~meshopt_toolkit.mesh.TriangleMesh`.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

from .mesh import PlanarMesh, SurfaceMesh, TriangleMesh

if TYPE_CHECKING:  # pragma: no cover
    import meshio
    import pymeshlab
    import trimesh

logger = logging.getLogger(__name__)

__all__ = [
    "to_meshio",
    "from_meshio",
    "to_trimesh",
    "from_trimesh",
    "to_pymeshlab",
    "from_pymeshlab",
    "surface_from_trimesh",
    "surface_from_pymeshlab",
]

_PHYSICAL = "gmsh:physical"
_GEOMETRICAL = "gmsh:geometrical"


def _points3d(points: np.ndarray) -> np.ndarray:
    if points.shape[1] == 3:
        return np.array(points, dtype=np.float64)
    out = np.zeros((len(points), 3))
    out[:, :2] = points
    return out


def _mesh(points, triangles, source=None, **tags) -> TriangleMesh:
    """PlanarMesh when 2D or z ≡ 0, else TriangleMesh."""
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim == 2 and (pts.shape[1] == 2 or (pts.shape[1] == 3 and not np.any(pts[:, 2]))):
        return PlanarMesh(pts, triangles, source=source, **tags)
    return TriangleMesh(pts, triangles, source=source, **tags)


# ----------------------------------------------------------------------------- meshio
def to_meshio(mesh: TriangleMesh, *, pad_z: bool = True) -> "meshio.Mesh":
    """A ``meshio.Mesh`` with a "triangle" block (and a "line" block for tagged lines).

    Parameters
    ----------
    mesh : TriangleMesh
    pad_z : bool
        Give 2D points a zero z column, ``(N, 3)``; several meshio writers need it.

    Physical tags go to ``cell_data["gmsh:physical"]`` (and ``"gmsh:geometrical"``), names
    to ``field_data`` as ``{name: [tag, dim]}``, as meshio's gmsh reader produces them.
    """
    import meshio

    from .io.cells import tagged_blocks

    points = _points3d(mesh.points) if pad_z else np.array(mesh.points)
    cells, phys, tagged = tagged_blocks(mesh)
    cells = [(kind, np.array(block)) for kind, block in cells]  # writable copies
    cell_data = {}
    if tagged:
        cell_data = {_PHYSICAL: phys, _GEOMETRICAL: [np.where(p > 0, p, 1) for p in phys]}
    field_data = {name: np.array([tag, dim]) for name, (tag, dim) in mesh.tag_names.items()}
    return meshio.Mesh(points, cells, cell_data=cell_data, field_data=field_data)


def from_meshio(m: "meshio.Mesh", source: str | None = None) -> TriangleMesh:
    """The triangles (and line elements) of a ``meshio.Mesh``, in block order.

    Every point is kept, in order. ``cell_data["gmsh:physical"]`` becomes
    ``triangle_tags`` / ``line_tags`` (all-zero triangle tags mean "untagged") and
    ``field_data`` the ``tag_names``. Vertex cells and other data are left out (logged);
    for everything use :meth:`meshopt_toolkit.io.CellMesh.from_meshio`.

    Raises
    ------
    InvalidMeshError
        Cells other than triangles, lines and vertices (quads, polygons, volumes: named
        with their counts), no triangle, or a readable-level check fails.
    """
    from .io.cells import CellMesh

    return CellMesh.from_meshio(m, source=source).to_triangle_mesh()


# ----------------------------------------------------------------------------- trimesh
def to_trimesh(mesh: TriangleMesh) -> "trimesh.Trimesh":
    """A ``trimesh.Trimesh`` built with ``process=False`` (no merging or reordering);
    2D points get z = 0."""
    import trimesh

    return trimesh.Trimesh(
        vertices=_points3d(mesh.points), faces=np.array(mesh.triangles), process=False
    )


def from_trimesh(t: "trimesh.Trimesh", source: str | None = None) -> TriangleMesh:
    """The vertices and faces of a ``trimesh.Trimesh``, as they are (no processing)."""
    return _mesh(np.asarray(t.vertices, dtype=np.float64), np.asarray(t.faces), source=source)


# ----------------------------------------------------------------------------- pymeshlab
def to_pymeshlab(mesh: TriangleMesh) -> "pymeshlab.Mesh":
    """A ``pymeshlab.Mesh`` with ``(N, 3)`` float64 vertices (z = 0 for planar meshes).

    Add it to a ``MeshSet`` with ``ms.add_mesh(m)``; vertex order is kept by filters that
    do not change the topology.
    """
    import pymeshlab

    return pymeshlab.Mesh(
        vertex_matrix=_points3d(mesh.points),
        face_matrix=np.ascontiguousarray(mesh.triangles, dtype=np.int32),
    )


def from_pymeshlab(m: "pymeshlab.Mesh", source: str | None = None) -> TriangleMesh:
    """A mesh from ``pymeshlab.Mesh`` vertices and faces (PlanarMesh when z ≡ 0)."""
    return _mesh(
        np.asarray(m.vertex_matrix(), dtype=np.float64),
        np.asarray(m.face_matrix(), dtype=np.int64),
        source=source,
    )


# ----------------------------------------------------------------------------- surfaces
def surface_from_trimesh(t: "trimesh.Trimesh", source: str | None = None) -> SurfaceMesh:
    """The vertices and faces of a ``trimesh.Trimesh`` as a :class:`SurfaceMesh`, as they
    are (build the ``Trimesh`` with ``process=False`` to keep a file's order)."""
    return SurfaceMesh(np.asarray(t.vertices, dtype=np.float64),
                       np.asarray(t.faces, dtype=np.int64), source=source)


def surface_from_pymeshlab(m: "pymeshlab.Mesh", source: str | None = None) -> SurfaceMesh:
    """The vertices and faces of a ``pymeshlab.Mesh`` as a :class:`SurfaceMesh`."""
    return SurfaceMesh(np.asarray(m.vertex_matrix(), dtype=np.float64),
                       np.asarray(m.face_matrix(), dtype=np.int64), source=source)
