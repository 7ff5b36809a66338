"""A document: the meshes a pipeline works on, with per-vertex and per-face attributes.

Attribute names with a MeshLab meaning are mapped onto MeshLab's own storage when the
document is converted to a ``pymeshlab.MeshSet``:

=============  =========================  ==============================================
name           shape                      MeshLab storage
=============  =========================  ==============================================
``quality``    vertex ``(N,)``/face ``(T,)``  vertex / face quality (scalar)
``color``      ``(N, 4)`` / ``(T, 4)``    vertex / face color (RGBA in [0, 1])
``selected``   ``(N,)`` / ``(T,)`` bool   selection (read back only, see below)
other          ``(N,)`` / ``(T,)``        custom scalar attributes
other          ``(N, 3)`` / ``(T, 3)``    custom point attributes
=============  =========================  ==============================================

So a face quality stored by a meshopt filter is what a following MeshLab filter that reads
face quality (e.g. "Select by Face Quality") sees. Custom attributes are added to the
mesh *after* ``add_mesh`` (adding them before and saving PLY crashes pymeshlab).
pymeshlab has no setter for selections: a selection made by a MeshLab step is read back
into ``selected`` and kept for the following MeshLab steps of the same run of consecutive
MeshLab steps (they share one MeshSet), but is not pushed back into a new MeshSet.

Vertex and face order survive the round trip (pymeshlab keeps them for filters that do
not change topology). When a MeshLab step keeps the faces, physical tags and line
elements of the mesh are kept too, and so is everything its file holds (blocks, groups,
point and cell data: the entry's ``source_workpiece`` of a planar mesh, ``source_cells``
of a surface in 3D or a tet mesh). When a MeshLab step changes the faces, what cannot
follow is named in one warning of the run (:attr:`Document.warnings`), never dropped
silently. A tet mesh (a :class:`~meshopt_toolkit.mesh.TetMesh` entry) cannot go to
pymeshlab, which holds triangles only: a MeshLab step on it is refused.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import FilterError
from ..mesh import PlanarMesh, TetMesh, TriangleMesh
from ..mesh.kinds import PLANAR, SURFACE, TETS, cells_kind, is_surface, is_tets, mesh_kind
from .limits import DEFAULT_MAX_TRIANGLES
from .meshset import add_custom, lost_extras, mesh_ids, read_custom

if TYPE_CHECKING:  # pragma: no cover
    from ..io.cells import CellMesh
    from ..io.workpiece import Workpiece

logger = logging.getLogger(__name__)

__all__ = ["MeshEntry", "Document", "load_entry", "save_entry", "kind_of", "KIND_NAMES",
           "MESH_KINDS", "PLANAR", "SURFACE", "TETS"]

_SPECIAL = ("quality", "color", "selected")

#: the kinds of current mesh a step may take (:attr:`~.filter.Filter.kinds`): planar
#: triangles (on any one plane), a triangle surface in 3D, tetrahedra (the names of the
#: cell kinds of ``meshopt info``)
MESH_KINDS = (PLANAR, SURFACE, TETS)
#: each kind of mesh in words
KIND_NAMES = {PLANAR: "a planar triangle mesh", SURFACE: "a triangle surface in 3D",
              TETS: "a tetrahedral mesh"}


def kind_of(mesh) -> str:
    """The kind of a document's mesh (:data:`MESH_KINDS`), as
    :func:`~meshopt_toolkit.mesh.kinds.mesh_kind` decides it: :data:`PLANAR` for
    triangles on one plane (any plane: what :meth:`MeshEntry.workpiece` takes)."""
    return mesh_kind(mesh, "a pipeline")


@dataclass
class MeshEntry:
    """One mesh of a document with its attributes.

    Attributes
    ----------
    mesh : TriangleMesh or TetMesh
        The mesh (a :class:`PlanarMesh` when planar; a tet mesh from a file with
        tetrahedra).
    name : str
        A label (file stem or filter output name).
    vertex_attributes : dict of str to ndarray
        ``(N,)`` or ``(N, k)`` arrays.
    face_attributes : dict of str to ndarray
        ``(T,)`` or ``(T, k)`` arrays.
    source_workpiece : Workpiece or None
        What the mesh's file holds beyond the triangles (every block, tag and datum, the
        plane): set by :func:`load_entry` and the planar filters, used by
        :meth:`workpiece` and :func:`save_entry` while the mesh keeps its triangles.
    source_cells : CellMesh or None
        What the file of a mesh in space (a surface in 3D, a tet mesh) holds: every
        block, tag and datum, written by :func:`save_entry` at the mesh's points while
        the mesh keeps the file's triangles (tetrahedra) and vertices.
    """

    mesh: TriangleMesh | TetMesh
    name: str = "mesh"
    vertex_attributes: dict[str, np.ndarray] = field(default_factory=dict)
    face_attributes: dict[str, np.ndarray] = field(default_factory=dict)
    source_workpiece: Workpiece | None = None
    source_cells: CellMesh | None = None

    @property
    def keeps_source_cells(self) -> bool:
        """Whether :attr:`source_cells` still describes the mesh (same vertex count, same
        triangles or tetrahedra in the same order)."""
        cells = self.source_cells
        if cells is None or len(cells.points) != self.mesh.n_vertices:
            return False
        kind = "tetra" if is_tets(self.mesh) else "triangle"
        mine = self.mesh.tets if kind == "tetra" else self.mesh.triangles
        blocks = [c for t, c in cells.cells if t == kind]
        return bool(blocks) and np.array_equal(np.concatenate(blocks), mine)

    def point_data(self) -> dict[str, np.ndarray]:
        """The vertex data of the mesh: its file's point data (while the file describes
        the mesh) and the vertex attributes computed in the pipeline (these win where a
        name is in both)."""
        wp = self.source_workpiece
        if self.keeps_source_cells:
            data = dict(self.source_cells.point_data)
        elif wp is not None and len(wp.cells.points) == self.mesh.n_vertices:
            data = dict(wp.cells.point_data)
        else:
            data = {}
        return {**data, **self.vertex_attributes}

    def workpiece(self, what: str = "this filter", *, required: bool = True
                  ) -> Workpiece | None:
        """The mesh as a :class:`~meshopt_toolkit.io.workpiece.Workpiece` (its plane's
        coordinates at the file's scale: the operations scale it themselves), with the
        extras of its file while the mesh keeps their triangles.

        Raises
        ------
        FilterError
            The mesh is not on one plane (None instead when not ``required``).
        """
        from ..errors import InvalidMeshError
        from ..io.workpiece import Workpiece

        if is_tets(self.mesh):
            if not required:
                return None
            raise FilterError(f"{what} needs a planar mesh; {self.name} has "
                              f"{self.mesh.n_tets} tetrahedra")
        wp = self.source_workpiece
        try:
            if wp is not None and np.array_equal(wp.mesh.triangles, self.mesh.triangles):
                if not _same_points(wp.cells.points, self.mesh.points):
                    wp = wp.with_file_points(self.mesh.points)  # moved by a MeshLab step
            else:
                wp = Workpiece.from_mesh(self.mesh)
        except InvalidMeshError as exc:
            if not required:
                return None
            raise FilterError(f"{what} needs a planar mesh; {self.name}: {exc}") from None
        return wp

    def set_workpiece(self, wp: Workpiece) -> None:
        """Make ``wp`` this entry's mesh (in file coordinates) and its extras."""
        self.mesh = wp.file_mesh()
        self.source_workpiece = wp

    def set_vertex_attribute(self, name: str, values) -> None:
        a = np.asarray(values)
        if a.shape[:1] != (self.mesh.n_vertices,):
            raise FilterError(f"vertex attribute {name!r} needs {self.mesh.n_vertices} rows, got {a.shape}")
        self.vertex_attributes[name] = a

    def set_face_attribute(self, name: str, values) -> None:
        a = np.asarray(values)
        n = _n_cells(self.mesh)
        if a.shape[:1] != (n,):
            raise FilterError(f"face attribute {name!r} needs {n} rows, got {a.shape}")
        self.face_attributes[name] = a

    def replace_mesh(self, mesh: TriangleMesh, *, keep_vertex: bool | None = None,
                     keep_face: bool | None = None) -> None:
        """Swap in a new mesh; attributes are kept only where the sizes still match."""
        same_v = mesh.n_vertices == self.mesh.n_vertices
        same_f = _n_cells(mesh) == _n_cells(self.mesh)
        if not (same_v if keep_vertex is None else keep_vertex):
            self.vertex_attributes = {}
        if not (same_f if keep_face is None else keep_face):
            self.face_attributes = {}
        self.mesh = mesh


def _n_cells(mesh) -> int:
    """Triangles of a triangle mesh, tetrahedra of a tet mesh."""
    return mesh.n_tets if is_tets(mesh) else mesh.n_triangles


def _as_best(mesh):
    """A PlanarMesh where z drops exactly; other planes stay in file coordinates (the
    planar filters see them through :meth:`MeshEntry.workpiece`); a SurfaceMesh as its
    TriangleMesh, a TetMesh as it is."""
    if is_tets(mesh):
        return mesh
    if is_surface(mesh):
        mesh = mesh.as_triangle_mesh()
    return mesh.as_planar() if mesh.in_xy_plane else mesh


def _same_points(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape[1] != b.shape[1]:
        a, b = (a, b) if a.shape[1] == 3 else (b, a)
        return a.shape[0] == b.shape[0] and not np.any(a[:, 2]) and np.array_equal(a[:, :2], b)
    return np.array_equal(a, b)


def load_entry(path) -> MeshEntry:
    """A mesh file as a document entry: its triangle mesh, and everything else it holds
    (blocks, tags, data) kept for :func:`save_entry` where the mesh is planar.

    Raises
    ------
    ReadError
        As :func:`meshopt_toolkit.io.load`.
    """
    from ..errors import InvalidMeshError, ReadError
    from ..io import load_cells
    from ..io.cells import triangle_mesh
    from ..io.workpiece import Workpiece

    cells = load_cells(path)
    name = Path(path).stem
    if cells_kind(cells) == TETS:
        try:
            return MeshEntry(cells.to_tet_mesh("a pipeline"), name=name, source_cells=cells)
        except InvalidMeshError as exc:
            raise ReadError(str(exc)) from exc
    entry = MeshEntry(_as_best(triangle_mesh(cells)), name=name)
    if kind_of(entry.mesh) == PLANAR:
        entry.set_workpiece(Workpiece.from_cells(cells))
    else:  # a surface in 3D: its file's blocks, tags and data kept beside it
        entry.source_cells = cells
    return entry


def entry_cells(entry: MeshEntry) -> tuple[CellMesh, tuple[str, ...]]:
    """The cells :func:`save_entry` writes, and the names of the data computed in the
    pipeline (the entry's vertex and face attributes)."""
    from ..io.cells import CellMesh
    from ..io.workpiece import cells_with_attributes

    wp = entry.source_workpiece
    if entry.keeps_source_cells:  # a mesh in space: the file's cells at its points
        cells = replace(entry.source_cells, points=np.array(entry.mesh.points, dtype=float))
    elif is_tets(entry.mesh):
        cells = CellMesh.from_tet_mesh(entry.mesh)
    elif wp is not None and np.array_equal(wp.mesh.triangles, entry.mesh.triangles):
        # the file's cells at the mesh's points (wherever a MeshLab step put them)
        pts = np.asarray(entry.mesh.points)
        if pts.shape[1] < wp.cells.points.shape[1]:
            pts = np.column_stack([pts, np.zeros(len(pts))])
        cells = replace(wp.cells, points=pts)
    else:
        if wp is not None or entry.source_cells is not None:
            logger.warning("%s: the faces changed since the file was read: its blocks, "
                           "groups and data are not kept", entry.name)
        cells = CellMesh.from_triangle_mesh(entry.mesh)
    fa, va = entry.face_attributes, entry.vertex_attributes
    return cells_with_attributes(cells, fa, va), tuple(fa) + tuple(va)


def save_entry(entry: MeshEntry, path, **kwargs) -> Path:
    """Write an entry with every block, tag and datum of its file, and its attributes as
    cell and point data (what the format cannot hold is left out with a warning);
    ``kwargs`` are those of :func:`meshopt_toolkit.io.save_cells`."""
    from ..io.workpiece import save_workpiece

    cells, computed = entry_cells(entry)
    return save_workpiece(cells, path, computed=computed, **kwargs)


class Document:
    """An ordered list of meshes with a current one (like a MeshLab project).

    Parameters
    ----------
    meshes : iterable of TriangleMesh or MeshEntry, optional
    current : int, optional
        Index of the current mesh (default: the last one).

    Attributes
    ----------
    entries : list of MeshEntry
    current : int
    results : list of dict
        One ``{"filter": name, ...summary}`` per step that returned a summary.
    output_dir : pathlib.Path or None
        The only folder a pipeline writes into (``meshopt run -o``); the current
        directory when None. See :mod:`meshopt_toolkit.pipeline.paths`.
    overwrite : bool
        Whether save steps may replace existing files (``--force``: the command line is
        the only authority; a pipeline's own ``overwrite`` parameter cannot grant it).
    dry_run : bool
        Save steps validate but do not write.
    variables : dict
        Values of the path template fields ``{stem}``, ``{suffix}``, ``{ext}``,
        ``{index}``, ``{input_dir}`` (``{name}`` is the current mesh's name).
    inputs : list of path
        Files a pipeline may read (the run's inputs) when reads are confined.
    allow_read : list of path or None
        Further files or folders a pipeline may read (``--allow-read``). None (the
        default for documents made in Python) leaves reads to the calling program; a list
        (``meshopt run`` always gives one) confines them to ``inputs`` and these paths.
    max_triangles : int
        The size budget: triangles of the current mesh after any step (``--max-triangles``).
    allow_inverted : bool
        Let a MeshLab step that inverts triangles of a planar mesh go on with a warning
        instead of failing (``--allow-inverted``).
    warnings : list of str
        One line per warning of the run (step named, from 1).
    written : list of str
        Files written by save steps.
    """

    def __init__(self, meshes=(), current: int | None = None) -> None:
        self.entries: list[MeshEntry] = []
        for m in meshes:
            self.add(m)
        if current is not None:
            self.set_current(current)
        self.results: list[dict] = []
        self.output_dir = None
        self.overwrite = False
        self.dry_run = False
        self.variables: dict[str, str] = {}
        self.inputs: list = []
        self.allow_read: list | None = None
        self.max_triangles: int = DEFAULT_MAX_TRIANGLES
        self.allow_inverted = False
        self.warnings: list[str] = []
        self.written: list[str] = []

    # -- meshes ---------------------------------------------------------------------
    def add(self, mesh: TriangleMesh | MeshEntry, name: str | None = None) -> MeshEntry:
        """Append a mesh and make it current."""
        entry = mesh if isinstance(mesh, MeshEntry) else MeshEntry(_as_best(mesh))
        if name is not None:
            entry.name = name
        elif not isinstance(mesh, MeshEntry) and getattr(mesh, "source", None):
            from pathlib import Path

            entry.name = Path(mesh.source).stem
        self.entries.append(entry)
        self.current = len(self.entries) - 1
        return entry

    def set_current(self, index: int) -> None:
        if not -len(self.entries) <= index < len(self.entries):
            raise FilterError(f"document has {len(self.entries)} meshes, no mesh {index}")
        self.current = index % len(self.entries)

    def __len__(self) -> int:
        return len(self.entries)

    @property
    def current_entry(self) -> MeshEntry:
        if not self.entries:
            raise FilterError("the document has no mesh (load one first)")
        return self.entries[self.current]

    @property
    def mesh(self) -> TriangleMesh:
        """The current mesh."""
        return self.current_entry.mesh

    # -- pymeshlab ------------------------------------------------------------------
    def require_triangles(self) -> None:
        """Raise FilterError (one line) when a mesh of the document is a tet mesh, which
        pymeshlab cannot hold."""
        for e in self.entries:
            if is_tets(e.mesh):
                raise FilterError(f"MeshLab filters work on triangles; {e.name} has "
                                  f"{e.mesh.n_tets:,} tetrahedra, which pymeshlab cannot hold")

    def to_meshset(self):
        """A ``pymeshlab.MeshSet`` with every mesh in order (same vertex/face order).

        Quality and colors go into MeshLab's scalar/color storage; other attributes into
        custom attributes added after ``add_mesh``. The current mesh is made current.
        """
        import pymeshlab

        from ..conversions import to_pymeshlab

        self.require_triangles()
        ms = pymeshlab.MeshSet()
        for e in self.entries:
            base = to_pymeshlab(e.mesh)
            kw: dict[str, Any] = {}
            va, fa = e.vertex_attributes, e.face_attributes
            if "quality" in va and np.ndim(va["quality"]) == 1:
                kw["v_scalar_array"] = np.asarray(va["quality"], np.float64)
            if "quality" in fa and np.ndim(fa["quality"]) == 1:
                kw["f_scalar_array"] = np.asarray(fa["quality"], np.float64)
            if "color" in va and np.shape(va["color"])[1:] == (4,):
                kw["v_color_matrix"] = np.asarray(va["color"], np.float64)
            if "color" in fa and np.shape(fa["color"])[1:] == (4,):
                kw["f_color_matrix"] = np.asarray(fa["color"], np.float64)
            m = pymeshlab.Mesh(base.vertex_matrix(), base.face_matrix(), **kw) if kw else base
            ms.add_mesh(m, e.name)
            cm = ms.current_mesh()
            for name, arr in va.items():
                if name not in _SPECIAL:
                    add_custom(cm, "vertex", name, arr)
            for name, arr in fa.items():
                if name not in _SPECIAL:
                    add_custom(cm, "face", name, arr)
        if self.entries:
            ids = mesh_ids(ms)
            ms.set_current_mesh(ids[self.current])
        return ms

    def update_from_meshset(self, ms, step: str = "") -> None:
        """Take the meshes of ``ms`` (after MeshLab filters ran) into this document.

        Meshes are matched by position; geometry, quality, colors, selection and the custom
        attributes this document knows are read back. Tags, and what the mesh's file holds,
        survive when faces are unchanged; where they changed, what is lost is named in one
        line of :attr:`warnings` (``step`` in front: the step that made the change).
        """
        from ..conversions import from_pymeshlab

        ids = mesh_ids(ms)
        new_entries = []
        for pos, mid in enumerate(ids):
            m = ms.mesh(mid)
            if not m.is_compact():  # filters that delete elements leave holes in the arrays
                m.compact()
            old = self.entries[pos] if pos < len(self.entries) else None
            mesh = from_pymeshlab(m)
            if old is not None and np.array_equal(mesh.triangles, old.mesh.triangles):
                kwargs = old.mesh._tag_kwargs()
                cls = PlanarMesh if mesh.in_xy_plane else TriangleMesh
                mesh = cls(mesh.points, mesh.triangles, **kwargs)
            mesh = _as_best(mesh)
            entry = MeshEntry(mesh, name=m.label() or (old.name if old else f"mesh{pos}"))
            same = old is not None and np.array_equal(mesh.triangles, old.mesh.triangles)
            if same:  # the faces are kept, and with them what the file holds
                entry.source_workpiece = old.source_workpiece
                entry.source_cells = old.source_cells if old.keeps_source_cells else None
            nv, nf = mesh.n_vertices, mesh.n_triangles
            for attributes, name, has, values in (
                    (entry.vertex_attributes, "quality", m.has_vertex_scalar, m.vertex_scalar_array),
                    (entry.face_attributes, "quality", m.has_face_scalar, m.face_scalar_array),
                    (entry.vertex_attributes, "color", m.has_vertex_color, m.vertex_color_matrix),
                    (entry.face_attributes, "color", m.has_face_color, m.face_color_matrix)):
                if has():
                    attributes[name] = np.array(values())
            vs, fs = np.array(m.vertex_selection_array()), np.array(m.face_selection_array())
            if vs.shape == (nv,) and vs.any():
                entry.vertex_attributes["selected"] = vs.astype(bool)
            if fs.shape == (nf,) and fs.any():
                entry.face_attributes["selected"] = fs.astype(bool)
            if old is not None:
                for name, arr in old.vertex_attributes.items():
                    if name not in _SPECIAL and len(arr) == nv:
                        entry.vertex_attributes[name] = read_custom(m, "vertex", name, arr)
                for name, arr in old.face_attributes.items():
                    if name not in _SPECIAL and len(arr) == nf:
                        entry.face_attributes[name] = read_custom(m, "face", name, arr)
                lost = [] if same else lost_extras(old, entry)
                if lost:
                    line = (f"{step + ': ' if step else ''}{entry.name}: a MeshLab step "
                            f"changed the faces ({old.mesh.n_triangles:,} -> {nf:,} "
                            f"triangles); not kept: {', '.join(lost)}")
                    self.warnings.append(line)
                    logger.info("%s", line)
            new_entries.append(entry)
        self.entries = new_entries
        cur = ms.current_mesh_id()
        self.current = ids.index(cur) if cur in ids else len(ids) - 1

    @classmethod
    def from_meshset(cls, ms) -> "Document":
        """A new document holding the meshes of ``ms``."""
        doc = cls()
        doc.update_from_meshset(ms)
        return doc
