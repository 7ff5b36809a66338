"""Exact self-intersections of triangles in 3D: which pairs of triangles of a surface (or
of a tet mesh's boundary) meet where the mesh says they should not.

Two triangles *intersect improperly* when their closed point sets meet beyond what their
shared vertices say: nowhere for triangles sharing no vertex, only at the vertex for
triangles sharing one, only along the edge for triangles sharing two (so a pair folded
flat onto each other across their edge counts), always for two triangles on the same
three vertices. Sharing is by vertex index: distinct vertices at the same point touch.

- **Broad phase** (:func:`candidate_pairs`): the triangles' axis-aligned boxes in a
  uniform grid (cells about the median box size; the few boxes spanning many cells are
  compared with all boxes directly); pairs of closed boxes that overlap, each once.
- **Narrow phase** (:func:`intersecting_pairs`): every decision is a sign of
  :func:`~.predicates.orient3d` or :func:`~.predicates.orient2d` of the input points, so
  the answer is that of the exact real numbers the floats stand for. Two triangles meet
  iff an edge of one meets the other (the intersection of two convex sets has an extreme
  point on an edge of one of them). A segment meets a triangle not in its plane iff its
  endpoints are not strictly on one side of the plane and the three orientations of the
  segment's line with the triangle's edges agree in sign (zeros allowed). A segment in
  the triangle's plane meets it iff their projections meet on a coordinate plane where
  the triangle keeps a nonzero area (that projection is one-to-one on the plane);
  two segments in space likewise, once coplanar. A zero-area triangle is the union of its
  edges.

Adjacent pairs: sharing an edge ``ab``, triangles ``abc`` and ``abd`` meet beyond it iff
they are coplanar and ``c``, ``d`` lie strictly on the same side of ``ab``; sharing a
vertex ``a``, triangles ``abc`` and ``ade`` meet beyond it iff ``bc`` meets ``ade`` or
``de`` meets ``abc`` (for a zero-area triangle with ``a`` inside its opposite edge the
pair is reported even where it touches only at ``a``).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError
from .predicates import exactly_scaled, orient2d, orient3d, segments_intersect

__all__ = ["self_intersections", "candidate_pairs", "intersecting_pairs",
           "degenerate_triangles_exact"]

#: a box over more grid cells than this is compared with every box directly
_MAX_CELLS = 64
#: at most this many such boxes (else the cells grow)
_MAX_BIG = 256
#: pairs tested at once in the narrow phase (bounds the temporary arrays)
_CHUNK = 1 << 18
_DROPS = ((1, 2), (2, 0), (0, 1))  # the coordinate planes: (y, z), (z, x), (x, y)


def _boxes(V: FloatArray, F: IntArray) -> tuple[FloatArray, FloatArray]:
    X = V[F]
    return X.min(axis=1), X.max(axis=1)


def _overlap(lo, hi, i, j) -> np.ndarray:
    """Do the closed boxes ``i`` and ``j`` overlap (touching included)? One axis at a
    time, on the pairs still in."""
    keep = np.ones(len(i), bool)
    for d in range(3):
        k = np.flatnonzero(keep)
        lo_d, hi_d = np.ascontiguousarray(lo[:, d]), np.ascontiguousarray(hi[:, d])
        ik, jk = i[k], j[k]
        keep[k] = (lo_d[ik] <= hi_d[jk]) & (lo_d[jk] <= hi_d[ik])
    return keep


def candidate_pairs(lo: FloatArray, hi: FloatArray) -> IntArray:
    """Pairs ``(i, j)``, ``i < j``, of closed boxes that overlap, each once.

    Parameters
    ----------
    lo, hi : (T, 3) float arrays
        The boxes' corners (finite).

    Returns
    -------
    (P, 2) int64 array, sorted by rows.
    """
    T = len(lo)
    if T < 2:
        return np.zeros((0, 2), np.int64)
    ext = (hi - lo).max(axis=1)
    span = float((hi.max(axis=0) - lo.min(axis=0)).max())
    if span == 0.0:  # every box is one and the same point
        i, j = np.triu_indices(T, 1)
        return np.stack([i, j], axis=1).astype(np.int64)
    positive = ext[ext > 0]
    s = float(np.median(positive)) if len(positive) else span / np.cbrt(T)
    s = max(s, span / 2.0**20)  # at most 2^20 cells per axis: keys fit in int64
    origin = lo.min(axis=0)
    while True:
        with np.errstate(over="ignore"):
            ilo = np.floor((lo - origin) / s).astype(np.int64)
            ihi = np.floor((hi - origin) / s).astype(np.int64)
        n_cells = np.prod(ihi - ilo + 1, axis=1)
        big = np.flatnonzero(n_cells > _MAX_CELLS)
        if len(big) <= _MAX_BIG:
            break
        s *= 2.0
    pairs = [_grid_pairs(lo, hi, ilo, ihi, n_cells, origin, s, big)]
    is_big = np.zeros(T, bool)
    is_big[big] = True
    for b in big:  # each against every box, vectorized
        other = np.flatnonzero(((lo <= hi[b]) & (lo[b] <= hi)).all(axis=1))
        other = other[(other != b) & (~is_big[other] | (other > b))]
        pairs.append(np.stack([np.minimum(other, b), np.maximum(other, b)], axis=1))
    out = np.concatenate(pairs)
    return out[np.lexsort((out[:, 1], out[:, 0]))]


def _grid_pairs(lo, hi, ilo, ihi, n_cells, origin, s, big) -> IntArray:
    """Overlapping pairs among the boxes not in ``big``, each found in the one cell that
    holds the low corner of the two boxes' intersection."""
    small = np.ones(len(lo), bool)
    small[big] = False
    t = np.flatnonzero(small)
    counts = n_cells[t]
    tri = np.repeat(t, counts)
    local = np.arange(len(tri)) - np.repeat(np.cumsum(counts) - counts, counts)
    nx, ny, _ = (ihi[tri] - ilo[tri] + 1).T
    cell = ilo[tri] + np.stack([local % nx, (local // nx) % ny, local // (nx * ny)], axis=1)
    key = (cell[:, 0] << 42) | (cell[:, 1] << 21) | cell[:, 2]
    order = np.argsort(key, kind="stable")
    key, tri = key[order], tri[order]
    start = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]]))
    size = np.diff(np.append(start, len(key)))
    rank = np.arange(len(key)) - np.repeat(start, size)
    partners = np.repeat(size, size) - 1 - rank  # entries after this one in its cell
    first = np.repeat(np.arange(len(key)), partners)
    second = first + 1 + (np.arange(len(first)) - np.repeat(np.cumsum(partners) - partners,
                                                            partners))
    i, j = tri[first], tri[second]
    keep = _overlap(lo, hi, i, j)
    i, j, k = i[keep], j[keep], key[first[keep]]
    with np.errstate(over="ignore"):
        corner = np.floor((np.maximum(lo[i], lo[j]) - origin) / s).astype(np.int64)
    home = ((corner[:, 0] << 42) | (corner[:, 1] << 21) | corner[:, 2]) == k
    i, j = i[home], j[home]
    return np.stack([np.minimum(i, j), np.maximum(i, j)], axis=1)


