"""Conversions between :class:`~meshopt_toolkit.mesh.TriangleMesh` and meshio, trimesh and
pymeshlab objects, keeping the vertex order and connectivity exactly.

A :class:`~meshopt_toolkit.mesh.SurfaceMesh` goes to the same ``to_*`` functions (its
points are ``(N, 3)``); :func:`surface_from_trimesh` and :func:`surface_from_pymeshlab`
bring a surface back as a ``SurfaceMesh``, planar or not.

trimesh and pymeshlab are imported only when their converter is called. A converted-back
mesh is a :class:`~meshopt_toolkit.mesh.PlanarMesh` when its points are 2D or every z is
exactly 0, else a :class:`~meshopt_toolkit.mesh.TriangleMesh`.

:class:`Carried` is how the operations (``mt.move``, ``mt.morph``, ``mt.deform``) take a
library object and give one back: the object seen as one of our meshes, and the same object
with its points replaced and everything else it carries kept (:meth:`Carried.with_points`).
"""

from __future__ import annotations

import copy
import logging
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import InvalidMeshError
from .kernels.surface import pad3
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
    "Carried",
    "CarriedResult",
    "DataLossWarning",
]

_PHYSICAL = "gmsh:physical"
_GEOMETRICAL = "gmsh:geometrical"


def _points3d(points: np.ndarray) -> np.ndarray:
    """A writable ``(N, 3)`` copy of ``points`` (z = 0 added to 2D points)."""
    return np.array(pad3(points))


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


# ----------------------------------------------------------------------------- carrying
class DataLossWarning(UserWarning):
    """A datum of a library object that its moved copy cannot hold (one line naming it).

    ``warnings.simplefilter("error", DataLossWarning)`` turns it into a refusal.
    """


#: the class of the library objects the operations take, by package
_LIBRARY_CLASSES = {"meshio": "Mesh", "trimesh": "Trimesh", "pymeshlab": "Mesh"}

#: what a new ``pymeshlab.Mesh`` takes of the old one: (constructor argument, test, getter)
_PYMESHLAB_DATA = (
    ("v_scalar_array", "has_vertex_scalar", "vertex_scalar_array"),
    ("f_scalar_array", "has_face_scalar", "face_scalar_array"),
    ("v_color_matrix", "has_vertex_color", "vertex_color_matrix"),
    ("f_color_matrix", "has_face_color", "face_color_matrix"),
    ("v_tex_coords_matrix", "has_vertex_tex_coord", "vertex_tex_coord_matrix"),
    ("w_tex_coords_matrix", "has_wedge_tex_coord", "wedge_tex_coord_matrix"),
    ("edge_matrix", "edge_number", "edge_matrix"),
)


def _package(obj) -> str | None:
    package = type(obj).__module__.split(".")[0]
    return package if package in _LIBRARY_CLASSES else None


def _meshio_view(m: "meshio.Mesh"):
    """A meshio mesh as the mesh an operation takes: a TetMesh when it has tetrahedra, a
    PlanarMesh when its points are 2D or every z is 0, else a SurfaceMesh; every point
    kept, in order."""
    from .io.cells import CellMesh
    from .mesh.kinds import PLANAR, TETS, cells_kind, mesh_kind

    cells = CellMesh.from_meshio(m)
    if cells_kind(cells) == TETS:
        return cells.to_tet_mesh()
    mesh = cells.to_triangle_mesh()  # other cells refused in its words
    return mesh if mesh_kind(m) == PLANAR else cells.to_surface_mesh()


def _meshio_with_points(m: "meshio.Mesh", points: np.ndarray) -> "meshio.Mesh":
    out = copy.deepcopy(m)
    if points.shape[1] < np.shape(m.points)[1]:  # moved in the plane: z (all 0) stays
        points = np.column_stack([points, np.asarray(m.points)[:, points.shape[1]:]])
    out.points = points
    return out


def _trimesh_with_points(t: "trimesh.Trimesh", points: np.ndarray) -> "trimesh.Trimesh":
    out = t.copy()  # visuals, attributes and metadata; not the cache (normals)
    out.vertices = points
    return out


def _pymeshlab_with_points(m: "pymeshlab.Mesh", points: np.ndarray) -> "pymeshlab.Mesh":
    import pymeshlab

    data = {arg: getattr(m, get)() for arg, has, get in _PYMESHLAB_DATA if getattr(m, has)()}
    out = pymeshlab.Mesh(vertex_matrix=points, face_matrix=m.face_matrix(), **data)
    out.set_label(m.label())
    return out


def _pymeshlab_losses(m: "pymeshlab.Mesh") -> list[str]:
    """What a new ``pymeshlab.Mesh`` cannot be given of ``m`` (pymeshlab has no setter)."""
    lost = []
    if m.texture_number():
        lost.append(f"its textures ({', '.join(sorted(m.textures()))})")
    if m.selected_vertex_number() or m.selected_face_number():
        lost.append("its selection")
    if not np.array_equal(m.transform_matrix(), np.eye(4)):
        lost.append("its transform matrix")
    return lost


