"""The triangle-mesh values (SPEC §1).

:class:`TriangleMesh` is the *readable* level: finite coordinates in 2D or 3D, indices in
range, at least one triangle. It is what file I/O and conversion work with.
:class:`PlanarMesh` adds planarity (points are stored as ``(N, 2)``) and is the object
every deformation and optimization works on. Both are immutable values: moving nodes
returns a new mesh (:meth:`PlanarMesh.with_points`), and derived topology (edges,
boundary, adjacency; built from the half-edge tables of :mod:`.topology`) is a
``functools.cached_property``.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from .._lazy import lazy_module
from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError
from ..kernels.admissibility import non_finite_problem
from ..kernels.triangles import quality_summary, signed_areas
from ..orientation import plane_embedding
from .topology import (_clean_manifold, _corner_table, _edge_index, _frozen, _sorted_half_edges,
                       new_points, tagged_vertices)
from .value import MeshValue

sp = lazy_module("scipy.sparse")  # imported on first use: info/convert need no scipy

__all__ = ["PlanarMesh", "TriangleMesh"]

#: the keywords of a mesh that operations changing its points or triangles keep
_KEPT = ("triangle_tags", "lines", "line_tags", "tag_names", "source")


class TriangleMesh(MeshValue):
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

    _cells, _count = "triangles", "n_triangles"  # repr and == (MeshValue)

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

    # -- plain data (read-only views, the idiom of every mesh class) ---------------
    points = property(lambda self: self._points,
                      doc="Node positions, read-only ``(N, d)`` float64.")
    triangles = property(lambda self: self._triangles,
                         doc="Connectivity, read-only ``(T, 3)`` int64.")
    triangle_tags = property(lambda self: self._triangle_tags,
                             doc="Physical tag per triangle ``(T,)``, or None.")
    lines = property(lambda self: self._lines, doc="Tagged line elements ``(L, 2)``, or None.")
    line_tags = property(lambda self: self._line_tags,
                         doc="Physical tag per line element ``(L,)``, or None.")
    tag_names = property(lambda self: dict(self._tag_names),
                         doc="``{name: (tag, dim)}`` physical names.")
    source = property(lambda self: self._source, doc="The file this mesh was read from, if any.")
    n_vertices = property(lambda self: len(self._points))
    n_triangles = property(lambda self: len(self._triangles))

    @property
    def dim(self) -> int:
        """Number of coordinates per point (2 or 3)."""
        return self._points.shape[1]

    def _tag_kwargs(self) -> dict:
        """What a mesh with other points or triangles keeps: the constructor's keywords."""
        return {name: getattr(self, "_" + name) for name in _KEPT}

    @property
    def in_xy_plane(self) -> bool:
        """True if the points are 2D, or 3D with every z exactly 0 (z drops losslessly)."""
        return self.dim == 2 or not np.any(self._points[:, 2])

    @property
    def is_planar(self) -> bool:
        """True if the points lie on one plane, any plane, within
        :data:`~meshopt_toolkit.orientation.PLANE_RTOL` (2D points always)."""
        if self.in_xy_plane:
            return True
        try:
            self._plane_view  # noqa: B018
        except InvalidMeshError:
            return False
        return True

    def as_planar(self) -> PlanarMesh:
        """This mesh as a :class:`PlanarMesh`.

        z is dropped when every z is 0; a mesh on another plane is given in the
        coordinates of an orthonormal frame of its plane, with that frame as ``embedding``
        (a :class:`~meshopt_toolkit.orientation.PlaneEmbedding`; :func:`meshopt_toolkit.io.save`
        writes the points back into the plane).

        Raises
        ------
        InvalidMeshError
            The points are not on one plane.
        """
        if isinstance(self, PlanarMesh):
            return self
        if self.in_xy_plane:
            return PlanarMesh(self._points, self._triangles, **self._tag_kwargs())
        return self._plane_view

    @cached_property
    def _plane_view(self) -> PlanarMesh:
        emb = plane_embedding(self._points, self._triangles, self._source)
        pm = PlanarMesh(emb.to_2d(self._points), self._triangles, **self._tag_kwargs())
        pm.__dict__["embedding"] = emb
        return pm

    def edge_ids(self, pairs) -> IntArray:
        """Index into :attr:`edges` of each vertex pair ``(K, 2)`` (either order); -1 where
        the pair is not an edge of the mesh."""
        key = np.sort(np.asarray(pairs, dtype=np.int64).reshape(-1, 2), axis=1)
        if not len(key):
            return np.zeros(0, np.int64)
        return _edge_index(self.edges, key)

    # -- topology (cached) ----------------------------------------------------------
    @cached_property
    def _triangle_columns(self) -> IntArray:
        """The triangles as a contiguous ``(3, T)`` array, row ``l`` = local vertex ``l``.

        Its transpose is the triangle array in column-major order: per-vertex gathers
        (``np.take(x, triangles.T)`` in :mod:`~meshopt_toolkit.kernels.triangles`) run several
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

    # the parts of :attr:`_edge_data`
    edges = property(lambda self: self._edge_data[0], doc="Unique undirected edges ``(E, 2)``, "
                     "each sorted (i < j), lexicographic order.")
    triangle_edges = property(lambda self: self._edge_data[1], doc="Index into :attr:`edges` "
                              "of the edge opposite each local vertex, ``(T, 3)``.")
    edge_triangle_counts = property(lambda self: self._edge_data[2],
                                    doc="Number of triangles containing each edge ``(E,)``.")
    _edge_corners = property(lambda self: self._edge_data[3], doc="First two corners "
                             "``3 k + l`` containing each edge ``(E, 2)``; -1 if only one.")

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

    def tagged_vertices(self, tag: int | str) -> IntArray:
        """Sorted vertices of the line elements and triangles carrying a physical tag, or
        of the group named ``tag`` (the elements of its dimension):
        :func:`~.topology.tagged_vertices`."""
        return tagged_vertices(tag, self._tag_names, (
            (1, self._lines, self._line_tags), (2, self._triangles, self._triangle_tags)))


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
                    f"{where}not planar: vertex {nz[0]} has z = {float(pts[nz[0], 2])!r} "
                    "(PlanarMesh takes 2D points or z = 0; TriangleMesh.as_planar takes any "
                    "plane)")
            pts = pts[:, :2]
        super().__init__(pts, triangles, **kwargs)

    def with_points(self, points) -> PlanarMesh:
        """A new mesh with the same connectivity and tags at new positions ``(N, 2)``."""
        q = new_points(points, self._points.shape)
        new = object.__new__(PlanarMesh)
        new.__dict__.update({k: v for k, v in self.__dict__.items() if not k.startswith("_geom")})
        if not np.isfinite(q).all():
            raise InvalidMeshError(non_finite_problem(q))
        new._points = _frozen(q.copy())
        return new

    def flipped(self) -> PlanarMesh:
        """The same mesh with every triangle's orientation reversed."""
        return PlanarMesh(self._points, self._triangles[:, ::-1], **self._tag_kwargs())

    def signed_areas(self) -> FloatArray:
        """Signed area per triangle ``(T,)``."""
        return signed_areas(self._points, self._triangle_columns.T)

    def quality(self):
        """:class:`~meshopt_toolkit.kernels.triangles.QualitySummary` of the current positions."""
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
            # each line element that is a mesh edge becomes its two halves, in place; one
            # that is not (rare) is kept unsplit
            idx = _edge_index(edges, np.sort(self._lines, axis=1))
            split = idx >= 0
            counts = np.where(split, 2, 1)
            m = np.where(split, n + idx, self._lines[:, 1])
            halves = np.stack([np.stack([self._lines[:, 0], m], 1),
                               np.stack([m, self._lines[:, 1]], 1)], 1)
            first = np.repeat(np.arange(len(counts)), counts)
            second = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
            lines = halves[first, second]
            ltags = np.repeat(self._line_tags, counts)
        return PlanarMesh(
            pts,
            tri,
            triangle_tags=ttags,
            lines=lines,
            line_tags=ltags,
            tag_names=self._tag_names,
            source=self._source,
        )