def degenerate_triangles_exact(V: FloatArray, F: IntArray) -> np.ndarray:
    """``(T,)`` bool: the triangle's three points are exactly collinear (zero area)."""
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return np.all([orient2d(A[:, d], B[:, d], C[:, d]) == 0 for d in _DROPS], axis=0)


def _segments_meet(p, q, u, v) -> np.ndarray:
    """Do the closed segments ``[p, q]`` and ``[u, v]`` in space meet? Exact; (K,) bool."""
    hit = orient3d(p, q, u, v) == 0
    for d in _DROPS:
        if not hit.any():
            break
        k = np.flatnonzero(hit)
        hit[k] = segments_intersect(p[k][:, d], q[k][:, d], u[k][:, d], v[k][:, d])
    return hit


def _inside_2d(p, a, b, c) -> np.ndarray:
    """Is the 2D point ``p`` in the closed triangle ``abc`` (non-degenerate)?"""
    o = np.stack([orient2d(a, b, p), orient2d(b, c, p), orient2d(c, a, p)])
    return (o >= 0).all(axis=0) | (o <= 0).all(axis=0)


def _coplanar_segment_meets(p, q, a, b, c) -> np.ndarray:
    """Segment and non-degenerate triangle in one plane: do they meet? (K,) bool.

    Decided in one coordinate projection per row, one on which the triangle keeps a
    nonzero area (exact): that projection is one-to-one on the plane. The normal's largest
    component (floats) names the first tried."""
    drop = np.argmax(np.abs(np.cross(b - a, c - a)), axis=1)
    hit = np.zeros(len(p), bool)
    todo = np.ones(len(p), bool)
    for shift in range(3):
        for i, d in enumerate(_DROPS):
            k = np.flatnonzero(todo & ((drop + shift) % 3 == i))
            if not len(k):
                continue
            P, Q, A, B, C = (x[k][:, d] for x in (p, q, a, b, c))
            k = k[orient2d(A, B, C) != 0]
            todo[k] = False
            P, Q, A, B, C = (x[k][:, d] for x in (p, q, a, b, c))
            hit[k] = (segments_intersect(P, Q, A, B) | segments_intersect(P, Q, B, C)
                      | segments_intersect(P, Q, C, A) | _inside_2d(P, A, B, C))
    return hit