_WITH_POINTS = {"meshio": _meshio_with_points, "trimesh": _trimesh_with_points,
                "pymeshlab": _pymeshlab_with_points}


@dataclass(frozen=True)
class Carried:
    """A meshio, trimesh or pymeshlab object seen as one of our meshes, and the way back.

    What comes back (:meth:`with_points`) is an object of the type given with the new
    points and everything else the object carries:

    - ``meshio.Mesh``: cells, ``point_data``, ``cell_data``, ``field_data``,
      ``point_sets``, ``cell_sets`` and the rest (a deep copy); 2D points stay 2D, a planar
      motion keeps the z column (all 0) as it was.
    - ``trimesh.Trimesh``: its visual (``TextureVisuals`` with uv and material, vertex or
      face colours), ``vertex_attributes``, ``face_attributes`` and ``metadata`` (a copy);
      normals are not carried: trimesh computes them from the new points when asked.
    - ``pymeshlab.Mesh``: vertex and wedge texture coordinates, vertex and face colours,
      vertex and face quality (scalars), edges and the label; normals are computed by
      pymeshlab for the new points. pymeshlab cannot give a new mesh textures, a
      selection or a transform matrix: :meth:`result` warns in one line
      (:class:`DataLossWarning`) naming those the object has. pymeshlab does not list a
      mesh's custom attributes, so none can be carried: add them again by name.

    Attributes
    ----------
    original : the object given
    mesh : PlanarMesh, SurfaceMesh or TetMesh
        What the operations work on: trimesh and pymeshlab objects are surfaces; a meshio
        mesh is a TetMesh when it has tetrahedra, planar when its points are 2D or every z
        is 0, else a surface. Its points are the object's, in order.
    """

    original: Any
    mesh: Any

    @classmethod
    def of(cls, obj) -> "Carried | None":
        """``obj`` carried, or None when it is not a library object (one of our meshes).

        Raises
        ------
        InvalidMeshError
            An object of those libraries that is not a mesh the operations take (a
            ``trimesh.Scene``, a ``trimesh.PointCloud``), or cells they do not take.
        """
        package = _package(obj)
        if package is None:
            return None
        if type(obj).__name__ != _LIBRARY_CLASSES[package]:
            raise InvalidMeshError(f"a {package}.{type(obj).__name__} is not a mesh; give a "
                                   f"{package}.{_LIBRARY_CLASSES[package]}")
        if package == "trimesh":
            return cls(obj, surface_from_trimesh(obj))
        if package == "pymeshlab":
            return cls(obj, surface_from_pymeshlab(obj))
        return cls(obj, _meshio_view(obj))

    @property
    def package(self) -> str:
        """``"meshio"``, ``"trimesh"`` or ``"pymeshlab"``."""
        return _package(self.original)

    def with_points(self, points) -> Any:
        """The object with its points replaced by ``points`` (``(N, 2)`` or ``(N, 3)``, in
        the order of :attr:`mesh`'s) and everything else kept (see the class)."""
        return _WITH_POINTS[self.package](self.original, np.array(points, dtype=np.float64))

    def lost(self) -> list[str]:
        """What the moved objects cannot hold (pymeshlab: textures, selection, transform)."""
        return _pymeshlab_losses(self.original) if self.package == "pymeshlab" else []

    def result(self, result) -> "CarriedResult":
        """``result`` (of an operation on :attr:`mesh`) with its meshes of the type given;
        a :class:`DataLossWarning` names what they cannot hold."""
        if lost := self.lost():
            warnings.warn(f"{self.package}.{type(self.original).__name__}: "
                          f"{' and '.join(lost)} cannot be set on a new mesh; the results "
                          "have none", DataLossWarning, stacklevel=3)
        def typed(mesh):  # the input itself where the operation returns it
            return self.original if mesh is self.mesh else self.with_points(mesh.points)

        return CarriedResult(mesh=typed(result.mesh), frames=[typed(f) for f in result.frames],
                             result=result)


@dataclass
class CarriedResult:
    """An operation's result with its meshes of the caller's type (the
    :class:`~meshopt_toolkit.results.Result` protocol).

    Attributes
    ----------
    mesh : the final mesh, of the type given (see :class:`Carried` for what it keeps)
    frames : list of the same type (first the input, itself where the operation returned
        it, last ``mesh``)
    result : the operation's own result, on our meshes; its other attributes
        (``similarity``, ``motion``, …) are read through this one.
    """

    mesh: Any
    frames: list
    result: Any

    seconds = property(lambda self: self.result.seconds, doc="Wall time.")
    status = property(lambda self: self.result.status, doc="The operation's status.")

    def summary(self) -> dict:
        return self.result.summary()

    def __getattr__(self, name: str):
        if name.startswith("__") or name == "result":
            raise AttributeError(name)
        return getattr(self.result, name)
