"""Triangle meshes with fixed connectivity (SPEC §1).

:class:`TriangleMesh` is the *readable* level: finite coordinates in 2D or 3D, indices in
range, at least one triangle. It is what file I/O and conversion work with.
:class:`PlanarMesh` adds planarity (points are stored as ``(N, 2)``) and is the object
every deformation and optimization works on. Both are immutable values: moving nodes
returns a new mesh (:meth:`PlanarMesh.with_points`), and derived topology is cached.

The planar-manifold checks of SPEC §1 and admissibility are reported by
:func:`check_mesh` (a :class:`MeshReport`) and enforced by :func:`require_admissible`.
A clean mesh is recognised by one exact pass over whole arrays (:func:`_clean_manifold`:
one sort of the half-edges, a breadth-first search, a walk around every vertex); only a
mesh with a problem pays for the edge list and the description of its first problem.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from ._lazy import lazy_module

sp = lazy_module("scipy.sparse")  # imported on first use: info/convert need no scipy
_csgraph = lazy_module("scipy.sparse.csgraph")

from ._typing import FloatArray, IntArray
from .errors import InvalidMeshError, NotAdmissibleError
from .geometry import quality_summary, signed_areas

logger = logging.getLogger(__name__)

__all__ = [
    "MeshReport",
    "PlanarMesh",
    "TriangleMesh",
    "boundary_self_intersections",
    "check_mesh",
    "require_admissible",
]


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


class TriangleMesh:
    """A readable triangle mesh: points ``(N, 2)`` or ``(N, 3)``, triangles ``(T, 3)``.

    Parameters
    ----------
    points : (N, 2) or (N, 3) array_like of float
    triangles : (T, 3) array_like of int
    triangle_tags : (T,) array_like of int, optional
        Physical tags of the triangles (e.g. gmsh ``$PhysicalNames``).
    lines : (L, 2) array_like of int, optional
        Tagged line elements (typically boundary parts) kept from the input file.
    line_tags : (L,) array_like of int, optional
        Physical tags of ``lines``; required when ``lines`` is given.
    tag_names : dict, optional
        ``{name: (tag, dim)}`` as in gmsh physical names.
    source : str, optional
        Where the mesh came from (a file name), used in error messages.

    Raises
    ------
    InvalidMeshError
        Non-finite coordinates, indices out of range, wrong shapes, or no triangle.
    """

    def __init__(
        self,
        points,
        triangles,
        *,
        triangle_tags=None,
        lines=None,
        line_tags=None,
        tag_names: dict | None = None,
        source: str | None = None,
    ) -> None:
        where = f"{source}: " if source else ""
        pts = np.array(points, dtype=np.float64, copy=True)
        if pts.ndim != 2 or pts.shape[1] not in (2, 3):
            raise InvalidMeshError(f"{where}points must have shape (N, 2) or (N, 3), got {pts.shape}")
        tri_in = np.asarray(triangles)
        if tri_in.size == 0:
            raise InvalidMeshError(f"{where}mesh has no triangles")
        if tri_in.ndim != 2 or tri_in.shape[1] != 3:
            raise InvalidMeshError(f"{where}triangles must have shape (T, 3), got {tri_in.shape}")
        if not np.issubdtype(tri_in.dtype, np.integer) and (
            not np.all(np.isfinite(tri_in)) or np.any(tri_in != np.round(tri_in))
        ):
            raise InvalidMeshError(f"{where}triangle indices must be integers")
        tri = np.array(tri_in, dtype=np.int64, copy=True)
        # cheap whole-array tests first; the offending row is searched only on failure
        # (a sum is non-finite if any term is, and may overflow only with huge values)
        with np.errstate(over="ignore", invalid="ignore"):
            total = pts.sum()
        if not np.isfinite(total):
            bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
            if bad.size:
                raise InvalidMeshError(
                    f"{where}vertex {bad[0]} has a non-finite coordinate {pts[bad[0]].tolist()}"
                    + (f" ({bad.size} such vertices)" if bad.size > 1 else "")
                )
        # negative indices are huge when read as unsigned: one reduction tests both ends
        if int(tri.view(np.uint64).max()) >= len(pts):
            out = np.flatnonzero(((tri < 0) | (tri >= len(pts))).any(axis=1))
            raise InvalidMeshError(
                f"{where}triangle {out[0]} {tri[out[0]].tolist()} has a vertex index out of "
                f"range [0, {len(pts)})"
            )
        self._points = _frozen(pts)
        self._triangles = _frozen(tri)
        self._source = source
        self._triangle_tags = None
        if triangle_tags is not None:
            tags = np.array(triangle_tags, dtype=np.int64).reshape(-1)
            if tags.shape != (len(tri),):
                raise InvalidMeshError(f"{where}triangle_tags must have one entry per triangle")
            self._triangle_tags = _frozen(tags)
        self._lines = None
        self._line_tags = None
        if lines is not None and len(lines):
            ln = np.array(lines, dtype=np.int64).reshape(-1, 2)
            lt = np.zeros(len(ln), np.int64) if line_tags is None else np.array(line_tags, np.int64).reshape(-1)
            if lt.shape != (len(ln),):
                raise InvalidMeshError(f"{where}line_tags must have one entry per line")
            if ((ln < 0) | (ln >= len(pts))).any():
                raise InvalidMeshError(f"{where}a line element has a vertex index out of range")
            self._lines = _frozen(ln)
            self._line_tags = _frozen(lt)
        self._tag_names = dict(tag_names or {})

    # -- plain data -----------------------------------------------------------------
    @property
    def points(self) -> FloatArray:
        """Node positions, read-only ``(N, d)`` float64."""
        return self._points

    @property
    def triangles(self) -> IntArray:
        """Connectivity, read-only ``(T, 3)`` int64."""
        return self._triangles

    @property
    def triangle_tags(self) -> IntArray | None:
        """Physical tag per triangle ``(T,)``, or None."""
        return self._triangle_tags

    @property
    def lines(self) -> IntArray | None:
        """Tagged line elements ``(L, 2)``, or None."""
        return self._lines

    @property
    def line_tags(self) -> IntArray | None:
        """Physical tag per line element ``(L,)``, or None."""
        return self._line_tags

    @property
    def tag_names(self) -> dict:
        """``{name: (tag, dim)}`` physical names."""
        return dict(self._tag_names)

    @property
    def source(self) -> str | None:
        """The file this mesh was read from, if any."""
        return self._source

    @property
    def n_vertices(self) -> int:
        return len(self._points)

    @property
    def n_triangles(self) -> int:
        return len(self._triangles)

    @property
    def dim(self) -> int:
        """Number of coordinates per point (2 or 3)."""
        return self._points.shape[1]

    def _tag_kwargs(self) -> dict:
        return {
            "triangle_tags": self._triangle_tags,
            "lines": self._lines,
            "line_tags": self._line_tags,
            "tag_names": self._tag_names,
            "source": self._source,
        }

    @property
    def is_planar(self) -> bool:
        """True if the points are 2D, or 3D with every z exactly 0."""
        return self.dim == 2 or not np.any(self._points[:, 2])

    def as_planar(self) -> PlanarMesh:
        """This mesh as a :class:`PlanarMesh` (drops z = 0); raises if not planar."""
        if isinstance(self, PlanarMesh):
            return self
        return PlanarMesh(self._points, self._triangles, **self._tag_kwargs())

    def __repr__(self) -> str:
        name = type(self).__name__
        src = f", source={self._source!r}" if self._source else ""
        return f"{name}(n_vertices={self.n_vertices}, n_triangles={self.n_triangles}{src})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TriangleMesh):
            return NotImplemented
        return (
            self._points.shape == other._points.shape
            and np.array_equal(self._points, other._points)
            and np.array_equal(self._triangles, other._triangles)
        )

    __hash__ = None  # type: ignore[assignment]

    # -- topology (cached) ----------------------------------------------------------
    @cached_property
    def _triangle_columns(self) -> IntArray:
        """The triangles as a contiguous ``(3, T)`` array, row ``l`` = local vertex ``l``.

        Its transpose is the triangle array in column-major order: per-vertex gathers
        (``np.take(x, triangles.T)`` in :mod:`~meshopt_toolkit.geometry`) run several
        times faster on it than on the row-major ``(T, 3)`` array.
        """
        return _frozen(np.ascontiguousarray(self._triangles.T))

    @cached_property
    def _edge_data(self) -> tuple[IntArray, IntArray, IntArray, IntArray]:
        """Edges, triangle→edge map, counts, and the first two corners of each edge.

        A *corner* ``c = 3 k + l`` names local edge ``l`` of triangle ``k`` (opposite local
        vertex ``l``, endpoints ``i_{l+1}, i_{l+2}``). Edges are found by one sort of the
        half-edges by (smaller end, larger end, direction, corner), see
        :func:`_sorted_half_edges`; an edge's corners are listed in that order.
        """
        tri = self._triangles
        nc = tri.size
        order, code, bits = _sorted_half_edges(_corner_table(tri), self.n_vertices, np.int64)
        code >>= 1  # drop the direction bit: lo << bits | hi
        start = np.empty(nc, dtype=bool)
        start[0] = True
        np.not_equal(code[1:], code[:-1], out=start[1:])
        first = np.flatnonzero(start)
        inverse = np.empty(nc, dtype=np.int64)
        inverse[order] = np.cumsum(start) - 1
        counts = np.diff(np.append(first, nc))
        u = code[first]
        edges = np.stack([u >> bits, u & ((1 << bits) - 1)], axis=1).astype(np.int64)
        corners = np.full((len(first), 2), -1, dtype=np.int64)
        corners[:, 0] = order[first]
        two = counts >= 2
        corners[two, 1] = order[first[two] + 1]
        return (
            _frozen(edges),
            _frozen(inverse.reshape(-1, 3)),
            _frozen(counts),
            _frozen(corners),
        )

    @cached_property
    def _clean_corners(self) -> IntArray | None:
        """:func:`_clean_manifold` of this connectivity (kept by :meth:`PlanarMesh.with_points`)."""
        corners = _clean_manifold(self)
        return None if corners is None else _frozen(corners)

    @property
    def _edge_corners(self) -> IntArray:
        """First two corners ``3 k + l`` containing each edge ``(E, 2)``; -1 if only one."""
        return self._edge_data[3]

    @property
    def edges(self) -> IntArray:
        """Unique undirected edges ``(E, 2)``, each sorted (i < j), lexicographic order."""
        return self._edge_data[0]

    @property
    def triangle_edges(self) -> IntArray:
        """Index into :attr:`edges` of the edge opposite each local vertex, ``(T, 3)``."""
        return self._edge_data[1]

    @property
    def edge_triangle_counts(self) -> IntArray:
        """Number of triangles containing each edge ``(E,)``."""
        return self._edge_data[2]

    @cached_property
    def boundary_edges(self) -> IntArray:
        """Boundary edges ``(B, 2)`` directed as in their triangle (CCW: interior on the left)."""
        tri = self._triangles
        directed = np.stack([np.roll(tri, -1, axis=1), np.roll(tri, -2, axis=1)], axis=-1)
        mask = self.edge_triangle_counts[self.triangle_edges] == 1
        return _frozen(np.ascontiguousarray(directed[mask]))

    @cached_property
    def boundary_vertices(self) -> IntArray:
        """Sorted indices of the boundary vertices ``(V∂,)``."""
        return _frozen(np.unique(self.boundary_edges))

    @cached_property
    def vertex_adjacency(self) -> sp.csr_matrix:
        """Symmetric ``(N, N)`` boolean adjacency matrix of the edge graph."""
        e = self.edges
        n = self.n_vertices
        data = np.ones(2 * len(e), dtype=bool)
        rows = np.concatenate([e[:, 0], e[:, 1]])
        cols = np.concatenate([e[:, 1], e[:, 0]])
        return sp.csr_matrix((data, (rows, cols)), shape=(n, n))

    @cached_property
    def triangle_adjacency(self) -> sp.csr_matrix:
        """Symmetric ``(T, T)`` boolean matrix: triangles sharing an edge."""
        nt = self.n_triangles
        if self.edge_triangle_counts.max(initial=0) <= 2:
            c = self._edge_corners
            c = c[c[:, 1] >= 0]
            t1, t2 = c[:, 0] // 3, c[:, 1] // 3
            keep = t1 != t2
            t1, t2 = t1[keep], t2[keep]
            rows = np.concatenate([t1, t2])
            cols = np.concatenate([t2, t1])
            adj = sp.csr_matrix((np.ones(len(rows), dtype=bool), (rows, cols)), shape=(nt, nt))
            adj.sum_duplicates()
            return adj
        # non-manifold edges: every pair of triangles on an edge is adjacent
        te = self.triangle_edges.ravel()
        tid = np.repeat(np.arange(nt), 3)
        inc = sp.csr_matrix((np.ones(len(te)), (tid, te)), shape=(nt, len(self.edges)))
        adj = (inc @ inc.T).tocsr()
        adj.setdiag(0)
        adj.eliminate_zeros()
        return adj.astype(bool)

    @cached_property
    def vertex_triangles(self) -> sp.csr_matrix:
        """``(N, T)`` incidence matrix: entry (i, k) is 1 if vertex i is in triangle k."""
        t = self._triangles
        rows = t.ravel()
        cols = np.repeat(np.arange(len(t)), 3)
        return sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(self.n_vertices, len(t)))


class PlanarMesh(TriangleMesh):
    """An immutable planar triangle mesh ``PlanarMesh(points, triangles)``.

    ``points`` is stored as ``(N, 2)`` float64; ``(N, 3)`` input is accepted when every z is
    exactly 0. Construction performs the *readable* checks of :class:`TriangleMesh`; the
    planar-manifold and admissibility checks are in :func:`check_mesh`.

    Examples
    --------
    >>> m = PlanarMesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]])
    >>> m.refine().n_triangles
    4
    """

    def __init__(self, points, triangles, **kwargs) -> None:
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim == 2 and pts.shape[1] == 3:
            # NaN counts as non-zero in any(); it is reported as non-finite by TriangleMesh
            nz = np.flatnonzero(np.isfinite(pts[:, 2]) & (pts[:, 2] != 0)) if pts[:, 2].any() else ()
            if len(nz):
                src = kwargs.get("source")
                where = f"{src}: " if src else ""
                raise InvalidMeshError(
                    f"{where}not planar: vertex {nz[0]} has z = {float(pts[nz[0], 2])!r} (z must be 0)"
                )
            pts = pts[:, :2]
        super().__init__(pts, triangles, **kwargs)

    def with_points(self, points) -> PlanarMesh:
        """A new mesh with the same connectivity and tags at new positions ``(N, 2)``."""
        q = np.asarray(points, dtype=np.float64)
        if q.shape != self._points.shape:
            raise InvalidMeshError(
                f"new points have shape {q.shape}, the mesh has {self._points.shape}"
            )
        new = object.__new__(PlanarMesh)
        new.__dict__.update({k: v for k, v in self.__dict__.items() if not k.startswith("_geom")})
        if not np.isfinite(q).all():
            bad = int(np.flatnonzero(~np.isfinite(q).all(axis=1))[0])
            raise InvalidMeshError(f"vertex {bad} has a non-finite coordinate")
        new._points = _frozen(q.copy())
        return new

    def flipped(self) -> PlanarMesh:
        """The same mesh with every triangle's orientation reversed."""
        return PlanarMesh(self._points, self._triangles[:, ::-1], **self._tag_kwargs())

    def signed_areas(self) -> FloatArray:
        """Signed area per triangle ``(T,)``."""
        return signed_areas(self._points, self._triangle_columns.T)

    def quality(self):
        """:class:`~meshopt_toolkit.geometry.QualitySummary` of the current positions."""
        return quality_summary(self._points, self._triangle_columns.T)

    @property
    def diameter(self) -> float:
        """Diagonal of the bounding box."""
        return float(np.linalg.norm(self._points.max(axis=0) - self._points.min(axis=0)))

    def refine(self) -> PlanarMesh:
        """Uniform refinement: every triangle into four at its edge midpoints.

        New vertices are appended after the old ones in edge order. Triangle tags are
        inherited by the four children; a tagged line element is split into two lines with
        the same tag. The orientation of every child equals its parent's.
        """
        n = self.n_vertices
        edges = self.edges
        mid = 0.5 * (self._points[edges[:, 0]] + self._points[edges[:, 1]])
        pts = np.vstack([self._points, mid])
        te = self.triangle_edges + n  # midpoint of edge opposite local vertex l
        a, b, c = self._triangles.T
        mab, mbc, mca = te[:, 2], te[:, 0], te[:, 1]
        tri = np.stack(
            [
                np.stack([a, mab, mca], 1),
                np.stack([mab, b, mbc], 1),
                np.stack([mca, mbc, c], 1),
                np.stack([mab, mbc, mca], 1),
            ],
            axis=1,
        ).reshape(-1, 3)
        ttags = None if self._triangle_tags is None else np.repeat(self._triangle_tags, 4)
        lines = ltags = None
        if self._lines is not None:
            key = np.sort(self._lines, axis=1)
            idx = _edge_index(edges, key)
            if np.any(idx < 0):
                # line elements that are not mesh edges: keep them unsplit
                keep = idx < 0
                m = n + idx[~keep]
                l0, l1 = self._lines[~keep, 0], self._lines[~keep, 1]
                lines = np.vstack(
                    [np.stack([l0, m], 1), np.stack([m, l1], 1), self._lines[keep]]
                )
                lt = self._line_tags
                ltags = np.concatenate([lt[~keep], lt[~keep], lt[keep]])
            else:
                m = n + idx
                lines = np.stack(
                    [np.stack([self._lines[:, 0], m], 1), np.stack([m, self._lines[:, 1]], 1)], 1
                ).reshape(-1, 2)
                ltags = np.repeat(self._line_tags, 2)
        return PlanarMesh(
            pts,
            tri,
            triangle_tags=ttags,
            lines=lines,
            line_tags=ltags,
            tag_names=self._tag_names,
            source=self._source,
        )

    def tagged_vertices(self, tag: int | str) -> IntArray:
        """Vertices of the line elements (or triangles) carrying a physical tag or name."""
        if isinstance(tag, str):
            if tag not in self._tag_names:
                raise InvalidMeshError(
                    f"no physical group named {tag!r}; known: {sorted(self._tag_names)}"
                )
            tag = self._tag_names[tag][0]
        parts = []
        if self._lines is not None:
            parts.append(self._lines[self._line_tags == tag].ravel())
        if self._triangle_tags is not None:
            parts.append(self._triangles[self._triangle_tags == tag].ravel())
        if not parts or not sum(len(p) for p in parts):
            raise InvalidMeshError(f"no element carries physical tag {tag}")
        return np.unique(np.concatenate(parts))