def _segment_meets_triangle(p, q, a, b, c, flat) -> np.ndarray:
    """Does the closed segment ``[p, q]`` meet the closed triangle ``abc``? ``flat``:
    the triangle has zero area. All (K, 3) but ``flat`` (K,) bool; returns (K,) bool."""
    hit = np.zeros(len(p), bool)
    f = np.flatnonzero(flat)
    if len(f):  # the union of its edges
        P, Q, A, B, C = (x[f] for x in (p, q, a, b, c))
        hit[f] = _segments_meet(P, Q, A, B) | _segments_meet(P, Q, B, C) | _segments_meet(
            P, Q, C, A)
    r = np.flatnonzero(~flat)
    if len(r):
        P, Q, A, B, C = (x[r] for x in (p, q, a, b, c))
        sp, sq = orient3d(A, B, C, P), orient3d(A, B, C, Q)
        flat_pq = (sp == 0) & (sq == 0)
        res = np.zeros(len(r), bool)
        k = np.flatnonzero(~flat_pq & (sp * sq <= 0))
        if len(k):
            Pk, Qk, Ak, Bk, Ck = (x[k] for x in (P, Q, A, B, C))
            o = np.stack([orient3d(Pk, Qk, Ak, Bk), orient3d(Pk, Qk, Bk, Ck),
                          orient3d(Pk, Qk, Ck, Ak)])
            res[k] = (o >= 0).all(axis=0) | (o <= 0).all(axis=0)
        k = np.flatnonzero(flat_pq)
        if len(k):
            res[k] = _coplanar_segment_meets(P[k], Q[k], A[k], B[k], C[k])
        hit[r] = res
    return hit


def _disjoint_meet(A, B, fa, fb) -> np.ndarray:
    """Triangles ``A``, ``B`` (K, 3, 3) sharing no vertex: do they meet? (K,) bool."""
    sa = np.stack([orient3d(B[:, 0], B[:, 1], B[:, 2], A[:, r]) for r in range(3)])
    sb = np.stack([orient3d(A[:, 0], A[:, 1], A[:, 2], B[:, r]) for r in range(3)])
    apart = (sa > 0).all(axis=0) | (sa < 0).all(axis=0) | (sb > 0).all(axis=0) | (
        sb < 0).all(axis=0)
    hit = np.zeros(len(A), bool)
    for X, Y, fy in ((A, B, fb), (B, A, fa)):
        for r in range(3):
            k = np.flatnonzero(~apart & ~hit)
            if not len(k):
                return hit
            hit[k] = _segment_meets_triangle(X[k, r], X[k, (r + 1) % 3], Y[k, 0], Y[k, 1],
                                             Y[k, 2], fy[k])
    return hit


def _rotated(X: FloatArray, first: IntArray) -> FloatArray:
    """Each row's vertices cyclically rotated to start at ``first``."""
    idx = (first[:, None] + np.arange(3)) % 3
    return np.take_along_axis(X, idx[:, :, None], axis=1)


