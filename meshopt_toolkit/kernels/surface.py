"""Measures of triangles in 3D (surface meshes), vectorized over all triangles.

Every function takes node positions ``points (N, 3)`` and triangles ``(T, 3)`` and returns
one value (or vector) per triangle, each triangle measured at a power of two of its own
size (no overflow or underflow at 1e±300, ratios the same at every scale); the
aspect ratio is the planar one, ``2r/R = 8 A² / (s E0 E1 E2)``, with the unsigned area of
the triangle in space.
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..scaling import unit_cells

#: a triangle whose aspect ratio 2r/R is at most this is degenerate (scale invariant)
DEGENERATE_ASPECT = 1e-12


def pad3(points: FloatArray) -> FloatArray:
    """``(N, 3)`` float64 points: 2D points ``(N, 2)`` with z = 0 added, 3D ones as they
    are (not copied when already contiguous float64)."""
    p = np.asarray(points, dtype=np.float64)
    if p.shape[1] == 3:
        return np.ascontiguousarray(p)
    return np.column_stack([p, np.zeros(len(p))])


def _unit_edges(points: FloatArray, triangles: IntArray, count: int = 3
                ) -> tuple[FloatArray, IntArray]:
    """The first ``count`` of the edges ``q1 − q0, q2 − q0, q2 − q1`` ``(count, T, 3)`` of
    each triangle divided by a power of two of its size
    (:func:`~meshopt_toolkit.scaling.unit_cells`), and the exponents ``(T,)``: the
    measures formed from them neither overflow nor underflow at 1e±300."""
    pts = np.asarray(points, dtype=np.float64)
    p = pts[np.ascontiguousarray(np.asarray(triangles, dtype=np.int64).T)]
    edges = p[1:] - p[0] if count == 2 else np.stack([p[1] - p[0], p[2] - p[0], p[2] - p[1]])
    return unit_cells(edges, axis=1)


def area_vectors(points: FloatArray, triangles: IntArray) -> FloatArray:
    """``(q1 − q0) × (q2 − q0)``: normal by the right-hand rule, length = twice the area.
    Returns ``(T, 3)``."""
    d, e = _unit_edges(points, triangles, 2)
    with np.errstate(over="ignore", under="ignore"):
        return np.ldexp(np.cross(d[0], d[1]), 2 * e[:, None])


def areas(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Areas (≥ 0) of triangles in space. Returns ``(T,)``."""
    d, e = _unit_edges(points, triangles, 2)
    with np.errstate(over="ignore", under="ignore"):
        return np.ldexp(0.5 * np.linalg.norm(np.cross(d[0], d[1]), axis=1), 2 * e)


def unit_normals(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Unit normals by the right-hand rule; zero rows for zero-area triangles. ``(T, 3)``."""
    d, _ = _unit_edges(points, triangles, 2)
    n = np.cross(d[0], d[1])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(length > 0, n / length, 0.0)


def aspect_ratios(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Aspect ratio ``2r/R = 8 A² / (s E0 E1 E2)`` in [0, 1]; 1 iff equilateral, 0 when
    degenerate (the definition of :func:`~meshopt_toolkit.kernels.triangles.aspect_ratios`,
    unsigned: a triangle in space has no orientation of its own); each triangle measured
    at a power of two of its own size, so the same number at every scale. Returns ``(T,)``."""
    d, _ = _unit_edges(points, triangles)
    lengths = np.sqrt(np.einsum("ltk,ltk->tl", d[::-1], d[::-1]))  # opposite q0, q1, q2
    area = 0.5 * np.linalg.norm(np.cross(d[0], d[1]), axis=1)
    s = 0.5 * lengths.sum(axis=1)
    prod = lengths.prod(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = 8.0 * area * area / (s * prod)
    return np.where(prod > 0, ratio, 0.0)


def degenerate_triangles(points: FloatArray, triangles: IntArray,
                         tolerance: float = DEGENERATE_ASPECT) -> IntArray:
    """Indices of degenerate triangles: a repeated vertex index, or aspect ratio ≤
    ``tolerance`` (zero area, or collinear corners up to rounding). Returns sorted ``(K,)``
    indices."""
    tri = np.asarray(triangles)
    repeated = (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2])
    return np.flatnonzero(repeated | (aspect_ratios(points, tri) <= tolerance))
