"""Inverted triangles after a MeshLab step (a planar mesh that was admissible before).

A MeshLab filter knows nothing of our admissibility: a Laplacian smoothing of a planar
mesh can fold triangles over (negative signed area) and still return normally. The runner
takes the plane normal of the current mesh before each MeshLab step — only when the mesh
is planar and every triangle is positively oriented about it — and counts the triangles
with a negative signed area about that normal after the step.
"""

from __future__ import annotations

import numpy as np

from ..kernels.surface import pad3
from ..orientation import PLANE_RTOL

__all__ = ["admissible_normal", "count_inverted"]


def _normals(points, triangles) -> tuple[np.ndarray, np.ndarray]:
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] not in (2, 3):
        raise ValueError("points must be (N, 2) or (N, 3)")
    P = pad3(P)
    T = np.asarray(triangles, dtype=np.int64)
    a = P[T[:, 0]]
    return P, np.cross(P[T[:, 1]] - a, P[T[:, 2]] - a)


def _on_plane(P: np.ndarray, normal: np.ndarray) -> bool:
    diag = float(np.linalg.norm(P.max(0) - P.min(0))) if len(P) else 0.0
    off = (P - P[0]) @ normal
    return bool(np.all(np.abs(off) <= PLANE_RTOL * max(diag, np.finfo(float).tiny)))


def admissible_normal(points, triangles) -> np.ndarray | None:
    """The unit normal of a planar mesh whose triangles all have positive area about it.

    Returns None for a mesh that is not planar, has no area, or already has an inverted
    or degenerate triangle (nothing to compare against).
    """
    if len(triangles) == 0:
        return None
    P, n = _normals(points, triangles)
    with np.errstate(all="ignore"):
        total = n.sum(0)
        length = float(np.linalg.norm(total))
        if not np.isfinite(length) or length == 0.0:
            return None
        unit = total / length
        if not _on_plane(P, unit) or not np.all(n @ unit > 0.0):
            return None
    return unit


def count_inverted(points, triangles, normal: np.ndarray) -> int | None:
    """Triangles with negative signed area about ``normal``; None if the mesh left the plane."""
    if len(triangles) == 0:
        return 0
    P, n = _normals(points, triangles)
    with np.errstate(all="ignore"):
        if not _on_plane(P, normal):
            return None
        return int(np.count_nonzero(n @ normal < 0.0))