def intersecting_pairs(V: FloatArray, F: IntArray, pairs: IntArray,
                       flat: np.ndarray | None = None) -> np.ndarray:
    """Which of ``pairs`` of triangles intersect improperly (see the module notes)? Exact.

    Parameters
    ----------
    V : (N, 3) float array (finite)
    F : (T, 3) int array, three distinct vertices per triangle
    pairs : (P, 2) int array of triangle indices
    flat : (T,) bool array, optional
        :func:`degenerate_triangles_exact`, if known.

    Returns
    -------
    (P,) bool array
    """
    V = np.asarray(V, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    if flat is None:
        flat = degenerate_triangles_exact(V, F)
    out = np.zeros(len(pairs), bool)
    for s in range(0, len(pairs), _CHUNK):
        i, j = pairs[s:s + _CHUNK].T
        out[s:s + _CHUNK] = _chunk(V, F[i], F[j], flat[i], flat[j])
    return out


def _chunk(V, Fa, Fb, fa, fb) -> np.ndarray:
    same = Fa[:, :, None] == Fb[:, None, :]  # (K, 3, 3): vertex r of a is vertex s of b
    shared = same.any(axis=2).sum(axis=1)
    hit = shared >= 3  # two triangles on the same vertices
    k = np.flatnonzero(shared == 0)
    if len(k):
        hit[k] = _disjoint_meet(V[Fa[k]], V[Fb[k]], fa[k], fb[k])
    k = np.flatnonzero(shared == 1)
    if len(k):  # apart when both opposite edges are strictly on one side of the other plane
        A, B = V[Fa[k]], V[Fb[k]]
        sa = sum(orient3d(B[:, 0], B[:, 1], B[:, 2], A[:, r]).astype(np.int64)
                 for r in range(3))  # the shared vertex gives 0
        sb = sum(orient3d(A[:, 0], A[:, 1], A[:, 2], B[:, r]).astype(np.int64)
                 for r in range(3))
        k = k[(np.abs(sa) != 2) | (np.abs(sb) != 2)]
    if len(k):  # rotate the shared vertex first: the opposite edges are 1–2
        A = _rotated(V[Fa[k]], np.argmax(same[k].any(axis=2), axis=1))
        B = _rotated(V[Fb[k]], np.argmax(same[k].any(axis=1), axis=1))
        hit[k] = _segment_meets_triangle(A[:, 1], A[:, 2], B[:, 0], B[:, 1], B[:, 2], fb[k])
        m = np.flatnonzero(~hit[k])
        hit[k[m]] = _segment_meets_triangle(B[m, 1], B[m, 2], A[m, 0], A[m, 1], A[m, 2],
                                            fa[k[m]])
    k = np.flatnonzero(shared == 2)
    if len(k):  # the unshared vertices c, d: coplanar and strictly on one side of ab
        A = _rotated(V[Fa[k]], (np.argmin(same[k].any(axis=2), axis=1) + 1) % 3)
        d = V[Fb[k, np.argmin(same[k].any(axis=1), axis=1)]]
        a, b, c = A[:, 0], A[:, 1], A[:, 2]
        flat_ab = orient3d(a, b, c, d) == 0
        m = np.flatnonzero(flat_ab)
        side = np.zeros(len(m), bool)
        for dd in _DROPS:
            a2, b2 = a[m][:, dd], b[m][:, dd]
            side |= orient2d(a2, b2, c[m][:, dd]) * orient2d(a2, b2, d[m][:, dd]) > 0
        hit[k[m]] = side
    return hit


def self_intersections(V: FloatArray, F: IntArray) -> IntArray:
    """The pairs of triangles that intersect improperly (see the module notes), exactly.

    Parameters
    ----------
    V : (N, 3) float array (finite)
    F : (T, 3) int array
        Triangles; one that repeats a vertex is left out (a degenerate triangle, which a
        mesh reports on its own).

    Returns
    -------
    (k, 2) int64 array
        Triangle index pairs ``(i, j)``, ``i < j``, sorted by rows.

    Raises
    ------
    InvalidMeshError
        A coordinate is not finite.
    """
    V = np.asarray(V, dtype=float).reshape(-1, 3)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    if not np.isfinite(V).all():
        raise InvalidMeshError("self-intersections need finite coordinates")
    proper = np.flatnonzero((F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2]))
    S = exactly_scaled(V)[0]  # the signs are those of V; no under- or overflow
    G = F[proper]
    lo, hi = _boxes(S, G)
    pairs = candidate_pairs(lo, hi)
    return proper[pairs[intersecting_pairs(S, G, pairs)]].reshape(-1, 2)
