"""Per-triangle distortion: the barrier vector of the graph metric.

Each triangle ``t`` of the current mesh is the image of its reference triangle under an
affine map whose linear part ``A_t`` is written in complex form ``A z = α z + β z̄``
(``α = ∂_z f``, ``β = ∂_z̄ f``, both linear in the current node positions). With the
Beltrami coefficient ``μ = β/α`` the singular values of ``A`` are ``σ₁,₂ = |α| ± |β|``,
``κ = σ₁/σ₂ = (1 + |μ|)/(1 − |μ|)``, and

    φ_t = (1/√2) · ( log(σ₁σ₂),  2μ/(1 − |μ|²) ),

a vector in R³ (the second part is a complex number, i.e. two reals) with
``|2μ/(1 − |μ|²)| = (κ − 1/κ)/2 = sinh(log κ)``. ``φ_t`` is invariant under rotations and
translations of the current mesh, a uniform scaling moves only its first component,
``φ_t = 0`` at the reference, and ``|φ_t| → ∞`` when the triangle degenerates (``σ₂ → 0``):
a proper barrier on the non-inverted meshes. Near the reference it agrees with the Hencky
strain ``log U`` to first order; far from it the shape part grows like κ (the Hencky
strain grows like log κ, which lets shear localize in a few triangles: measured, a
least-squares fit of log strains took an annulus twist from min aspect ratio 0.15 to 0.001).

Quality bound. For any linear map the shape quality (5.23) satisfies
``1/ψ(A T) ≤ κ(A) · 1/ψ(T)``, and ``κ = exp(asinh(|F|))`` with ``|F| ≤ √2·|φ_t|``, so for a
mesh ``Q`` and the reference ``Q₀``:
``1/ψ_t(Q) ≤ exp(asinh(√2·|φ_t(Q) − φ_t(Q₀)|)) · 1/ψ_t(Q₀)`` (:func:`shape_quality_bound`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...kernels.cell_maps import block_jacobian, coordinate_columns
from .assembly import UPPER_COLS, UPPER_ROWS

SQRT_HALF = np.sqrt(0.5)


def _complex_points(points: FloatArray) -> np.ndarray:
    return points[:, 0] + 1j * points[:, 1]


def wirtinger_coefficients(reference: FloatArray, triangles: IntArray) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of ``α_t = Σ_j a_tj z_j`` and ``β_t = Σ_j b_tj z_j`` (z = x + iy).

    Parameters
    ----------
    reference : (N, 2) float array
        Reference node positions (counter-clockwise triangles).
    triangles : (T, 3) int array

    Returns
    -------
    a, b : (T, 3) complex arrays
    """
    p = _complex_points(np.asarray(reference, dtype=float))[triangles]
    e1 = p[:, 1] - p[:, 0]
    e2 = p[:, 2] - p[:, 0]
    den = e1 * np.conj(e2) - e2 * np.conj(e1)  # = −4i·(reference area)
    a = np.empty_like(p)
    b = np.empty_like(p)
    a[:, 1] = np.conj(e2) / den
    a[:, 2] = -np.conj(e1) / den
    a[:, 0] = -(a[:, 1] + a[:, 2])
    b[:, 2] = e1 / den
    b[:, 1] = -e2 / den
    b[:, 0] = -(b[:, 1] + b[:, 2])
    return a, b


