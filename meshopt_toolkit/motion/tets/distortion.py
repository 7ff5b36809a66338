"""Per-tetrahedron distortion: the barrier vector of the graph metric of tet meshes.

Each tet ``c`` of the current mesh is the image of its reference tet under an affine map
with linear part ``A`` (3×3, :mod:`..kernels.cell_maps`); ``C = AᵀA`` is its Cauchy–Green
tensor and ``Ĉ = C / det(C)^{1/3}`` the unimodular (shape) part. The distortion is

    φ_c = ( log det A / √3,  vec(Φ) / 2 ),   Φ = (Ĉ − Ĉ⁻¹)/2 = sinh(log Ĉ),

a vector in R⁷ (``vec`` the orthonormal coordinates of symmetric 3×3 matrices: the three
diagonal entries, then √2 × the entries 01, 02, 12). It is the d = 3 case of the planar
``TriangleDistortion`` (:mod:`..planar.distortion`, d = 2, where ``(Ĉ − Ĉ⁻¹)/2`` is the traceless part
of ``Ĉ`` and ``vec(Φ)/2`` is ``2μ/(1 − |μ|²)/√2`` up to a fixed isometry).

``φ`` depends on ``C`` only (rotations and translations of the current mesh do not move
it); a uniform scaling by ``s`` adds ``√3 log s`` to the first component of every tet and
nothing else (so a similarity can be factored out of a motion as in :mod:`..engine.similarity`);
``φ = 0`` at the reference; ``|φ| → ∞`` when a tet degenerates (``det A → 0`` or the
shape part's extreme eigenvalue to 0 or ∞); ``+inf`` where inverted.

Bounds (docs/theory-3d.md): ``|dφ| ≥ ½‖C^{-½} dC C^{-½}‖_F``, so along any path the map
``B`` from a tet's start to its end has Hencky strain ``‖log σ(B)‖ ≤`` the tet's φ-length
``≤ ℓ/w`` (:func:`tet_path_quality_bound`); from the reference, ``log κ(A) ≤
asinh(√2 |φ|)`` and ``2 log σ₁(A) − ⅔ log det A ≤ asinh(2|φ|)`` (:func:`tet_quality_bound`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...errors import InvalidMeshError
from ...kernels.cell_maps import (REGULAR_TET_EDGES, affine_maps, barycentric_gradients,
                                  block_jacobian, coordinate_columns, space_cells)

SQRT2 = np.sqrt(2.0)
SQRT3 = np.sqrt(3.0)
#: the symmetric-matrix entries of vec and their weights (orthonormal coordinates)
SYM_I = np.array([0, 1, 2, 0, 0, 1])
SYM_J = np.array([0, 1, 2, 1, 2, 2])
SYM_W = np.array([1.0, 1.0, 1.0, SQRT2, SQRT2, SQRT2])


def sym_vec(S: FloatArray) -> FloatArray:
    """Orthonormal coordinates (…, 6) of symmetric matrices (…, 3, 3)."""
    return S[..., SYM_I, SYM_J] * SYM_W


def sym_unvec(v: FloatArray) -> FloatArray:
    """The symmetric matrices (…, 3, 3) of :func:`sym_vec` coordinates (…, 6)."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., SYM_I, SYM_J] = v / SYM_W
    out[..., SYM_J, SYM_I] = v / SYM_W
    return out


def _mm(X: FloatArray, Y: FloatArray) -> FloatArray:
    """Products of 3×3 matrices stored tets last, (3, 3, C)."""
    return (X[:, :, None] * Y[None, :, :]).sum(axis=1)


