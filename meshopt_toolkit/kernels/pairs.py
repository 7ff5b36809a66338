"""Boundary vertex–edge pairs and the per-pair edge frame (kernels of the boundary term).

A pair is a row ``[i0, j0, j1]``: boundary vertex ``i0`` and a boundary edge ``[j0, j1]``
not incident to it. :func:`boundary_pairs` lists them (all, or those closer than a radius,
by a k-d tree), :func:`iter_boundary_pairs` in chunks; :func:`segment_distance` and
:func:`vertex_edge_distance` (4.13, B.1) evaluate the Euclidean and the 1-norm distance.
Pairs are processed in cache-sized blocks in the edge frame of each pair (tangent ``t``,
normal ``n``, the vertex at ``(x̃, ỹ)``): the regularized distance D^μ of
:mod:`.distance` uses the same frame.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import numpy as np
from scipy.spatial import cKDTree

from .._options import require_at_least
from .._typing import FloatArray, IntArray
from ..errors import NotAdmissibleError

__all__ = ["boundary_pairs", "iter_boundary_pairs", "segment_distance", "vertex_edge_distance"]


# --------------------------------------------------------------------------- pairs


def _pair_grid(boundary_vertices, boundary_edges) -> tuple[IntArray, IntArray]:
    bv = np.asarray(boundary_vertices, dtype=np.int64).ravel()
    be = np.asarray(boundary_edges, dtype=np.int64).reshape(-1, 2)
    return bv, be


def _range_rows(bv: IntArray, be: IntArray, start: int, stop: int) -> IntArray:
    """Pairs for the flat range ``[start, stop)`` of the edge-major (E, V) grid."""
    V = bv.size
    e_lo, e_hi = start // V, -(-stop // V)
    edges = be[e_lo:e_hi]
    keep = (bv[None, :] != edges[:, :1]) & (bv[None, :] != edges[:, 1:])
    offset = e_lo * V
    if start > offset or stop < e_hi * V:  # partial first/last edge rows
        keep[0, : start - offset] = False
        keep[-1, stop - (e_hi - 1) * V :] = False
    e, v = np.nonzero(keep)
    rows = np.empty((e.size, 3), dtype=np.int64)
    rows[:, 0] = bv[v]
    rows[:, 1:] = edges[e]
    return rows


def _rows(bv: IntArray, be: IntArray, flat: IntArray) -> IntArray:
    """Pairs for flat indices ``e * V + v`` into the edge-major grid, endpoints removed."""
    e, v = np.divmod(flat, bv.size)
    i0 = bv[v]
    j = be[e]
    keep = (i0 != j[:, 0]) & (i0 != j[:, 1])
    return np.column_stack([i0[keep], j[keep]])


def iter_boundary_pairs(
    boundary_vertices, boundary_edges, chunk: int = 1_000_000
) -> Iterator[IntArray]:
    """All boundary pairs in memory-bounded chunks.

    Parameters
    ----------
    boundary_vertices : (V,) int
    boundary_edges : (E, 2) int, directed edges ``[j0, j1]``
    chunk : candidate (edge, vertex) combinations per chunk; each chunk has at most
        ``chunk`` rows (fewer where ``i0`` is an endpoint of the edge).

    Yields
    ------
    (k, 3) int arrays of rows ``[i0, j0, j1]``, edge-major (edges in the given order, then
    vertices in the given order), ``i0 ∉ {j0, j1}``. Their concatenation equals
    ``boundary_pairs(boundary_vertices, boundary_edges)``. Empty chunks are skipped.
    """
    require_at_least("chunk", chunk, 1, error=ValueError)
    bv, be = _pair_grid(boundary_vertices, boundary_edges)
    total = bv.size * be.shape[0]
    for start in range(0, total, chunk):
        rows = _range_rows(bv, be, start, min(start + chunk, total))
        if rows.shape[0]:
            yield rows


def boundary_pairs(
    boundary_vertices,
    boundary_edges,
    points: FloatArray | None = None,
    radius: float | None = None,
) -> IntArray:
    """Boundary (vertex, edge) pairs, optionally only those closer than ``radius``.

    Parameters
    ----------
    boundary_vertices : (V,) int
    boundary_edges : (E, 2) int, directed edges ``[j0, j1]`` (``mesh.boundary_edges``)
    points : (N, 2) float, required when ``radius`` is given
    radius : keep pairs whose Euclidean vertex–segment distance is ``< radius``. Since
        the Euclidean distance is ``≤ D`` (4.13), this finds every pair with ``D < radius``.

    Returns
    -------
    (K, 3) int array of rows ``[i0, j0, j1]`` with ``i0 ∉ {j0, j1}``, edge-major: edges in
    the given order, and for each edge the vertices in the given order. With a radius,
    the rows are the same subset, in the same order, as filtering all pairs.

    Notes
    -----
    Broad phase: a cKDTree of the boundary vertices queried at each edge midpoint with
    radius ``radius + L/2`` (a vertex within ``radius`` of the segment is within that of
    its midpoint); then the exact vectorized point–segment filter.
    """
    bv, be = _pair_grid(boundary_vertices, boundary_edges)
    if radius is None:
        if bv.size == 0:
            return np.empty((0, 3), dtype=np.int64)
        return _range_rows(bv, be, 0, bv.size * be.shape[0])
    if points is None:
        raise ValueError("boundary_pairs: a radius needs the points")
    radius = float(radius)
    if not radius > 0 or bv.size == 0 or be.shape[0] == 0:
        return np.empty((0, 3), dtype=np.int64)
    pts = np.asarray(points, dtype=float)[:, :2]
    a, b = pts[be[:, 0]], pts[be[:, 1]]
    half = 0.5 * np.hypot(*(b - a).T)
    tree = cKDTree(pts[bv])
    # cKDTree's ball query returns one list per edge; flatten them at C speed.
    hits = tree.query_ball_point(0.5 * (a + b), radius + half * (1 + 1e-12))
    counts = np.fromiter(map(len, hits), dtype=np.int64, count=len(hits))
    total = int(counts.sum())
    if total == 0:
        return np.empty((0, 3), dtype=np.int64)
    v = np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64, count=total)
    e = np.repeat(np.arange(be.shape[0], dtype=np.int64), counts)
    flat = np.sort(e * bv.size + v)
    rows = _rows(bv, be, flat)
    return rows[segment_distance(pts, rows) < radius]


# --------------------------------------------------------------------------- frames

_BLOCK = 16384
"""Pairs per internal block: the per-pair temporaries of a block stay in cache, which is
several times faster than whole-array numpy on millions of pairs (benchmarks/)."""


def _inputs(points: FloatArray, pairs: IntArray) -> tuple[np.ndarray, IntArray]:
    """Validate; return the points as complex numbers ``x + iy`` ``(N,)`` and the pairs."""
    pts = np.asarray(points, dtype=float)
    pairs = np.asarray(pairs)
    if pairs.ndim != 2 or pairs.shape[1] != 3:
        raise ValueError(f"pairs must have shape (K, 3), got {pairs.shape}")
    if pts.ndim != 2 or pts.shape[1] < 2:
        raise ValueError(f"points must have shape (N, 2), got {pts.shape}")
    return _as_complex(pts), pairs


def _as_complex(pts: FloatArray) -> np.ndarray:
    return np.ascontiguousarray(pts[:, :2]).view(np.complex128).ravel()


def _blocks(K: int) -> Iterator[slice]:
    for start in range(0, K, _BLOCK):
        yield slice(start, min(start + _BLOCK, K))


def _frame(Z: np.ndarray, pairs: IntArray):
    """Edge frame for a block of pairs (all ``(k,)`` real arrays).

    The complex points are gathered (one 16-byte load per vertex) and split into real
    parts; returns the unit tangent ``(tx, ty)`` (the normal is ``(−ty, tx)``), ``L``,
    ``x̃`` and ``ỹ``.
    """
    j0 = pairs[:, 1]
    a = Z[j0]
    e = Z[pairs[:, 2]] - a
    w = Z[pairs[:, 0]] - a
    ex, ey = e.real, e.imag
    L = np.sqrt(ex * ex + ey * ey)
    if L.size and not (L.min() > 0):
        k = int(np.argmin(np.where(np.isnan(L), -1.0, L)))
        raise NotAdmissibleError(
            f"boundary edge [{j0[k]}, {pairs[k, 2]}] has length {L[k]}: "
            "vertex–edge distance undefined"
        )
    inv_L = 1.0 / L
    tx, ty = ex * inv_L, ey * inv_L
    wx, wy = w.real, w.imag
    return tx, ty, L, wx * tx + wy * ty, wy * tx - wx * ty


def _map_blocks(kernel, points: FloatArray, pairs: IntArray) -> FloatArray:
    """``(K,)`` output of ``kernel(L, x̃, ỹ)`` evaluated block by block."""
    Z, pairs = _inputs(points, pairs)
    out = np.empty(pairs.shape[0])
    for blk in _blocks(pairs.shape[0]):
        _, _, L, xt, yt = _frame(Z, pairs[blk])
        out[blk] = kernel(L, xt, yt)
    return out


def segment_distance(points: FloatArray, pairs: IntArray) -> FloatArray:
    """Euclidean distance from ``q_i0`` to the segment ``[q_j0, q_j1]``, shape ``(K,)``.

    Always ``≤ vertex_edge_distance`` (the 2-norm is at most the 1-norm).
    """
    return _map_blocks(lambda L, xt, yt: np.hypot(xt - np.clip(xt, 0.0, L), yt), points, pairs)


def vertex_edge_distance(points: FloatArray, pairs: IntArray) -> FloatArray:
    """Exact 1-norm vertex–edge distance ``D(i0; [j0, j1])`` (4.13, B.1).

    Parameters
    ----------
    points : (N, 2) float
    pairs : (K, 3) int rows ``[i0, j0, j1]``

    Returns
    -------
    (K,) float ``g(x̃; [0, L]) + |ỹ|``.
    """

    def kernel(L, xt, yt):
        return np.maximum(np.maximum(-xt, xt - L), 0.0) + np.abs(yt)

    return _map_blocks(kernel, points, pairs)
