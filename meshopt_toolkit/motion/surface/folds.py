"""The fold test of a triangle surface in R³ against its rest shape (:class:`FoldTest`):
a triangle folds when its normal turns against its rest normal carried by the best rotation
of its neighbourhood (:func:`best_rotations`, batched Kabsch). The handles' paths and the
similarities they follow live in :mod:`..engine.similarity`.
"""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray, IntArray


def best_rotations(S: FloatArray) -> FloatArray:
    """Rotations R (det +1) maximizing tr(R S) for covariances ``S = Σ e eᵀ'`` (T, 3, 3).

    With ``S = U Σ Vᵀ`` (σ_a ≥ σ_b ≥ σ_c) the optimum maps ``u_a ↦ v_a``, ``u_b ↦ v_b`` and,
    being a rotation, ``u_a × u_b ↦ v_a × v_b`` (Kabsch's ``V diag(1, 1, ±1) Uᵀ`` without the
    determinant). ``v_a, v_b`` are the top eigenvectors of the symmetric ``SᵀS`` (one
    batched ``eigh``, faster than the SVD), ``u_a, u_b`` the normalized ``S v_a`` and ``S v_b``
    (Gram–Schmidt), so ``σ_c`` may vanish (coplanar rest edges). Where ``σ_b = 0`` the
    optimum is not unique and ``u_b`` is completed to any unit vector normal to ``u_a``.
    """
    _, W = np.linalg.eigh(np.swapaxes(S, 1, 2) @ S)  # ascending eigenvalues
    va, vb = W[:, :, 2], W[:, :, 1]
    ua = _unit(np.einsum("tij,tj->ti", S, va), np.eye(3)[0])
    ub = np.einsum("tij,tj->ti", S, vb)
    ub -= np.einsum("ti,ti->t", ua, ub)[:, None] * ua
    # where S has rank ≤ 1: any unit vector normal to u_a (the axis of u_a's least component)
    fallback = np.cross(ua, np.eye(3)[np.argmin(np.abs(ua), axis=1)])
    ub = _unit(ub, fallback, scale=np.linalg.norm(S.reshape(len(S), 9), axis=1))
    return (va[:, :, None] * ua[:, None, :] + vb[:, :, None] * ub[:, None, :]
            + np.cross(va, vb)[:, :, None] * np.cross(ua, ub)[:, None, :])


def _unit(x: FloatArray, fallback: FloatArray, scale: FloatArray | None = None) -> FloatArray:
    """Rows of ``x`` normalized; those of norm ≤ 1e-12·scale (or 0) replaced by ``fallback``
    (normalized)."""
    n = np.linalg.norm(x, axis=1)
    tiny = n <= (0.0 if scale is None else 1e-12 * scale)
    if np.any(tiny):
        fb = np.broadcast_to(fallback, x.shape)[tiny]
        x = x.copy()
        x[tiny] = fb
        n = n.copy()
        n[tiny] = np.linalg.norm(fb, axis=1)
    return x / n[:, None]


class FoldTest:
    """Triangle t folds when its normal turns against its rest normal carried by the best
    rotation of its neighbourhood, ``n_t' · (R_t n_t) < 0``; ``R_t`` the Kabsch rotation of
    the rest edge vectors of the one-ring fans of t's corners onto their new ones."""

    def __init__(self, rest: FloatArray, triangles: IntArray) -> None:
        self.rest = np.asarray(rest, float)
        self.triangles = np.asarray(triangles)
        F = self.triangles
        E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        E = np.sort(E, axis=1)
        n = len(self.rest)
        key = np.unique(E[:, 0] * n + E[:, 1])  # each edge once, as one integer key
        self.edges = np.stack(np.divmod(key, n), axis=1)
        self.rest_edges = self.rest[self.edges[:, 1]] - self.rest[self.edges[:, 0]]
        P = self.rest[F]
        self.rest_normals = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])

    def vertex_covariances(self, A: FloatArray, B: FloatArray) -> FloatArray:
        """``Σ a bᵀ`` over the edges at each vertex, ``a`` the edge vector in ``A`` and ``b``
        in ``B`` (N, 9); ``A = None``: the rest shape's."""
        a = self.rest_edges if A is None else A[self.edges[:, 1]] - A[self.edges[:, 0]]
        b = B[self.edges[:, 1]] - B[self.edges[:, 0]]
        outer = (a[:, :, None] * b[:, None, :]).reshape(-1, 9)
        n = len(B)
        return np.stack([np.bincount(self.edges[:, 0], outer[:, c], n)
                         + np.bincount(self.edges[:, 1], outer[:, c], n) for c in range(9)], 1)

    def vertex_rotations(self, A: FloatArray, B: FloatArray) -> FloatArray:
        """The Kabsch rotations (N, 3, 3) of each vertex's edge vectors in ``A`` onto
        those in ``B``."""
        return best_rotations(self.vertex_covariances(A, B).reshape(-1, 3, 3))

    def mask(self, Q: FloatArray) -> np.ndarray:
        """Folded triangles of ``Q`` (T,) bool."""
        Sv = self.vertex_covariances(None, Q)
        R = best_rotations(Sv[self.triangles].sum(axis=1).reshape(-1, 3, 3))
        carried = np.einsum("tij,tj->ti", R, self.rest_normals)
        P = Q[self.triangles]
        normals = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        return np.einsum("ti,ti->t", normals, carried) < 0