def _corner_table(tri: IntArray) -> IntArray:
    """The triangles as a contiguous ``(3, T)`` array: row ``l`` holds local vertex ``l``.

    int32 when every index fits, which halves the memory traffic of the passes below.
    """
    small = tri.size < 2**31 - 1 and (tri.size == 0 or int(tri.max()) < 2**31 - 1)
    return np.ascontiguousarray(tri.T, dtype=np.int32 if small else np.int64)


def _sorted_half_edges(
    table: IntArray, n: int, dtype, step: int = 0
) -> tuple[IntArray, np.ndarray, int]:
    """Half-edges sorted by (smaller end, larger end, direction, corner).

    Corner ``c = 3 k + l`` stands for the half-edge of triangle ``k`` opposite local vertex
    ``l``, from ``i_{l+1}`` to ``i_{l+2}``. Its code is ``lo << (b + 1) | hi << 1 | dir``
    with ``lo < hi`` its ends, ``b`` bits per vertex index and ``dir = i_{l+1} > i_{l+2}``,
    so equal codes are the same directed half-edge and codes differing only in the last
    bit are the two directions of one edge. When code and corner fit together in 64 bits
    they are packed into one key and sorted by value (much faster than an argsort).

    Parameters
    ----------
    table : (3, T) int array
        :func:`_corner_table` of the triangles.
    n : int
        Number of vertices.
    dtype : numpy integer type of the returned corners.
    step : int
        Return corner ``3k + (l + step) % 3`` in place of ``3k + l`` (``step = 1``: the
        corner after it in its triangle).

    Returns
    -------
    corners : (3T,) array of ``dtype``
        Corners in sorted order (shifted by ``step`` within their triangle).
    codes : (3T,) uint64
        Their codes, non-decreasing.
    b : int
        Bits per vertex index in the codes.
    """
    nt = table.shape[1]
    nc = 3 * nt
    bits = max(int(n - 1).bit_length(), 1)
    shift = max(int(nc - 1).bit_length(), 1)
    packed = 2 * bits + 1 + shift <= 64
    key = np.empty((3, nt), dtype=np.uint64)
    tmp = np.empty(nt, dtype=np.uint64)
    if packed:
        base = np.arange(0, nc, 3, dtype=np.uint64)
    for l in range(3):
        s, d = table[(l + 1) % 3], table[(l + 2) % 3]
        row = key[l]
        up = shift if packed else 0
        np.left_shift(np.minimum(s, d), bits + 1 + up, out=row, dtype=np.uint64, casting="unsafe")
        np.left_shift(np.maximum(s, d), 1 + up, out=tmp, dtype=np.uint64, casting="unsafe")
        row |= tmp
        np.left_shift(s > d, up, out=tmp, dtype=np.uint64, casting="unsafe")
        row |= tmp
        if packed:
            row |= base
            if (l + step) % 3:
                row += (l + step) % 3  # the corner 3k + l' fits in the low bits, no carry
    key = key.ravel()
    if packed:
        key.sort()
        corners = np.empty(nc, dtype=dtype)
        np.bitwise_and(key, (1 << shift) - 1, out=corners, casting="unsafe")
        key >>= shift
        return corners, key, bits
    order = np.argsort(key)
    # argsort lists the corners row by row of ``table``: translate to 3k + l
    corners = (order % nt) * 3 + (order // nt + step) % 3
    return corners.astype(dtype), key[order], bits


def _edge_index(edges: IntArray, keys: IntArray) -> IntArray:
    """Row index of each sorted pair in ``keys`` within lexicographically sorted ``edges``.

    Returns -1 where a pair is not an edge.
    """
    n = int(max(edges.max(initial=0), keys.max(initial=0))) + 1
    code_e = edges[:, 0] * n + edges[:, 1]
    code_k = keys[:, 0] * n + keys[:, 1]
    pos = np.searchsorted(code_e, code_k)
    pos = np.clip(pos, 0, len(code_e) - 1)
    return np.where(code_e[pos] == code_k, pos, -1)


# ---------------------------------------------------------------------------------------
# checks
# ---------------------------------------------------------------------------------------


@dataclass
class MeshReport:
    """Outcome of :func:`check_mesh`.

    Attributes
    ----------
    planar : bool
        2D points (or z ≡ 0).
    manifold : bool
        Every planar-manifold condition of SPEC §1 holds (planarity included).
    admissible : bool
        ``manifold`` and every signed area > 0 and no boundary self-intersection.
    reoriented : bool
        Some triangles were flipped (each component is oriented by propagation across its
        edges, then counter-clockwise); :attr:`mesh` is the oriented version.
    problems : list of str
        Human-readable reasons, each naming a vertex/triangle/edge.
    mesh : TriangleMesh
        The checked mesh (re-oriented to CCW when ``reoriented``; in plane coordinates,
        with ``embedding`` set, when the input lies on a plane other than z = 0).
    n_reoriented : int
        Number of triangles flipped.
    """

    planar: bool
    manifold: bool
    admissible: bool
    reoriented: bool = False
    problems: list[str] = field(default_factory=list)
    mesh: TriangleMesh | None = None
    n_reoriented: int = 0


def _manifold_problems(mesh: TriangleMesh) -> list[str]:
    problems: list[str] = []
    tri = mesh.triangles
    n = mesh.n_vertices
    used = np.zeros(n, bool)
    used[tri.ravel()] = True
    if not used.all():
        v = np.flatnonzero(~used)
        problems.append(f"vertex {v[0]} is not used by any triangle ({v.size} unused)")
    degenerate = np.flatnonzero(
        (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2])
    )
    if degenerate.size:
        k = degenerate[0]
        problems.append(f"triangle {k} {tri[k].tolist()} repeats a vertex")
        return problems
    counts = mesh.edge_triangle_counts
    over = np.flatnonzero(counts > 2)
    if over.size:
        e = mesh.edges[over[0]]
        problems.append(
            f"edge ({e[0]}, {e[1]}) is shared by {counts[over[0]]} triangles (not edge-manifold)"
        )
        return problems
    # consistent orientation: an interior edge appears once in each direction
    directed = np.stack([np.roll(tri, -1, axis=1), np.roll(tri, -2, axis=1)], axis=-1).reshape(-1, 2)
    forward = directed[:, 0] < directed[:, 1]
    te = mesh.triangle_edges.ravel()
    fwd_count = np.bincount(te, weights=forward, minlength=len(counts))
    bad = np.flatnonzero((counts == 2) & (fwd_count != 1))
    if bad.size:
        e = mesh.edges[bad[0]]
        problems.append(
            f"triangles sharing edge ({e[0]}, {e[1]}) have inconsistent orientation"
        )
    # 2-path connectivity: components of the graph "triangles sharing an edge", each
    # interior edge entered once (connected_components symmetrizes it)
    c = mesh._edge_corners
    c = c[c[:, 1] >= 0] // 3
    nt = len(tri)
    shared = sp.coo_matrix((np.ones(len(c), dtype=bool), (c[:, 0], c[:, 1])), shape=(nt, nt))
    ncomp, _ = _csgraph.connected_components(shared, directed=False)
    if ncomp > 1:
        problems.append(f"mesh has {ncomp} pieces not connected through edges")
    # bow-ties: the triangles around each vertex must form one fan
    if not bad.size:
        fans = _fans_per_vertex(mesh)
        bow = np.flatnonzero(fans > 1)
        if bow.size:
            problems.append(
                f"vertex {bow[0]} is a bow-tie: its triangles form {fans[bow[0]]} separate fans"
            )
    return problems


