"""A lossless container for what mesh files hold: :class:`CellMesh`.

``meshopt convert`` reads a file into a :class:`CellMesh` (points, every cell block in
file order, point/cell/field data) and writes it again; a writer that cannot hold some
part refuses with :class:`~meshopt_toolkit.errors.WriteError` naming it, so nothing is
dropped silently. The planar-triangle operations see the same file through
:meth:`CellMesh.to_triangle_mesh`, which keeps triangles, line elements and physical tags
and refuses any other cell type with one line naming the types.

Physical groups travel as meshio does it: ``cell_data["gmsh:physical"]`` and
``cell_data["gmsh:geometrical"]`` (one int array per cell block) and ``field_data``
``{name: [tag, dim]}``; formats with cell data (.vtu) carry them unchanged.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..kernels.admissibility import non_finite_problem
from ..kernels.surface import pad3
from ..errors import InvalidMeshError, ReadError

if TYPE_CHECKING:  # pragma: no cover
    import meshio

    from ..mesh import SurfaceMesh, TetMesh, TriangleMesh

logger = logging.getLogger(__name__)

PHYSICAL = "gmsh:physical"
GEOMETRICAL = "gmsh:geometrical"
GMSH_KEYS = (PHYSICAL, GEOMETRICAL)
#: point data names of per-vertex normals (N, 3) and texture coordinates (N, 2): OBJ
#: ``vn``/``vt``, PLY ``nx ny nz``/``texture_u texture_v``
NORMALS = "normals"
TEXCOORDS = "texture_coordinates"

#: the cell types of a triangle mesh (lines and vertices beside the triangles)
TRIANGLE_KINDS = ("triangle", "line", "vertex")
#: vertices per cell of the common fixed-size cell types (meshio names)
NODES_PER_CELL = {
    "vertex": 1, "line": 2, "triangle": 3, "quad": 4, "tetra": 4, "pyramid": 5,
    "wedge": 6, "hexahedron": 8, "line3": 3, "triangle6": 6, "quad8": 8, "quad9": 9,
    "tetra10": 10,
}
#: topological dimension of the cell types (polygon: 2)
DIMENSION = {
    "vertex": 0, "line": 1, "line3": 1, "triangle": 2, "triangle6": 2, "quad": 2, "quad8": 2,
    "quad9": 2, "polygon": 2, "tetra": 3, "tetra10": 3, "pyramid": 3, "wedge": 3,
    "hexahedron": 3,
}


def cell_dimension(cell_type: str) -> int:
    """Topological dimension of a meshio cell type (meshio's table for rare types)."""
    if cell_type in DIMENSION:
        return DIMENSION[cell_type]
    from meshio._mesh import topological_dimension

    return int(topological_dimension.get(cell_type, 2))


@dataclass
class CellMesh:
    """Points, cell blocks and data of a mesh file, as they are.

    Attributes
    ----------
    points : (N, 2) or (N, 3) float64 array
    cells : list of (type, (M, k) int64 array)
        Cell blocks in file order with meshio's type names (``"triangle"``, ``"quad"``,
        ``"polygon"`` (k > 4 vertices), ``"line"``, ``"vertex"``, ...).
    point_data : dict name → (N, ...) array
    cell_data : dict name → list of one (M_b, ...) array per cell block
    field_data : dict name → array
    source : str, optional
        The file it was read from (named in messages).
    dropped : list of str
        What the reader saw but could not represent (e.g. OBJ groups, texture coordinates
        that are not per vertex): ``meshopt convert`` refuses a mesh whose ``dropped`` is
        not empty unless ``--allow-loss``.
    layout : object, optional
        What the reader knows of the file's own structure beyond cells and data, which a
        writer of the same format keeps while it fits the cells (gmsh: version,
        encoding, entities, node classification; :class:`~.gmsh_layout.GmshLayout`).
    """

    points: np.ndarray
    cells: list[tuple[str, np.ndarray]]
    point_data: dict[str, np.ndarray] = field(default_factory=dict)
    cell_data: dict[str, list[np.ndarray]] = field(default_factory=dict)
    field_data: dict[str, np.ndarray] = field(default_factory=dict)
    source: str | None = None
    dropped: list[str] = field(default_factory=list)
    layout: Any = field(default=None, compare=False, repr=False)

    # -- summary ---------------------------------------------------------------------
    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_cells(self) -> int:
        return int(sum(len(c) for _, c in self.cells))

    def cell_counts(self) -> dict[str, int]:
        """``{type: number of cells}`` in order of first appearance."""
        out: dict[str, int] = {}
        for t, c in self.cells:
            out[t] = out.get(t, 0) + len(c)
        return out

    def describe_cells(self, types=None) -> str:
        """``"18 quad, 4 vertex"`` for the given (default: all) types."""
        counts = self.cell_counts()
        return ", ".join(f"{n} {t}" for t, n in counts.items() if types is None or t in types)

    # -- meshio ----------------------------------------------------------------------
    def to_meshio(self, pad_z: bool = True) -> "meshio.Mesh":
        """A ``meshio.Mesh`` with the same blocks and data (2D points padded with z = 0)."""
        import meshio

        pts = self.points
        if pad_z:
            pts = pad3(pts)
        return meshio.Mesh(pts, [(t, c) for t, c in self.cells],
                           point_data=dict(self.point_data),
                           cell_data={k: list(v) for k, v in self.cell_data.items()},
                           field_data=dict(self.field_data))

    @classmethod
    def from_meshio(cls, m: "meshio.Mesh", source: str | None = None) -> "CellMesh":
        """Everything of a ``meshio.Mesh``; arrays in native byte order.

        meshio's ``point_data["gmsh:dim_tags"]`` (the gmsh entity of each node, which
        meshio invents when reading gmsh 4 files and our gmsh writer regenerates) is not
        kept.
        """
        def native(a):
            a = np.asarray(a)
            return a.astype(a.dtype.newbyteorder("="), copy=False) if a.dtype.byteorder == ">" \
                else a

        cells = [(str(b.type), native(b.data).astype(np.int64, copy=False)) for b in m.cells]
        return cls(
            points=np.asarray(native(m.points), dtype=np.float64),
            cells=cells,
            point_data={str(k): native(v) for k, v in m.point_data.items()
                        if k != "gmsh:dim_tags"},
            cell_data={str(k): [native(x) for x in v] for k, v in m.cell_data.items()},
            field_data={str(k): native(v) for k, v in (m.field_data or {}).items()},
            source=source,
        )

    def require_cell_types(self, allowed, supported: str) -> None:
        """Refuse cells of a type outside ``allowed`` in one line naming the file, the
        cells and what is ``supported`` (``"triangles"``).

        Raises
        ------
        InvalidMeshError
        """
        other = {t for t, c in self.cells if t not in allowed and len(c)}
        if other:
            where = f"{self.source}: " if self.source else ""
            raise InvalidMeshError(
                f"{where}has {self.describe_cells(other)} cells; only {supported} are "
                "supported (meshopt info describes the file; meshopt convert keeps other "
                "cell types)")

    # -- triangle meshes ---------------------------------------------------------------
    @classmethod
    def from_triangle_mesh(cls, mesh: "TriangleMesh") -> "CellMesh":
        """Blocks ``line`` (if any) then ``triangle``, physical tags as cell data.

        No ``gmsh:geometrical`` data is made up: the gmsh writer numbers the entities.
        """
        cells, phys, tagged = tagged_blocks(mesh)
        pts = mesh.points
        embed = getattr(mesh, "embedding", None)
        if embed is not None:
            pts = embed.to_3d(pts)
        return cls(
            points=np.asarray(pts, dtype=np.float64),
            cells=cells,
            cell_data={PHYSICAL: phys} if tagged else {},
            field_data={name: np.array([tag, dim]) for name, (tag, dim) in
                        mesh.tag_names.items()},
            source=mesh.source,
        )

    def to_triangle_mesh(self, what: str = "this operation") -> "TriangleMesh":
        """The triangles, line elements and physical tags as a triangle mesh.

        A :class:`~meshopt_toolkit.mesh.PlanarMesh` when the points are 2D or every z is
        exactly 0. Vertex cells are left out (logged); point, cell and field data other
        than the physical groups are not part of a triangle mesh (logged).

        Raises
        ------
        InvalidMeshError
            Cells other than triangles, lines and vertices (naming the types and counts),
            no triangle, or a readable-level check fails.
        """
        from ..mesh import PlanarMesh, TriangleMesh

        where = f"{self.source}: " if self.source else ""
        self.require_cell_types(TRIANGLE_KINDS, "triangles")
        phys = self.cell_data.get(PHYSICAL)
        tris, ttags, lines, ltags = [], [], [], []
        for i, (t, c) in enumerate(self.cells):
            tag = None if phys is None else np.asarray(phys[i]).reshape(-1).astype(np.int64)
            if t == "triangle":
                tris.append(c)
                ttags.append(tag)
            elif t == "line":
                lines.append(c)
                ltags.append(np.zeros(len(c), np.int64) if tag is None else tag)
        if not tris or not sum(len(c) for c in tris):
            found = self.describe_cells() or "none"
            raise InvalidMeshError(f"{where}mesh has no triangles (cells: {found})")
        _log_unused(self, what)
        triangles = tris[0] if len(tris) == 1 else np.concatenate(tris)
        tags: dict[str, Any] = {"triangle_tags": None}
        if all(t is not None for t in ttags):
            tt = ttags[0] if len(ttags) == 1 else np.concatenate(ttags)
            if np.any(tt):
                tags["triangle_tags"] = tt
        if lines:
            tags["lines"] = np.concatenate(lines)
            tags["line_tags"] = np.concatenate(ltags)
        tags["tag_names"] = tag_names(self)
        pts = np.asarray(self.points, dtype=np.float64)
        planar = pts.ndim == 2 and (pts.shape[1] == 2
                                    or (pts.shape[1] == 3 and not np.any(pts[:, 2])))
        cls = PlanarMesh if planar else TriangleMesh
        return cls(pts, triangles, source=self.source, **tags)


    # -- surfaces and tetrahedra -------------------------------------------------------
    def to_surface_mesh(self, what: str = "this operation") -> "SurfaceMesh":
        """The triangles, line elements and physical tags as a triangle surface in 3D.

        What :meth:`to_triangle_mesh` keeps and refuses, with the file's points as they
        are (``(N, 3)``; 2D points get z = 0), planar or not.
        """
        from ..mesh import SurfaceMesh

        tm = self.to_triangle_mesh(what)
        return SurfaceMesh(self.points, tm.triangles, triangle_tags=tm.triangle_tags,
                           lines=tm.lines, line_tags=tm.line_tags, tag_names=tm.tag_names,
                           source=self.source)

    def to_tet_mesh(self, what: str = "this operation") -> "TetMesh":
        """The tetrahedra, with the triangles, lines and physical tags beside them.

        Vertex cells, point data and cell data other than the physical groups are left out
        (logged), as :meth:`to_triangle_mesh` does.

        Raises
        ------
        InvalidMeshError
            Cells other than tetrahedra, triangles, lines and vertices (naming the types
            and counts), no tetrahedron, or a readable-level check fails.
        """
        from ..mesh import TetMesh

        where = f"{self.source}: " if self.source else ""
        kinds = ("tetra", *TRIANGLE_KINDS)
        self.require_cell_types(kinds, "tetrahedra")
        parts = {t: _concatenated(self, t) for t in kinds[:3]}
        if parts["tetra"] is None:
            found = self.describe_cells() or "none"
            raise InvalidMeshError(f"{where}mesh has no tetrahedra (cells: {found})")
        _log_unused(self, what)
        (tets, tet_tags), (tri, tri_tags), (lines, line_tags) = (
            parts[t] or (None, None) for t in kinds[:3])
        return TetMesh(self.points, tets, tet_tags=tet_tags, triangles=tri,
                       triangle_tags=tri_tags, lines=lines, line_tags=line_tags,
                       tag_names=tag_names(self), source=self.source)

    @classmethod
    def from_surface_mesh(cls, mesh: "SurfaceMesh") -> "CellMesh":
        """As :meth:`from_triangle_mesh`: blocks ``line`` (if any) then ``triangle``."""
        return cls.from_triangle_mesh(mesh)  # type: ignore[arg-type]

    @classmethod
    def from_tet_mesh(cls, mesh: "TetMesh") -> "CellMesh":
        """Blocks ``line``, ``triangle`` (where the mesh has them) then ``tetra``, physical
        tags as cell data where any element is tagged."""
        blocks = [("line", mesh.lines, mesh.line_tags),
                  ("triangle", mesh.triangles, mesh.triangle_tags),
                  ("tetra", mesh.tets, mesh.tet_tags)]
        blocks = [(t, c, tags) for t, c, tags in blocks if c is not None]
        tagged = mesh.tet_tags is not None or any(np.any(tags) for _, _, tags in blocks)
        cells = [(t, np.array(c)) for t, c, _ in blocks]
        phys = [np.zeros(len(c), np.int64) if tags is None else np.array(tags)
                for _, c, tags in blocks]
        return cls(np.array(mesh.points), cells, cell_data={PHYSICAL: phys} if tagged else {},
                   field_data={name: np.array([tag, dim]) for name, (tag, dim) in
                               mesh.tag_names.items()},
                   source=mesh.source)


def _concatenated(cm: CellMesh, cell_type: str):
    """``(cells, physical tags or None)`` of every block of ``cell_type``, or None."""
    phys = cm.cell_data.get(PHYSICAL)
    idx = [i for i, (t, c) in enumerate(cm.cells) if t == cell_type and len(c)]
    if not idx:
        return None
    cells = np.concatenate([cm.cells[i][1] for i in idx])
    if phys is None:
        return cells, None
    return cells, np.concatenate([np.asarray(phys[i]).reshape(-1) for i in idx]).astype(np.int64)


def tag_names(cm: CellMesh) -> dict:
    """The physical names of ``cm``'s field data: ``{name: (tag, dim)}``."""
    names = {}
    for name, value in cm.field_data.items():
        v = np.asarray(value).reshape(-1)
        if v.size == 2 and np.issubdtype(v.dtype, np.integer):
            names[str(name)] = (int(v[0]), int(v[1]))
    return names


def _log_unused(cm: CellMesh, what: str) -> None:
    ignored = [f"{n} vertex cells" for t, n in cm.cell_counts().items() if t == "vertex"]
    ignored += [f"point data {k!r}" for k in cm.point_data]
    ignored += [f"cell data {k!r}" for k in cm.cell_data if k not in GMSH_KEYS]
    if ignored:
        where = f"{cm.source}: " if cm.source else ""
        logger.info("%snot used by %s: %s", where, what, ", ".join(ignored))


def tagged_blocks(mesh: "TriangleMesh") -> tuple[list, list, bool]:
    """The cell blocks of a triangle mesh, ``line`` (if any) then ``triangle``, their
    physical tags (zeros for untagged triangles) and whether the mesh has any tags."""
    cells = []
    phys = []
    if mesh.lines is not None:
        cells.append(("line", np.asarray(mesh.lines)))
        phys.append(np.asarray(mesh.line_tags))
    cells.append(("triangle", np.asarray(mesh.triangles)))
    phys.append(np.zeros(mesh.n_triangles, np.int64) if mesh.triangle_tags is None
                else np.asarray(mesh.triangle_tags))
    return cells, phys, mesh.triangle_tags is not None or mesh.lines is not None


def triangles_only(mesh: "TriangleMesh") -> CellMesh:
    """Points (3D where the mesh has an embedding) and one triangle block: what
    :func:`~meshopt_toolkit.io.save` writes of a triangle mesh to a format without tags."""
    cm = CellMesh.from_triangle_mesh(mesh)
    return CellMesh(cm.points, [("triangle", np.asarray(mesh.triangles))], source=mesh.source)


def triangle_mesh(cm: CellMesh) -> "TriangleMesh":
    """:meth:`CellMesh.to_triangle_mesh` with readable-level failures as :class:`ReadError`."""
    try:
        return cm.to_triangle_mesh()
    except InvalidMeshError as exc:
        raise ReadError(str(exc)) from exc


def check_cells(cm: CellMesh) -> None:
    """Readable-level checks of a cell mesh: finite points, indices in range.

    Raises
    ------
    ReadError
        Naming the file, the block and the offending entry.
    """
    where = f"{cm.source}: " if cm.source else ""
    pts = cm.points
    if pts.size == 0:
        raise ReadError(f"{where}has no nodes (no vertices)")
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ReadError(f"{where}points must have 2 or 3 coordinates, got shape {pts.shape}")
    with np.errstate(over="ignore", invalid="ignore"):
        finite = np.isfinite(pts.sum())
    problem = None if finite else non_finite_problem(pts, show=True)
    if problem:
        raise ReadError(where + problem)
    n = len(pts)
    for t, c in cm.cells:
        if c.size and (int(c.min()) < 0 or int(c.max()) >= n):
            raise ReadError(f"{where}a {t} cell has a vertex index out of range [0, {n})")
    for k, v in cm.point_data.items():
        if len(v) != n:
            raise ReadError(f"{where}point data {k!r} has {len(v)} values for {n} points")
    for k, v in cm.cell_data.items():
        if len(v) != len(cm.cells) or any(len(a) != len(c) for a, (_, c) in zip(v, cm.cells)):
            raise ReadError(f"{where}cell data {k!r} does not match the cell blocks")


def face_blocks(flat: np.ndarray, sizes: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """Cell blocks of faces given in file order as concatenated indices ``flat`` and
    vertex counts ``sizes``: each run of equal size is one block, named ``triangle``,
    ``quad`` or ``polygon`` (``vertex``/``line`` for sizes 1 and 2)."""
    sizes = np.asarray(sizes, np.int64)
    if len(sizes) == 0:
        return []
    cut = np.flatnonzero(np.diff(sizes)) + 1
    starts = np.concatenate([[0], cut]).tolist()
    stops = np.concatenate([cut, [len(sizes)]]).tolist()
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    out = []
    for a, b in zip(starts, stops):
        k = int(sizes[a])
        name = {1: "vertex", 2: "line", 3: "triangle", 4: "quad"}.get(k, "polygon")
        out.append((name, np.asarray(flat[offsets[a]:offsets[b]], np.int64).reshape(b - a, k)))
    return out