class TriangleDistortion:
    """The per-triangle distortion ``φ(Q)`` (shape ``(T, 3)``) relative to a reference:
    the :class:`~meshopt_toolkit.cells.base.CellDistortion` of ``(reference, triangles)``,
    reference (N, 2) with counter-clockwise triangles."""

    n_components = 3

    def __init__(self, reference: FloatArray, triangles: IntArray) -> None:
        self.reference = np.asarray(reference, dtype=float)
        self.triangles = np.asarray(triangles)
        self.n_vertices = self.reference.shape[0]
        self._a, self._b = wirtinger_coefficients(self.reference, self.triangles)

    @classmethod
    def equilateral(cls, points: FloatArray, triangles: IntArray) -> TriangleDistortion:
        """Distortion from equilateral triangles of the same areas as ``points``' ones:
        its shape part measures absolute quality, ``|F_t|² = 1/ψ_t² − 1`` (5.23)."""
        p = np.asarray(points, float)[triangles]
        area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                            - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
        side = np.sqrt(4.0 * area / np.sqrt(3.0))
        unit = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3.0) / 2]])
        ref = (side[:, None, None] * unit).reshape(-1, 2)
        out = cls(ref, np.arange(3 * len(triangles)).reshape(-1, 3))
        out.reference = np.asarray(points, float)
        out.triangles = np.asarray(triangles)
        out.n_vertices = len(points)
        return out

    def alpha_beta(self, Q: FloatArray) -> tuple[np.ndarray, np.ndarray]:
        """``α_t, β_t`` (complex, shape (T,)) of the current positions ``Q``."""
        z = _complex_points(Q)[self.triangles]
        return np.einsum("tj,tj->t", self._a, z), np.einsum("tj,tj->t", self._b, z)

    def determinants(self, Q: FloatArray) -> FloatArray:
        """``det A_t = |α|² − |β|²`` = current / reference area; > 0 iff not inverted."""
        al, be = self.alpha_beta(Q)
        return np.abs(al) ** 2 - np.abs(be) ** 2

    def values(self, Q: FloatArray) -> FloatArray:
        """``φ(Q)``, shape (T, 3); ``+inf``-free only where every triangle has det > 0."""
        phi, _ = self._evaluate(Q, jacobian=False)
        return phi

    def values_and_jacobian(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``φ(Q)`` (T, 3) and the per-triangle Jacobian blocks (T, 3, 6).

        Block ``[t, c, 2j + d]`` is ``∂φ_tc / ∂Q[triangles[t, j], d]``.
        """
        return self._evaluate(Q, jacobian=True)

    def _evaluate(self, Q: FloatArray, jacobian: bool):
        al, be = self.alpha_beta(Q)
        det = np.abs(al) ** 2 - np.abs(be) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            mu = be / al
        y = np.abs(mu) ** 2
        bad = ~(det > 0) | ~(y < 1) | ~np.isfinite(det)
        y_safe = np.where(bad, 0.0, y)
        mu_s = np.where(bad, 0.0, mu)
        F = 2.0 * mu_s / (1.0 - y_safe)
        phi = np.empty((al.shape[0], 3))
        with np.errstate(divide="ignore", invalid="ignore"):
            phi[:, 0] = np.log(np.where(bad, np.nan, det))
        phi[:, 1] = F.real
        phi[:, 2] = F.imag
        phi *= SQRT_HALF
        if bad.any():
            phi[bad] = np.inf
        if not jacobian:
            return phi, None
        # d/d(α, β) as 3 × 4 real blocks over (Re α, Im α, Re β, Im β)
        d_ab = np.zeros((al.shape[0], 3, 4))
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_det = np.where(bad, 0.0, 2.0 / det)
            al_s = np.where(bad, 1.0, al)
        d_ab[:, 0, 0] = inv_det * al.real
        d_ab[:, 0, 1] = inv_det * al.imag
        d_ab[:, 0, 2] = -inv_det * be.real
        d_ab[:, 0, 3] = -inv_det * be.imag
        # dF = P dμ + R dμ̄ with P = 2/(1−|μ|²)², R = 2μ²/(1−|μ|²)²;  dμ = (dβ − μ dα)/α
        P = 2.0 / (1.0 - y_safe) ** 2
        R = mu_s**2 * P
        _linear_block(d_ab[:, 1:, 0:2], -P * mu_s / al_s)
        _antilinear_block(d_ab[:, 1:, 0:2], -R * np.conj(mu_s) / np.conj(al_s))
        _linear_block(d_ab[:, 1:, 2:4], P / al_s)
        _antilinear_block(d_ab[:, 1:, 2:4], R / np.conj(al_s))
        d_ab *= SQRT_HALF
        d_ab[bad] = 0.0
        return phi, np.matmul(d_ab, self._ab_blocks)

    def second_order(self, Q: FloatArray, rho: FloatArray, out: FloatArray | None = None
                     ) -> FloatArray:
        """``Σ_c ρ_tc ∇²φ_tc`` per triangle in the coordinates of :meth:`values_and_jacobian`,
        as an upper array (21, T) (:mod:`.assembly`; added to ``out`` when given): the
        residual-curvature part of a Hessian ``JᵀJ + Σ r_i ∇²r_i`` (Newton's term that
        Gauss–Newton leaves out).

        In ``x = (Re α, Im α, Re β, Im β)``: ``φ_0 = s·log d`` and ``φ_1 + iφ_2 = s·N/d``
        with ``d = |α|² − |β|²``, ``N = 2βᾱ`` (``= 2μ/(1 − |μ|²)·d``), ``s = 1/√2``, so with
        ``n = ρ_1 Re N + ρ_2 Im N`` and ``∇N_ρ = ρ_1∇Re N + ρ_2∇Im N``

            Σ_c ρ_c ∇²φ_c = (s/d)·[(ρ_0 − n/d)∇²d + ρ_1∇²Re N + ρ_2∇²Im N]
                            + (s/d²)·[(2n/d − ρ_0)∇d∇dᵀ − ∇N_ρ∇dᵀ − ∇d∇N_ρᵀ]

        (``∇²d = 2·diag(1, 1, −1, −1)``; ``∇²Re N``, ``∇²Im N`` constant). ``x`` is linear in
        the vertices, ``α = Σ_j a_j z_j``, ``β = Σ_j b_j z_j``: the first bracket maps to the
        2×2 blocks ``R(Z_jk)`` of the complex Hermitian ``Z = 2(s/d)[ā ⊗ (c a + ρ̄ b) +
        b̄ ⊗ (ρ a − c b)]`` (``c = ρ_0 − n/d``, ``ρ = ρ_1 + iρ_2``, ``R(z)`` the real matrix
        of ``w ↦ zw``), the gradients to ``∇_{z_j} d = 2 conj(ᾱa_j − β̄b_j)`` and
        ``∇_{z_j} Re(ρ̄N) = 2 conj(ρ̄ᾱb_j + ρβ̄a_j)``.

        Parameters
        ----------
        Q : (N, 2) float array
            Current positions (every triangle non-inverted).
        rho : (T, 3) float array
            Weights of the components.
        out : (21, T) float array, optional
        """
        al, be = self.alpha_beta(Q)
        a, b = self._coefficients_by_corner  # (3, T)
        d = np.abs(al) ** 2 - np.abs(be) ** 2
        rho_c = rho[:, 1] + 1j * rho[:, 2]
        n = 2 * (np.conj(rho_c) * be * np.conj(al)).real
        s_d = SQRT_HALF / d
        c = rho[:, 0] - n / d
        left_a = 2 * s_d * np.conj(a)  # Z_jk = left_a_j·x_k + left_b_j·y_k
        left_b = 2 * s_d * np.conj(b)
        x, y = c * a + np.conj(rho_c) * b, rho_c * a - c * b
        # the rank-two bracket: gradients in (x_j, y_j) = (Re, −Im) of 2·(…)_j
        u = _real_pairs(2 * (np.conj(al) * a - np.conj(be) * b))  # (6, T)
        v = _real_pairs(2 * (np.conj(rho_c) * np.conj(al) * b + rho_c * np.conj(be) * a))
        scale = s_d / d
        f = scale * ((2 * n / d - rho[:, 0]) * u - v)
        g = scale * u
        if out is None:
            out = np.zeros((len(UPPER_ROWS), len(d)))
        zs = {}
        for row, (i, j) in enumerate(zip(UPPER_ROWS, UPPER_COLS)):
            z = zs.get((i // 2, j // 2))
            if z is None:
                z = zs[i // 2, j // 2] = left_a[i // 2] * x[j // 2] + left_b[i // 2] * y[j // 2]
            p, q = i % 2, j % 2  # R(z) = [[Re z, −Im z], [Im z, Re z]]
            entry = z.real if p == q else (z.imag if p else -z.imag)
            out[row] += entry + f[i] * u[j] - g[i] * v[j]
        return out

    @property
    def _coefficients_by_corner(self) -> tuple[np.ndarray, np.ndarray]:
        """``a, b`` as contiguous (3, T) arrays (each corner's coefficients of all
        triangles together), kept."""
        kept = getattr(self, "_by_corner", None)
        if kept is None:
            kept = self._by_corner = (np.ascontiguousarray(self._a.T),
                                      np.ascontiguousarray(self._b.T))
        return kept

    @property
    def _ab_blocks(self) -> FloatArray:
        """(T, 4, 6): ∂(Re α, Im α, Re β, Im β)/∂(x0, y0, x1, y1, x2, y2), constant."""
        blocks = getattr(self, "_ab_cache", None)
        if blocks is None:
            blocks = np.zeros((self.triangles.shape[0], 4, 6))
            for row, c in ((0, self._a), (2, self._b)):
                blocks[:, row, 0::2] = c.real       # ∂Re/∂x_j
                blocks[:, row + 1, 0::2] = c.imag   # ∂Im/∂x_j
                blocks[:, row, 1::2] = -c.imag      # ∂Re/∂y_j
                blocks[:, row + 1, 1::2] = c.real   # ∂Im/∂y_j
            self._ab_cache = blocks
        return blocks

    def jacobian_matrix(self, blocks: FloatArray) -> sp.csr_matrix:
        """Assemble per-triangle blocks (T, 3, 6) into the sparse ``J`` (3T × 2N)."""
        return block_jacobian(blocks, coordinate_columns(self.triangles, 2), 2 * self.n_vertices)

def _real_pairs(w: np.ndarray) -> FloatArray:
    """(3, T) complex ``w_j`` → (6, T) ``(Re w_0, −Im w_0, Re w_1, …)``: the real gradient
    in ``(x_j, y_j)`` of ``Re Σ_j w_j z_j``."""
    out = np.empty((2 * w.shape[0],) + w.shape[1:])
    out[0::2] = w.real
    out[1::2] = -w.imag
    return out


def _linear_block(out: FloatArray, c: np.ndarray) -> None:
    """Add the real 2×2 matrix of ``w ↦ c·w`` to ``out`` (..., 2, 2)."""
    out[:, 0, 0] += c.real
    out[:, 0, 1] -= c.imag
    out[:, 1, 0] += c.imag
    out[:, 1, 1] += c.real


def _antilinear_block(out: FloatArray, c: np.ndarray) -> None:
    """Add the real 2×2 matrix of ``w ↦ c·w̄`` to ``out`` (..., 2, 2)."""
    out[:, 0, 0] += c.real
    out[:, 0, 1] += c.imag
    out[:, 1, 0] += c.imag
    out[:, 1, 1] -= c.real


def stretch_ratios(distortion: FloatArray) -> FloatArray:
    """``κ = σ₁/σ₂ = exp(asinh(√2·|φ_shape|))`` per triangle from ``φ`` (T, 3)."""
    return np.exp(np.arcsinh(np.sqrt(2.0) * np.hypot(distortion[:, 1], distortion[:, 2])))


def shape_quality_bound(inverse_quality_reference: FloatArray, change: FloatArray) -> FloatArray:
    """Upper bound of ``1/ψ_t`` (5.23) from the reference's ``1/ψ_t`` and ``|Δφ_t|``.

    ``1/ψ_t(Q) ≤ exp(asinh(√2·|φ_t(Q) − φ_t(Q₀)|)) · 1/ψ_t(Q₀)``; with ``|Δφ_t| ≤ ℓ/w``
    along a path of length ℓ in the metric ``M + w² JᵀJ`` this bounds every triangle by
    the length of the path, whatever the number of triangles.
    """
    return np.exp(np.arcsinh(np.sqrt(2.0) * np.asarray(change))) * inverse_quality_reference