def _fans_per_vertex(mesh: TriangleMesh) -> IntArray:
    """Number of fans (edge-connected groups of incident triangles) at each vertex ``(N,)``.

    Needs an edge-manifold, consistently oriented mesh without repeated vertices. The
    triangle corners at a vertex ``v`` (corner ``3k + l`` is vertex ``l`` of triangle
    ``k``) are linked by a successor map: from triangle ``(v, a, b)`` across the edge
    ``(v, b)`` to the next triangle around ``v``. Each fan is a path (a boundary fan) or
    a cycle (an interior fan) of that map. Pointer doubling, ``⌈log2(max degree)⌉``
    rounds over all corners at once, labels each path by its last corner and each cycle
    by its smallest corner; the fans at ``v`` are the corners that are their own label.
    """
    tri = mesh.triangles
    flat = tri.ravel()  # corner c sits at vertex flat[c]
    nc = len(flat)
    # int32 corner ids halve the memory traffic of the random gathers below
    idx = np.int32 if nc < 2**31 - 1 else np.int64
    corner = np.arange(nc, dtype=idx)
    nxt1 = np.tile(np.array([1, 1, -2], dtype=idx), nc // 3)  # c -> 3k + (l + 1) % 3 - c
    nxt2 = np.tile(np.array([2, -1, -1], dtype=idx), nc // 3)  # c -> 3k + (l + 2) % 3 - c
    # edge-corner e = 3k + l names the edge opposite local vertex l of triangle k;
    # partner[e] is the same edge's edge-corner in the neighbouring triangle (or -1)
    ec = mesh._edge_corners
    two = ec[:, 1] >= 0
    partner = np.full(nc, -1, dtype=idx)
    partner[ec[two, 0]] = ec[two, 1]
    partner[ec[two, 1]] = ec[two, 0]
    # corner c = 3k + l at v in triangle (v, a, b): the edge (v, b) is opposite a = l + 1
    across = partner[corner + nxt1]
    succ = corner.copy()  # the end of a path points to itself
    has = np.flatnonzero(across >= 0)
    e = across[has]
    cand1 = e + nxt1[e]  # the two endpoints of that edge in the neighbour
    cand2 = e + nxt2[e]
    succ[has] = np.where(flat[cand1] == flat[has], cand1, cand2)
    return _count_fans(succ, flat, mesh.n_vertices)


def _count_fans(succ: IntArray, vertex: IntArray, n: int) -> IntArray:
    """Number of orbits (paths and cycles) of a successor map at each vertex ``(n,)``.

    ``succ`` maps each of a set of corners ``0..m-1`` (each at ``vertex[c]``) to the next
    corner around the same vertex, or to itself at the end of a path; it is injective.
    Pointer doubling, ``⌈log2(max corners per vertex)⌉`` rounds over all corners at once,
    labels each path by its last corner and each cycle by its smallest corner; the orbits
    at ``v`` are the corners that are their own label.
    """
    corner = np.arange(len(succ), dtype=succ.dtype)
    is_end = succ == corner
    label = corner.copy()
    rounds = int(np.ceil(np.log2(max(int(np.bincount(vertex).max(initial=0)), 2))))
    for _ in range(rounds):  # after r rounds: label = min over 2^r corners, succ = succ^(2^r)
        np.minimum(label, label[succ], out=label)
        succ = succ[succ]
    # 2^rounds >= corners at the vertex: every path corner has reached its end
    root = np.where(is_end[succ], succ, label)
    own = root == corner
    return np.bincount(vertex[own], minlength=n)


#: fans longer than this are checked by pointer doubling instead of a step-by-step walk
_WALK_STEPS = 64
#: meshes with at most this many triangles are checked for connectivity in numpy alone,
#: and at most this many boundary edges are intersected pairwise (no scipy import)
_NUMPY_CONNECTIVITY = 20000
_NUMPY_PAIRS = 600


def _clean_manifold(mesh: TriangleMesh) -> IntArray | None:
    """The boundary corners ``(B,)`` if ``mesh`` passes every planar-manifold check, else None.

    The fast path of :func:`check_mesh`: it decides exactly whether
    :func:`_manifold_problems` finds nothing (then the sorted corners ``3k + l`` of the
    boundary half-edges are returned), without building the edge list. Problems are
    described by :func:`_manifold_problems`, run only when this returns None.

    Every test is a pass over whole arrays:

    * unused vertex: a zero in the vertex degrees (triangles per vertex ``t_v``);
    * repeated vertex in a triangle;
    * edge in three or more triangles, or inconsistent orientation: both hold iff some
      directed half-edge occurs twice (a manifold, consistently oriented mesh has each
      interior edge once in each direction), seen as equal neighbours after one sort of
      the half-edge codes (:func:`_sorted_half_edges`);
    * 2-path connectivity: a breadth-first search over the triangle graph (three slots
      per triangle: its neighbour across each edge, itself at a boundary edge);
    * bow-ties: around each vertex the successor map ``succ(c) = next(twin(next(c)))``
      (corner ``c`` at ``v`` in triangle ``(v, a, b)`` → the corner at ``v`` across edge
      ``(v, b)``) is injective, so its orbits are paths (boundary fans) and cycles
      (interior fans). A path starts at ``next(e)`` for each boundary half-edge ``e``
      leaving ``v``; two starts mean two fans. Otherwise one walk per vertex from its
      path start (or any corner) must make ``t_v - 1`` steps without reaching the path's
      end or returning to the start: then the orbit has all ``t_v`` corners and is the
      only fan. All vertices walk together, the ones with more triangles first (``t_v`` steps in total);
      vertices with more than :data:`_WALK_STEPS` triangles are counted by pointer
      doubling (:func:`_count_fans`) instead.
    """
    tri = mesh.triangles
    n = mesh.n_vertices
    nt = len(tri)
    nc = 3 * nt
    table = _corner_table(tri)
    idx = table.dtype
    deg = np.bincount(tri.ravel(), minlength=n)
    if deg.min() == 0:
        return None  # an unused vertex
    a, b, c = table
    if ((a == b) | (b == c) | (a == c)).any():
        return None  # a repeated vertex
    # corners are labelled by their successor next(c) = 3k + (l + 1) % 3 from here on
    order, code, _ = _sorted_half_edges(table, n, idx, step=1)
    del table, a, b, c
    diff = code[1:] ^ code[:-1]
    if not diff.all():
        return None  # a directed half-edge twice: > 2 triangles or inconsistent orientation
    pair = np.flatnonzero(diff == 1)  # the two directions of one edge
    del diff, code
    p, q = order[pair], order[pair + 1]
    del order, pair
    # twin[next(e)] = next(e') for the two half-edges e, e' of an interior edge, else -1
    twin = np.full(nc, -1, dtype=idx)
    twin[p] = q
    twin[q] = p
    del p, q
    first = np.flatnonzero(twin < 0)  # next(e) of the boundary half-edges e, sorted
    # 2-path connectivity
    nbr = twin // 3
    nbr[first] = first // 3
    if nt <= _NUMPY_CONNECTIVITY:  # small meshes: numpy only, no scipy import
        from .orientation import component_labels

        inner = np.flatnonzero(twin >= 0)
        if component_labels(nt, inner // 3, twin[inner] // 3).any():
            return None
    else:
        graph = sp.csr_matrix(
            (np.ones(nc), nbr, np.arange(0, nc + 1, 3, dtype=idx)), shape=(nt, nt)
        )
        reached = _csgraph.breadth_first_order(graph, 0, directed=True,
                                               return_predecessors=False)
        if len(reached) != nt:
            return None
        del graph, reached
    del nbr
    # bow-ties: succ(c) = next(twin(next(c))) = twin[prev(c)]
    tn = twin.reshape(nt, 3)
    succ = np.empty_like(tn)
    succ[:, 1:] = tn[:, :2]
    succ[:, 0] = tn[:, 2]
    succ = succ.ravel()
    del tn, twin
    flat = tri.ravel()
    start = np.empty(n, dtype=idx)
    start[flat] = np.arange(nc, dtype=idx)  # any corner at each vertex
    if len(first):
        # a boundary fan at v starts at next(e) for the boundary half-edge e leaving v
        at = flat[first]
        if np.bincount(at, minlength=n).max() > 1:
            return None  # two boundary fans at a vertex
        start[at] = first
    maxdeg = int(deg.max())
    if maxdeg > 1:
        key = maxdeg - deg
        by_degree = np.argsort(key.astype(np.uint16) if maxdeg < 2**16 else key, kind="stable")
        n_more = n - np.cumsum(np.bincount(deg))  # n_more[s]: vertices with > s triangles
        cur = start[by_degree]
        origin = cur.copy()
        for s in range(1, min(maxdeg, _WALK_STEPS + 1)):
            m = n_more[s]
            cur = succ[cur[:m]]
            if (cur < 0).any() or (cur == origin[:m]).any():
                return None  # a fan ended or closed before visiting every corner
    if maxdeg > _WALK_STEPS + 1:
        sel = np.flatnonzero(deg[flat] > _WALK_STEPS + 1)
        local = np.full(nc, -1, dtype=idx)
        local[sel] = np.arange(len(sel), dtype=idx)
        nxt = succ[sel]
        sub = np.where(nxt >= 0, local[nxt], np.arange(len(sel), dtype=idx))
        if _count_fans(sub, flat[sel], n).max() > 1:
            return None
    return np.sort(_prev_corner(first))


def _next_corner(c: IntArray) -> IntArray:
    """``next(3k + l) = 3k + (l + 1) % 3``."""
    out = c + 1
    out[c % 3 == 2] -= 3
    return out


def _prev_corner(c: IntArray) -> IntArray:
    """``prev(3k + l) = 3k + (l + 2) % 3``."""
    out = c - 1
    out[c % 3 == 0] += 3
    return out


def _boundary_edges_of(tri: IntArray, corners: IntArray) -> IntArray:
    """Directed boundary edges ``(B, 2)`` of the half-edges at ``corners`` (sorted)."""
    flat = tri.ravel()
    return np.stack([flat[_next_corner(corners)], flat[_prev_corner(corners)]], axis=1)


def boundary_self_intersections(points: FloatArray, boundary_edges: IntArray) -> IntArray:
    """Pairs of non-adjacent boundary edges that intersect, ``(K, 2)`` indices.

    A broad phase with a k-d tree on edge midpoints (two segments can only meet when their
    midpoints are closer than the longest edge) followed by exact orientation tests.
    """
    if len(boundary_edges) < 3:
        return np.zeros((0, 2), np.int64)
    a = points[boundary_edges[:, 0]]
    b = points[boundary_edges[:, 1]]
    if len(boundary_edges) > _NUMPY_PAIRS:
        from scipy.spatial import cKDTree
    mid = 0.5 * (a + b)
    reach = float(np.linalg.norm(b - a, axis=1).max())
    if len(boundary_edges) <= _NUMPY_PAIRS:  # the same pairs as the k-d tree, no scipy
        pairs = np.stack(np.triu_indices(len(boundary_edges), 1), axis=1)
        gap = np.linalg.norm(mid[pairs[:, 0]] - mid[pairs[:, 1]], axis=1)
        pairs = pairs[gap <= reach * (1 + 1e-9)]
    else:
        pairs = cKDTree(mid).query_pairs(reach * (1 + 1e-9), output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), np.int64)
    i, j = pairs[:, 0], pairs[:, 1]
    e = boundary_edges
    share = (
        (e[i, 0] == e[j, 0]) | (e[i, 0] == e[j, 1]) | (e[i, 1] == e[j, 0]) | (e[i, 1] == e[j, 1])
    )
    i, j = i[~share], j[~share]

    def orient(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    d1 = orient(a[i], b[i], a[j])
    d2 = orient(a[i], b[i], b[j])
    d3 = orient(a[j], b[j], a[i])
    d4 = orient(a[j], b[j], b[i])
    hit = (d1 * d2 <= 0) & (d3 * d4 <= 0)
    # collinear but disjoint segments satisfy the sign test; exclude them by projection
    col = hit & (d1 == 0) & (d2 == 0)
    if col.any():
        k = np.flatnonzero(col)
        dvec = b[i[k]] - a[i[k]]
        t0 = np.einsum("kd,kd->k", a[j[k]] - a[i[k]], dvec)
        t1 = np.einsum("kd,kd->k", b[j[k]] - a[i[k]], dvec)
        L = np.einsum("kd,kd->k", dvec, dvec)
        overlap = (np.maximum(t0, t1) >= 0) & (np.minimum(t0, t1) <= L)
        hit[k] = overlap
    return np.stack([i[hit], j[hit]], 1)


def check_mesh(mesh: TriangleMesh) -> MeshReport:
    """Run every check of SPEC §1 and report (never raises for a readable mesh).

    A planar-manifold mesh whose triangles are all clockwise is re-oriented to CCW; the
    report says so and carries the re-oriented mesh.
    """
    return _check_mesh(mesh)


def _check_mesh(mesh: TriangleMesh, positive_areas: bool = False) -> MeshReport:
    """:func:`check_mesh`; ``positive_areas=True`` is the caller's promise that every
    signed area of ``mesh`` is > 0 (e.g. from a quality summary), which skips that pass.

    A clean mesh is recognised by :func:`_clean_manifold`; only a mesh with a problem pays
    for the edge list and the description of the problem (:func:`_manifold_problems`).
    """
    from .orientation import diagnose, planar_view, with_embedding_of  # issue 12 hooks

    pm, why = planar_view(mesh)
    if pm is None:
        return MeshReport(False, False, False, problems=[why], mesh=mesh)
    corners = pm._clean_corners
    n_flipped, soft = 0, []
    if corners is None:
        pm, n_flipped, hard, soft = diagnose(pm)
        if hard:
            return MeshReport(True, False, False, n_flipped > 0, hard + soft, pm, n_flipped)
        corners = pm._clean_corners
    if corners is not None and "boundary_edges" not in pm.__dict__:
        pm.__dict__["boundary_edges"] = _frozen(_boundary_edges_of(pm.triangles, corners))
    reoriented = False
    area = None if positive_areas else pm.signed_areas()
    if area is not None and area.sum() < 0 and corners is not None:
        pm = with_embedding_of(pm.flipped(), pm)
        area = -area
        reoriented = True
        n_flipped = pm.n_triangles
        if corners is not None:
            # corner 3k + l of the flipped mesh is corner 3k + 2 - l of the original
            flip = np.sort(corners - 2 * (corners % 3) + 2)
            pm.__dict__["boundary_edges"] = _frozen(_boundary_edges_of(pm.triangles, flip))
        logger.info("%s: re-oriented from clockwise to counter-clockwise", pm.source or "mesh")
    problems = list(soft)
    reoriented = reoriented or n_flipped > 0
    nonpos = np.flatnonzero(area <= 0) if area is not None else ()
    if len(nonpos):
        k = nonpos[0]
        kind = "zero-area" if area[k] == 0 else "inverted"
        problems.append(
            f"triangle {k} {pm.triangles[k].tolist()} is {kind} (signed area {area[k]:.3g})"
            + (f"; {len(nonpos)} non-positive triangles" if len(nonpos) > 1 else "")
        )
    hits = boundary_self_intersections(pm.points, pm.boundary_edges)
    if len(hits):
        e1, e2 = pm.boundary_edges[hits[0, 0]], pm.boundary_edges[hits[0, 1]]
        problems.append(
            f"boundary self-intersects: edges ({e1[0]}, {e1[1]}) and ({e2[0]}, {e2[1]}) cross"
        )
    return MeshReport(True, True, not problems, reoriented, problems, pm, n_flipped)


def require_admissible(mesh: TriangleMesh, what: str = "this operation") -> PlanarMesh:
    """Return the (CCW-oriented) planar mesh, or raise a clear error naming the problem.

    Raises
    ------
    InvalidMeshError
        Not planar or not a planar manifold.
    NotAdmissibleError
        Planar manifold but with an inverted/zero-area triangle or boundary crossing.
    """
    report = check_mesh(mesh)
    where = f"{mesh.source}: " if mesh.source else ""
    if not report.manifold:
        raise InvalidMeshError(f"{where}{what} needs a planar manifold mesh: {report.problems[0]}")
    if not report.admissible:
        raise NotAdmissibleError(f"{where}{what} needs an admissible mesh: {report.problems[0]}")
    if report.reoriented:
        logger.warning("%sreoriented %d triangles", where, report.n_reoriented)
    return report.mesh  # type: ignore[return-value]
