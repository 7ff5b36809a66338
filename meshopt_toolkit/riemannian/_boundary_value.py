"""Constants and helpers of the boundary-value geodesics (discrete geodesic, log map,
initial paths) of the scalar complete metric."""

from __future__ import annotations


import numpy as np

from .._typing import FloatArray
from ..errors import InvalidMeshError, NotAdmissibleError


#: tolerance of log_map relative to the mesh diameter
DEFAULT_TOL = 1e-8

#: relative tolerance of the exponential maps evaluated by the shooting
SHOOTING_RTOL = 1e-10


def _as_points(Q, what: str, dimension: int = 2) -> FloatArray:
    """The first ``dimension`` columns of the points ``Q`` (or of ``Q.points``)."""
    Q = np.array(getattr(Q, "points", Q), dtype=np.float64)
    if Q.ndim != 2 or Q.shape[1] < dimension:
        raise InvalidMeshError(f"{what} must have shape (N, {dimension}), got {Q.shape}")
    return np.ascontiguousarray(Q[:, :dimension])


def _path_frames(path, Q0: FloatArray, Q1: FloatArray, segments: int) -> FloatArray:
    """The ``segments + 1`` frames of ``path`` as a new float array, its ends set to ``Q0``
    and ``Q1`` (InvalidMeshError for another shape)."""
    frames = np.array(path, dtype=np.float64)
    if frames.shape != (segments + 1,) + Q0.shape:
        raise InvalidMeshError(f"path must have shape {(segments + 1,) + Q0.shape}, "
                               f"got {frames.shape}")
    frames[0], frames[-1] = Q0, Q1
    return frames


def _require_finite(pen, Q: FloatArray, what: str) -> float:
    try:
        f = float(pen.value(Q))
    except ValueError as exc:
        raise InvalidMeshError(f"{what}: {exc}") from None
    if not np.isfinite(f):
        problem = ""
        if hasattr(pen, "_area_problem"):
            problem = pen._area_problem(Q) or pen._boundary_problem(Q) or ""
        raise NotAdmissibleError(
            f"{what} is not admissible for the morph metric" + (f": {problem}" if problem else "")
        )
    return f


class _Counter:
    """Wrap a penalty, counting calls."""

    def __init__(self, pen) -> None:
        self.pen = pen
        self.n = 0

    def value(self, Q):
        self.n += 1
        return float(self.pen.value(Q))

    def value_and_gradient(self, Q):
        self.n += 1
        if hasattr(self.pen, "value_and_gradient"):
            f, g = self.pen.value_and_gradient(Q)
        else:
            f, g = self.pen.value(Q), self.pen.gradient(Q)
        return float(f), np.asarray(g, dtype=np.float64)

    def hvp(self, Q, V):
        self.n += 1
        return np.asarray(self.pen.hvp(Q, V), dtype=np.float64)


def _diameter(Q: FloatArray) -> float:
    return float(np.linalg.norm(Q.max(axis=0) - Q.min(axis=0)))
