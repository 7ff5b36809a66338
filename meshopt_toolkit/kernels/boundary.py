"""Admissibility kernels of the boundary: does a closed polygon touch itself, and do its
loops nest as the boundary of an embedded region?

Plain functions of ``points (N, 2)`` and directed ``boundary_edges (E, 2)`` (interior on
the left); every sign is exact (:mod:`.predicates`).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from .predicates import exactly_scaled, orient2d, orient2d_xy, segments_intersect

__all__ = ["BoundaryLoops", "boundary_loops", "boundary_self_intersections", "loop_nesting",
           "loop_orientations"]

#: at most this many boundary edges are intersected pairwise in numpy (no scipy import)
_NUMPY_PAIRS = 600
#: loop nesting works on at most about this many (point, edge) pairs at a time
_BATCH = 1 << 21


def boundary_self_intersections(points: FloatArray, boundary_edges: IntArray) -> IntArray:
    """Pairs of non-adjacent boundary edges that intersect, ``(K, 2)`` indices.

    A broad phase on edge midpoints (two segments can only meet when their midpoints are
    at most the longest edge apart; a k-d tree above ``_NUMPY_PAIRS`` edges) with a margin
    for the rounding of midpoints and lengths, then the exact test
    :func:`~.predicates.segments_intersect` (touching and collinear overlap count).
    """
    if len(boundary_edges) < 3:
        return np.zeros((0, 2), np.int64)
    E = len(boundary_edges)
    ab, _ = exactly_scaled(np.concatenate([points[boundary_edges[:, 0]],
                                           points[boundary_edges[:, 1]]]), extreme_only=True)
    a, b = ab[:E], ab[E:]
    mid = 0.5 * a + 0.5 * b  # no overflow where the points could not be scaled
    with np.errstate(over="ignore"):
        reach = float(np.linalg.norm(b - a, axis=1).max())
    # relative rounding of the lengths, absolute rounding of the midpoints
    reach = reach * (1 + 1e-9) + 8 * np.finfo(float).eps * float(np.abs(ab).max())
    if len(boundary_edges) <= _NUMPY_PAIRS:  # the same pairs as the k-d tree, no scipy
        pairs = np.stack(np.triu_indices(len(boundary_edges), 1), axis=1)
        with np.errstate(over="ignore"):
            gap = np.linalg.norm(mid[pairs[:, 0]] - mid[pairs[:, 1]], axis=1)
        pairs = pairs[gap <= reach]
    else:
        from scipy.spatial import cKDTree

        pairs = cKDTree(mid).query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), np.int64)
    i, j = pairs[:, 0], pairs[:, 1]
    e = boundary_edges
    share = (
        (e[i, 0] == e[j, 0]) | (e[i, 0] == e[j, 1]) | (e[i, 1] == e[j, 0]) | (e[i, 1] == e[j, 1])
    )
    i, j = i[~share], j[~share]
    hit = segments_intersect(a[i], b[i], a[j], b[j])
    out = np.stack([i[hit], j[hit]], 1)
    return out[np.lexsort((out[:, 1], out[:, 0]))] if len(out) else out


def boundary_loops(boundary_edges: IntArray) -> IntArray:
    """The loop of each directed boundary edge, ``(E,)`` labels ``0 … L−1``.

    Each boundary vertex of a planar-manifold mesh starts exactly one boundary edge, so
    "the edge that starts where this one ends" is a permutation of the edges; its cycles
    are the loops, labelled by pointer jumping (the smallest edge index in each cycle),
    numbered in the order of their smallest edge.
    """
    be = np.asarray(boundary_edges)
    E = len(be)
    if E == 0:
        return np.zeros(0, np.int64)
    order = np.argsort(be[:, 0], kind="stable")
    pos = np.clip(np.searchsorted(be[order, 0], be[:, 1]), 0, E - 1)
    nxt = order[pos]
    if not np.array_equal(be[nxt, 0], be[:, 1]):
        raise ValueError("the boundary edges do not form closed loops")
    label = np.arange(E)
    step = nxt.copy()
    for _ in range(max(1, int(E).bit_length())):
        np.minimum(label, label[step], out=label)
        step = step[step]
    _, loops = np.unique(label, return_inverse=True)
    return loops.astype(np.int64)


class BoundaryLoops:
    """The loops of a directed boundary, prepared once for judging many positions.

    Parameters
    ----------
    boundary_edges : (E, 2) directed edges (interior on the left)
    loops : (E,) loop labels of :func:`boundary_loops` (computed when None)

    Attributes
    ----------
    loops : (E,) the labels; ``n_loops`` their number.
    """

    def __init__(self, boundary_edges: IntArray, loops: IntArray | None = None) -> None:
        be = np.asarray(boundary_edges)
        self.loops = boundary_loops(be) if loops is None else np.asarray(loops)
        self.n_loops = int(self.loops.max()) + 1 if len(self.loops) else 0
        # the boundary vertices only, numbered 0 … V−1; edges sorted by loop
        self.used, local = np.unique(be, return_inverse=True)
        local = local.reshape(be.shape)
        self.order = np.argsort(self.loops, kind="stable")
        self.start = np.searchsorted(self.loops[self.order], np.arange(self.n_loops + 1))
        self.u, self.v = local[self.order, 0], local[self.order, 1]  # in loop order
        self.loop_of = self.loops[self.order]
        # the edge (in loop order) that ends where each edge starts
        by_end = np.argsort(self.v, kind="stable")
        self.prev = by_end[np.searchsorted(self.v[by_end], self.u)]

    def _points(self, points: FloatArray) -> FloatArray:
        return exactly_scaled(np.asarray(points, dtype=float)[self.used], extreme_only=True)[0]

    def _orientations(self, P: FloatArray) -> tuple[np.ndarray, IntArray]:
        # judged vertex: the lexicographically smallest start vertex of each loop
        x, y = P[self.u, 0], P[self.u, 1]
        heads = self.start[:-1]
        xmin = np.minimum.reduceat(x, heads)
        at_min = x == xmin[self.loop_of]
        ymin = np.minimum.reduceat(np.where(at_min, y, np.inf), heads)
        hit = np.flatnonzero(at_min & (y == ymin[self.loop_of]))
        lp = self.loop_of[hit]
        first = hit[np.concatenate([[True], lp[1:] != lp[:-1]])]
        vertex = self.u[first]
        sign = orient2d(P[self.u[self.prev[first]]], P[vertex], P[self.v[first]])
        return sign, vertex

    def orientations(self, points: FloatArray) -> tuple[np.ndarray, IntArray]:
        """``(sign, vertex)``: each loop's exact orientation (+1 counter-clockwise, −1
        clockwise) judged at its lexicographically smallest vertex ``vertex`` (valid for
        loops that are simple polygons, see :meth:`nesting`)."""
        if not self.n_loops:
            return np.zeros(0, np.int8), np.zeros(0, np.int64)
        sign, vertex = self._orientations(self._points(points))
        return sign, self.used[vertex]

    def nesting(self, points: FloatArray) -> tuple[np.ndarray, IntArray, IntArray]:
        """``(sign, depth, vertex)``: :meth:`orientations` and how many other loops
        enclose each loop (exact; the loops must be pairwise disjoint simple polygons,
        i.e. the boundary simple). See :func:`loop_nesting`."""
        L = self.n_loops
        if not L:
            return np.zeros(0, np.int8), np.zeros(0, np.int64), np.zeros(0, np.int64)
        P = self._points(points)
        sign, vertex = self._orientations(P)
        depth = np.zeros(L, np.int64)
        if L < 2:
            return sign, depth, self.used[vertex]
        # bounding boxes; candidate pairs (inner k, outer m): box of k inside box of m
        heads = self.start[:-1]
        x, y = P[self.u, 0], P[self.u, 1]
        lo = np.stack([np.minimum.reduceat(x, heads), np.minimum.reduceat(y, heads)], 1)
        hi = np.stack([np.maximum.reduceat(x, heads), np.maximum.reduceat(y, heads)], 1)
        rows = max(1, _BATCH // L)  # the (L, L) box test in row blocks
        ks, ms = [], []
        for r in range(0, L, rows):
            inner = lo[r:r + rows, 0, None] >= lo[None, :, 0]
            inner &= lo[r:r + rows, 1, None] >= lo[None, :, 1]
            inner &= hi[r:r + rows, 0, None] <= hi[None, :, 0]
            inner &= hi[r:r + rows, 1, None] <= hi[None, :, 1]
            kk, mm = np.nonzero(inner)
            ks.append(kk + r)
            ms.append(mm)
        k, m = np.concatenate(ks), np.concatenate(ms)
        keep = k != m
        k, m = k[keep], m[keep]
        # every edge of loop m against the judged vertex of loop k, in batches of pairs
        counts = self.start[m + 1] - self.start[m]
        cum = np.cumsum(counts)
        cuts = np.searchsorted(cum, np.arange(_BATCH, int(cum[-1]) if len(cum) else 0, _BATCH))
        splits = np.unique(np.concatenate([[0], cuts, [len(k)]]))
        inside = np.zeros(len(k), bool)
        for s0, s1 in zip(splits[:-1], splits[1:]):
            sel = slice(int(s0), int(s1))
            inside[sel] = self._winds(P, vertex[k[sel]], m[sel], counts[sel])
        depth = np.bincount(k[inside], minlength=L).astype(np.int64)
        return sign, depth, self.used[vertex]

    def _winds(self, P, points, m, counts) -> np.ndarray:
        """Is each point ``P[points[i]]`` inside loop ``m[i]`` (non-zero exact winding
        number, half-open crossings of the horizontal line through it)?"""
        pair = np.repeat(np.arange(len(m)), counts)
        offs = np.arange(len(pair)) - np.repeat(np.cumsum(counts) - counts, counts)
        edge = np.repeat(self.start[m], counts) + offs
        p = P[points[pair]]
        a, b = P[self.u[edge]], P[self.v[edge]]
        up = (a[:, 1] <= p[:, 1]) & (b[:, 1] > p[:, 1])
        down = (b[:, 1] <= p[:, 1]) & (a[:, 1] > p[:, 1])
        cross = np.flatnonzero(up | down)
        side = orient2d_xy(a[cross, 0], a[cross, 1], b[cross, 0], b[cross, 1],
                           p[cross, 0], p[cross, 1])
        wind = np.zeros(len(pair), np.int64)
        wind[cross] = (up[cross] & (side > 0)).astype(np.int64) - (down[cross] & (side < 0))
        return np.bincount(pair, weights=wind, minlength=len(m)) != 0


def loop_orientations(points: FloatArray, boundary_edges: IntArray,
                      loops: IntArray | None = None) -> tuple[np.ndarray, IntArray]:
    """:meth:`BoundaryLoops.orientations` of the loops of ``boundary_edges``."""
    return BoundaryLoops(boundary_edges, loops).orientations(points)


def loop_nesting(points: FloatArray, boundary_edges: IntArray, loops: IntArray | None = None
                 ) -> tuple[IntArray, np.ndarray, IntArray, IntArray]:
    """Orientation and nesting depth of each boundary loop (exact; the loops must be
    pairwise disjoint simple polygons, i.e. the boundary simple).

    Parameters
    ----------
    points : (N, 2)
    boundary_edges : (E, 2) directed edges
    loops : (E,) loop labels of :func:`boundary_loops` (computed when None)

    Returns
    -------
    loops : (E,) the labels
    sign : (L,) int8, +1 for a counter-clockwise loop, −1 for a clockwise one
    depth : (L,) how many other loops enclose the loop
    vertex : (L,) the vertex each loop is judged at (its lexicographically smallest)

    Notes
    -----
    A simple polygon's orientation is the exact orientation at its lexicographically
    smallest vertex: both neighbours are lexicographically larger, so a straight turn there
    would put them on one ray from it, i.e. the two edges would overlap. Disjoint loops are
    nested or apart, so a loop is inside another iff its judged vertex is; that is a
    winding number with half-open crossings of the horizontal line (comparisons of floats
    and exact orientations), computed only for pairs whose bounding boxes nest.
    """
    bl = BoundaryLoops(boundary_edges, loops)
    sign, depth, vertex = bl.nesting(points)
    return bl.loops, sign, depth, vertex
