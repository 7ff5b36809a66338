"""Admissibility kernels of the boundary: does a closed polygon touch itself?

Plain functions of ``points (N, 2)`` and directed ``boundary_edges (E, 2)``.
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = ["boundary_self_intersections"]

#: at most this many boundary edges are intersected pairwise in numpy (no scipy import)
_NUMPY_PAIRS = 600


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

