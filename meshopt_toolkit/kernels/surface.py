"""Measures of triangles in 3D (surface meshes), vectorized over all triangles.

Every function takes node positions ``points (N, 3)`` and triangles ``(T, 3)`` and returns
one value (or vector) per triangle. Edge lengths are those of
:func:`~meshopt_toolkit.kernels.triangles.edge_lengths` (it works in any dimension); the
aspect ratio is the planar one, ``2r/R = 8 A² / (s E0 E1 E2)``, with the unsigned area of
the triangle in space.
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from .triangles import edge_lengths

#: a triangle whose aspect ratio 2r/R is at most this is degenerate (scale invariant)
DEGENERATE_ASPECT = 1e-12


def area_vectors(points: FloatArray, triangles: IntArray) -> FloatArray:
    """``(q1 − q0) × (q2 − q0)``: normal by the right-hand rule, length = twice the area.
    Returns ``(T, 3)``."""
    pts = np.asarray(points, dtype=np.float64)
    p = pts[np.ascontiguousarray(np.asarray(triangles, dtype=np.int64).T)]
    return np.cross(p[1] - p[0], p[2] - p[0])


def areas(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Areas (≥ 0) of triangles in space. Returns ``(T,)``."""
    return 0.5 * np.linalg.norm(area_vectors(points, triangles), axis=1)


def unit_normals(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Unit normals by the right-hand rule; zero rows for zero-area triangles. ``(T, 3)``."""
    n = area_vectors(points, triangles)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(length > 0, n / length, 0.0)


def aspect_ratios(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Aspect ratio ``2r/R = 8 A² / (s E0 E1 E2)`` in [0, 1]; 1 iff equilateral, 0 when
    degenerate (the definition of :func:`~meshopt_toolkit.kernels.triangles.aspect_ratios`,
    unsigned: a triangle in space has no orientation of its own). Returns ``(T,)``."""
    lengths = edge_lengths(np.asarray(points, dtype=np.float64), np.asarray(triangles))
    area = areas(points, triangles)
    s = 0.5 * lengths.sum(axis=1)
    prod = lengths.prod(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = 8.0 * area * area / (s * prod)
    return np.where(prod > 0, ratio, 0.0)


def degenerate_triangles(points: FloatArray, triangles: IntArray,
                         tol: float = DEGENERATE_ASPECT) -> IntArray:
    """Indices of degenerate triangles: a repeated vertex index, or aspect ratio ≤ ``tol``
    (zero area, or collinear corners up to rounding). Returns sorted ``(K,)`` indices."""
    tri = np.asarray(triangles)
    repeated = (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2])
    return np.flatnonzero(repeated | (aspect_ratios(points, tri) <= tol))
