"""The :class:`~.metrics.Metric` protocol of a metric given as an operator and its
assembled matrix: the distortion metrics ``M + w² JᵀJ`` of the plane, of surfaces and of
tetrahedra (``motion.planar.metric``, ``motion.surface.metric``, ``motion.tets.metric``)
share it on ``(N, d)`` points, ``d`` read from the arrays.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._linalg import dot
from .._options import require_shape
from .._typing import FloatArray
from ..solvers import factorize_spd
from .metrics import MetricNotImplementedError, _derivative

__all__ = ["AssembledMetric"]


class AssembledMetric:
    """``inner``, ``norm``, ``riesz`` and ``exp`` of a metric that supplies ``apply(Q, V)``
    (``g_Q V`` for ``V`` (N, d)) and ``matrix(Q)`` (``g_Q`` as a ``(dN, dN)`` sparse matrix,
    dof ``d·i + c`` the component ``c`` of vertex ``i``). Not the Euclidean metric; its
    geodesics are boundary-value problems (discrete geodesics), so ``exp`` raises."""

    #: not the Euclidean metric (the Metric protocol's flag)
    is_flat = False

    def apply(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        raise NotImplementedError

    def matrix(self, Q: FloatArray) -> sp.spmatrix:
        raise NotImplementedError

    def embed(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The isometric embedding ``X(Q)`` in two flat parts, where the metric has one
        (the distortion metrics: ``(m^½ ⊙ Q, w φ(Q))``)."""
        raise MetricNotImplementedError(f"{type(self).__name__}.embed is not implemented")

    def segment_lengths(self, frames: FloatArray) -> FloatArray:
        """``|X(Q_{k+1}) − X(Q_k)|`` for consecutive frames (K+1, N, d) → (K,), ``X`` the
        embedding :meth:`embed`."""
        X = [np.concatenate(self.embed(Q)) for Q in frames]
        return np.array([np.linalg.norm(b - a) for a, b in zip(X[:-1], X[1:])])

    def inner(self, Q: FloatArray, U: FloatArray, V: FloatArray) -> float:
        """``vec U · g_Q vec V``. ``Q, U, V`` : (N, d)."""
        return dot(np.asarray(U, dtype=float), self.apply(Q, np.asarray(V, dtype=float)))

    def norm(self, Q: FloatArray, V: FloatArray) -> float:
        """``sqrt(inner(Q, V, V))``."""
        return float(np.sqrt(max(self.inner(Q, V, V), 0.0)))

    def riesz(self, Q: FloatArray, P: FloatArray, free: np.ndarray | None = None) -> FloatArray:
        """Gradient ``g_Q⁻¹ vec P`` of a derivative ``P`` (N, d); returns (N, d).
        With an (N,) bool mask ``free`` the system is restricted to the free vertices'
        dofs and the fixed rows of the result are 0 (one sparse factorization per call)."""
        A = self.matrix(Q)
        d = np.shape(Q)[1]
        P = _derivative(P, (A.shape[0] // d, d))
        keep = require_shape("free mask", np.ones(P.shape[0], bool) if free is None
                             else np.asarray(free, dtype=bool), (P.shape[0],))
        dof = np.repeat(keep, d)
        out = np.zeros_like(P)
        if dof.any():
            out[keep] = factorize_spd(A[dof][:, dof].tocsc())(P[keep].ravel()).reshape(-1, d)
        return out

    def exp(self, Q: FloatArray, V: FloatArray, time: float = 1.0) -> FloatArray:
        """Not available: this metric's geodesics are boundary-value problems."""
        raise MetricNotImplementedError(
            f"{type(self).__name__}.exp is not implemented: the distortion metric's geodesics "
            "are computed between two meshes, use riemannian.discrete_geodesic(metric, Q0, Q1, "
            "K)")