class TetDistortion:
    """The per-tet distortion ``φ(Q)`` (shape ``(C, 7)``) relative to a reference: the
    :class:`~meshopt_toolkit.cells.base.CellDistortion` of ``(reference, tets)``, reference
    (N, 3).

    Raises
    ------
    InvalidMeshError
        When a reference tet is not positively oriented.
    """

    n_components = 7

    def __init__(self, reference: FloatArray, tets: IntArray) -> None:
        self.reference, self.tets = space_cells(reference, tets, 4, "a tet distortion")
        self.n_vertices = len(self.reference)
        p = self.reference[self.tets]
        vol = np.linalg.det(np.swapaxes(p[:, 1:] - p[:, :1], 1, 2))
        if not (vol > 0).all():
            bad = int(np.flatnonzero(~(vol > 0))[0])
            raise InvalidMeshError(f"reference tet {bad} is not positively oriented")
        self.gradients = barycentric_gradients(p)  # (C, 4, 3)

    @classmethod
    def regular(cls, points: FloatArray, tets: IntArray) -> TetDistortion:
        """Distortion from regular tets of the same volumes as ``points``' ones: its shape
        part measures absolute quality, ``η_c(Q) ≥ exp(−asinh(2|φ_c(Q)|))``
        (:func:`tet_quality_bound` with ``η = 1`` at the reference)."""
        points, tets = np.asarray(points, float), np.asarray(tets)
        p = points[tets]
        vol = np.abs(np.linalg.det(np.swapaxes(p[:, 1:] - p[:, :1], 1, 2))) / 6.0
        side = np.cbrt(6.0 * np.sqrt(2.0) * vol)  # a regular tet of edge s has V = s³/(6√2)
        unit = np.vstack([np.zeros(3), REGULAR_TET_EDGES.T])
        soup = np.arange(4 * len(tets)).reshape(-1, 4)
        out = cls((side[:, None, None] * unit).reshape(-1, 3), soup)
        out.reference, out.tets, out.n_vertices = points, tets, len(points)
        return out

    def affine_maps(self, Q: FloatArray) -> FloatArray:
        """Linear parts ``A`` (C, 3, 3) of the maps from the reference tets to ``Q``'s."""
        return affine_maps(Q, self.tets, self.gradients)

    def determinants(self, Q: FloatArray) -> FloatArray:
        """``det A`` = current / reference volume; > 0 iff not inverted."""
        return np.linalg.det(self.affine_maps(Q))

    def values(self, Q: FloatArray) -> FloatArray:
        """``φ(Q)``, shape (C, 7); rows of an inverted or degenerate tet are ``+inf``."""
        return self._evaluate(Q, jacobian=False)[0]

    def values_and_jacobian(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``φ(Q)`` (C, 7) and the per-tet Jacobian blocks (C, 7, 12).

        Block ``[c, i, 3j + d]`` is ``∂φ_ci / ∂Q[tets[c, j], d]`` (zero where inverted).
        """
        return self._evaluate(Q, jacobian=True)

    def _parts(self, Q: FloatArray):
        """``A``, ``K = A⁻¹`` (rows: cross products of ``A``'s columns over ``det A``),
        ``log det A``, ``det(A)^{-2/3}`` and the inverted rows (``A = I`` there)."""
        A = self.affine_maps(Q)
        cof = np.stack([np.cross(A[:, :, 1], A[:, :, 2]), np.cross(A[:, :, 2], A[:, :, 0]),
                        np.cross(A[:, :, 0], A[:, :, 1])], axis=1)
        det = np.einsum("ti,ti->t", cof[:, 0], A[:, :, 0])
        bad = ~(det > 0) | ~np.isfinite(det)
        A = np.where(bad[:, None, None], np.eye(3), A)
        det = np.where(bad, 1.0, det)
        K = np.where(bad[:, None, None], np.eye(3), cof / det[:, None, None])
        ld = np.log(det)
        m = np.exp(-2.0 * ld / 3.0)  # det(C)^{-1/3}
        return A, K, ld, m, bad

    def _evaluate(self, Q: FloatArray, jacobian: bool):
        A, K, ld, m, bad = self._parts(Q)
        C = np.matmul(np.swapaxes(A, 1, 2), A)
        Y = np.matmul(K, np.swapaxes(K, 1, 2))  # C⁻¹
        n = 1.0 / m
        Phi = 0.5 * (m[:, None, None] * C - n[:, None, None] * Y)
        phi = np.empty((len(A), 7))
        phi[:, 0] = ld / SQRT3
        phi[:, 1:] = 0.5 * sym_vec(Phi)
        phi[bad] = np.inf
        if not jacobian:
            return phi, None
        last = [np.ascontiguousarray(np.moveaxis(X, 0, -1)) for X in (A, K, C, Y)]
        return phi, self._to_corners(self._map_derivative(*last, m, n, bad))

    @staticmethod
    def _map_derivative(A, K, C, Y, m, n, bad) -> FloatArray:
        """``∂φ_ci/∂A_ab`` per tet, tets last: (7, 3, 3, C) from ``A``, ``K = A⁻¹``,
        ``C = AᵀA``, ``Y = C⁻¹`` (3, 3, C). With ``δ = tr(K dA) = K_ba``,
        ``dĈ = m(dAᵀA + AᵀdA − ⅔δC)`` and ``d(Ĉ⁻¹) = −n(K dA Y + Y dAᵀKᵀ − ⅔δY)``, so entry
        ``(i, k)`` of ``4 dΦ/W_ik`` is ``m(δ_ib A_ak + A_ai δ_kb) + n(K_ia Y_bk + Y_ib K_ka)
        − ⅔ K_ba (mC + nY)_ik``. (Tets last: every numpy loop runs over the tets.)"""
        i, k, s = SYM_I, SYM_J, np.arange(6)
        D = np.empty((7, 3, 3, A.shape[-1]))
        Kt = np.swapaxes(K, 0, 1)
        D[0] = Kt / SQRT3
        S = D[1:]  # [s, a, b]
        mA, nK = m * A, n * K
        np.multiply(nK[i][:, :, None], np.swapaxes(Y[:, k], 0, 1)[:, None], out=S)
        S += nK[k][:, :, None] * Y[i][:, None]
        S -= (2.0 / 3.0) * Kt * (m * C[i, k] + n * Y[i, k])[:, None, None]
        # (the indexed view is (6, 3, C): advanced indices split by a slice go first)
        S[s, :, i] += np.swapaxes(mA[:, k], 0, 1)  # m δ_ib A_ak
        S[s, :, k] += np.swapaxes(mA[:, i], 0, 1)  # m A_ai δ_kb
        S *= (0.25 * SYM_W)[:, None, None, None]
        D[..., bad] = 0.0
        return D

    def _to_corners(self, D: FloatArray) -> FloatArray:
        """Blocks over the corners (C, r, 12), column ``3j + c``, from derivatives in
        ``A`` (r, 3, 3, C): ``A = Σ_j x_j ⊗ γ_j`` gives ``∂/∂x_jc = Σ_b γ_jb ∂/∂A_cb``."""
        G = np.moveaxis(self.gradients, 0, -1)  # (4, 3, C): [j, b]
        out = D[:, None, :, 0] * G[None, :, None, 0]
        out += D[:, None, :, 1] * G[None, :, None, 1]
        out += D[:, None, :, 2] * G[None, :, None, 2]
        return np.ascontiguousarray(np.moveaxis(out.reshape(len(D), 12, -1), -1, 0))

    def second_order(self, Q: FloatArray, rho: FloatArray) -> FloatArray:
        """``Σ_i ρ_ci ∇²φ_ci`` per tet in the coordinates of :meth:`values_and_jacobian`:
        (C, 12, 12), symmetric; the residual-curvature part of a Hessian ``JᵀJ + Σ r ∇²r``.

        With ``R`` the symmetric matrix of ``ρ_c[1:]`` (``⟨ρ[1:], vec Φ⟩ = ⟨R, Φ⟩``),
        ``ρ·φ = (ρ_0/√3) log det A + ¼(m q − n p)`` where ``m = det^{-2/3}``, ``n = 1/m``,
        ``q = ⟨R, AᵀA⟩``, ``p = ⟨R, A⁻¹A⁻ᵀ⟩``; in the entries of ``A`` (``P = ab``,
        ``Q = ce``, ``K = A⁻¹``, ``δ_P = K_ba``, ``T_PQ = K_ea K_bc``, ``W = KKᵀRK``,
        ``Z = KᵀRK``):

            ∇²log det = −T,   ∇²q = 2 δ_ac R_eb,   ∇q = 2 AR,   ∇p_P = −2 W_ba,
            ∇²p = 2 (K_bc W_ea + K_ea W_bc + Z_ca (KKᵀ)_be),
            ∇m = −⅔ m δ,  ∇²m = m (4/9 δδᵀ + ⅔ T),  ∇n = ⅔ n δ,  ∇²n = n (4/9 δδᵀ − ⅔ T),

        then ``∇²_Q = Gᵀ ∇²_A G`` (``A`` is linear in ``Q``).

        Parameters
        ----------
        Q : (N, 3) float array
            Current positions (every tet positively oriented).
        rho : (C, 7) float array
        """
        A, K, _, m, bad = self._parts(Q)
        n = 1.0 / m
        rho = np.asarray(rho, float)
        # tets last (every numpy loop runs over the tets); collected, the terms are
        # H = αT + βδδᵀ − (δuᵀ + uδᵀ)/6 + ½m δ_ac R_eb − ½n ∇²p/2 with α = −ρ₀/√3 +
        # (mq + np)/6, β = (mq − np)/9, u = m∇q + n∇p
        R = np.moveaxis(sym_unvec(rho[:, 1:]), 0, -1)
        A, K = np.moveaxis(A, 0, -1), np.moveaxis(K, 0, -1)
        Kt = np.swapaxes(K, 0, 1)
        Y = _mm(K, Kt)
        RK = _mm(R, K)
        W = _mm(Y, RK)
        Z = _mm(Kt, RK)
        AR = _mm(A, R)
        q = (AR * A).sum(axis=(0, 1))  # ⟨R, AᵀA⟩ = tr(AᵀAR)
        p = (R * Y).sum(axis=(0, 1))
        delta = Kt.reshape(9, -1)  # δ_(ab) = K_ba
        u = 2.0 * m * AR.reshape(9, -1) - 2.0 * n * np.swapaxes(W, 0, 1).reshape(9, -1)
        alpha = -rho[:, 0] / SQRT3 + (m * q + n * p) / 6.0
        beta = (m * q - n * p) / 9.0
        Wt = np.swapaxes(W, 0, 1)
        # [a, b, c, e]: T = K_ea K_bc; ∇²p/2 = K_bc W_ea + K_ea W_bc + Z_ac Y_be
        H = (alpha * Kt[:, None, None, :]) * K[None, :, :, None]
        H -= (0.5 * n * K)[None, :, :, None] * Wt[:, None, None, :]
        H -= Kt[:, None, None, :] * (0.5 * n * W)[None, :, :, None]
        H -= (0.5 * n * Z)[:, None, :, None] * Y[None, :, None, :]
        H = H.reshape(9, 9, -1)
        H += delta[:, None] * (beta * delta - u / 6.0)[None]
        H -= (u / 6.0)[:, None] * delta[None]
        H4 = H.reshape(3, 3, 3, 3, -1)
        for a_ in range(3):
            H4[a_, :, a_] += 0.5 * m * R
        H = np.ascontiguousarray(np.moveaxis(H, -1, 0))
        H[bad] = 0.0
        # Gᵀ H G: [j a, k c] = Σ_{b e} γ_jb H[a b c e] γ_ke, as two batched products
        G = self.gradients
        X = np.matmul(H.reshape(-1, 27, 3), np.swapaxes(G, 1, 2))  # [a b c, k]
        X = np.swapaxes(X.reshape(-1, 3, 3, 12), 1, 2).reshape(-1, 3, 36)  # [b, a c k]
        out = np.matmul(G, X).reshape(-1, 4, 3, 3, 4)  # [j, a, c, k]
        return np.ascontiguousarray(np.swapaxes(out, 3, 4)).reshape(-1, 12, 12)

    def columns(self) -> IntArray:
        """Global coordinate index ``3·vertex + d`` of each block column: (C, 12)."""
        if getattr(self, "_columns_of", None) is not self.tets:  # kept for these tets
            self._columns = coordinate_columns(self.tets, 3)
            self._columns_of = self.tets
        return self._columns

    def jacobian_matrix(self, blocks: FloatArray) -> sp.csr_matrix:
        """Assemble per-tet blocks (C, 7, 12) into the sparse ``J`` (7C × 3N)."""
        return block_jacobian(blocks, self.columns(), 3 * self.n_vertices)

def tet_quality_bound(mean_ratio_reference: FloatArray, change: FloatArray) -> FloatArray:
    """Lower bound of the mean ratio ``η`` of each tet from its reference value and
    ``δ ≥ |φ_c(Q) − φ_c(Q₀)|`` (``Q₀`` the reference, where ``φ = 0``):

        η_c(Q) ≥ η_c(Q₀) · exp(−asinh(2δ)).

    With ``δ = ℓ/w`` (ℓ the path length in ``M + w²JᵀJ``) it bounds every tet by the
    length of the path, whatever the number of tets.
    """
    return np.asarray(mean_ratio_reference) * np.exp(-np.arcsinh(2.0 * np.asarray(change)))


def tet_condition_bound(condition_reference: FloatArray, change: FloatArray) -> FloatArray:
    """Upper bound of the condition number ``κ`` of each tet (the map from the regular
    tet) from its reference value and ``δ ≥ |φ_c(Q) − φ_c(Q₀)|`` (``Q₀`` the reference):
    ``κ_c(Q) ≤ κ_c(Q₀) · exp(asinh(√2 δ))``."""
    return np.asarray(condition_reference) * np.exp(np.arcsinh(SQRT2 * np.asarray(change)))


def tet_path_quality_bound(mean_ratio_start: FloatArray, length: FloatArray) -> FloatArray:
    """Lower bound of the mean ratio at the end of any path that starts anywhere, from the
    start's value and the tet's φ-length ``L`` along the path (``L ≤ ℓ/w``):
    ``η(end) ≥ η(start) · exp(−2√(2/3) L)``."""
    return np.asarray(mean_ratio_start) * np.exp(-2.0 * np.sqrt(2.0 / 3.0) * np.asarray(length))


def tet_path_condition_bound(condition_start: FloatArray, length: FloatArray) -> FloatArray:
    """Upper bound of ``κ`` at the end of any path from the start's value and the tet's
    φ-length ``L`` along the path: ``κ(end) ≤ κ(start) · exp(√2 L)``."""
    return np.asarray(condition_start) * np.exp(SQRT2 * np.asarray(length))


def hencky_strains(A: FloatArray) -> FloatArray:
    """``‖log σ(A)‖₂`` per map (…, 3, 3): the Hencky strain norm ``‖log √(AᵀA)‖_F``."""
    return np.linalg.norm(np.log(np.linalg.svd(A, compute_uv=False)), axis=-1)
