"""Per-triangle membrane distortion of triangle surfaces in R³.

Each current triangle is the image of its rest triangle (in an orthonormal frame of the
rest triangle's own plane, :func:`..kernels.cell_maps.triangle_plane_coordinates`) under
an affine map with linear part ``A`` (3×2); ``C = AᵀA`` (2×2) is the first fundamental
form pulled back to the rest triangle. The distortion is the planar one (:mod:`..planar.distortion`)
written through ``C``:

    φ_t = (1/√2) · ( ½ log det C,  ((C₁₁ − C₂₂)/2) / √det C,  C₁₂ / √det C ).

For a map of the plane ``A z = αz + βz̄`` one has ``√det C = |α|² − |β|²`` and
``(C₁₁ − C₂₂)/2 + iC₁₂ = 2ᾱβ``, so the last two components are ``2μ/(1 − |μ|²)/√2`` of
:class:`..planar.distortion.TriangleDistortion` (in the rest frame of each triangle: for a flat mesh
they are the planar ones turned by twice minus the angle of the rest edge 0→1, a fixed
rotation per triangle, so the metric ``JᵀJ`` and every bound are the planar ones).

``φ`` depends on ``C`` only, hence is invariant under any rotation (even one per triangle)
and translation of the current triangles; a uniform scaling by ``s`` adds ``√2 log s`` to
the first component only; ``φ = 0`` at the reference and ``|φ| → ∞`` when a triangle
degenerates (``+inf`` rows where ``det C ≤ 0``). Bounds: those of the plane,
:func:`surface_quality_bound` (from the reference) and :func:`surface_path_quality_bound`
(any start), proved in docs/theory-3d.md.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...errors import InvalidMeshError
from ...kernels.cell_maps import (affine_maps, barycentric_gradients, block_jacobian,
                                  coordinate_columns, space_cells,
                                  triangle_plane_coordinates)
from ..planar.distortion import shape_quality_bound

S = np.sqrt(0.5)
#: gradients of p = (C₁₁ − C₂₂)/2 and q = C₁₂ in c = (C₁₁, C₂₂, C₁₂)
GRAD_P = np.array([0.5, -0.5, 0.0])
GRAD_Q = np.array([0.0, 0.0, 1.0])
#: ∇²D of D = C₁₁C₂₂ − C₁₂²
HESS_D = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -2.0]])


class SurfaceDistortion:
    """The per-triangle membrane distortion ``φ(Q)`` (shape ``(T, 3)``) of a surface: the
    :class:`~meshopt_toolkit.cells.base.CellDistortion` of ``(reference, triangles)``,
    reference (N, 3).

    Raises
    ------
    InvalidMeshError
        When a reference triangle is degenerate.
    """

    n_components = 3

    def __init__(self, reference: FloatArray, triangles: IntArray) -> None:
        self.reference, self.triangles = space_cells(reference, triangles, 3,
                                                     "a surface distortion")
        self.n_vertices = len(self.reference)
        rest = triangle_plane_coordinates(self.reference, self.triangles)
        # twice the area against the squared edges: degenerate up to rounding is refused
        scale = np.einsum("tij,tij->t", rest, rest)
        good = rest[:, 1, 0] * rest[:, 2, 1] > 64 * np.finfo(float).eps * scale
        if not good.all():
            bad = int(np.flatnonzero(~good)[0])
            raise InvalidMeshError(f"reference triangle {bad} is degenerate")
        self.gradients = barycentric_gradients(rest)  # (T, 3, 2)

    def affine_maps(self, Q: FloatArray) -> FloatArray:
        """Linear parts ``A`` (T, 3, 2) from the rest triangles' planes to R³."""
        return affine_maps(Q, self.triangles, self.gradients)

    def metric_tensors(self, Q: FloatArray) -> FloatArray:
        """First fundamental forms ``C = AᵀA`` (T, 2, 2) in the rest frames."""
        A = self.affine_maps(Q)
        return np.matmul(np.swapaxes(A, 1, 2), A)

    def values(self, Q: FloatArray) -> FloatArray:
        """``φ(Q)``, shape (T, 3); rows of a degenerate triangle are ``+inf``."""
        return self._evaluate(Q, jacobian=False)[0]

    def values_and_jacobian(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``φ(Q)`` (T, 3) and the per-triangle Jacobian blocks (T, 3, 9).

        Block ``[t, i, 3j + d]`` is ``∂φ_ti / ∂Q[triangles[t, j], d]``.
        """
        return self._evaluate(Q, jacobian=True)

    def _invariants(self, Q: FloatArray):
        """``A``, ``c = (C₁₁, C₂₂, C₁₂)``, ``D = det C``, the bad rows, ``∇_c φ`` (T, 3, 3)
        and the pieces of the second derivatives."""
        A = self.affine_maps(Q)
        a0, a1 = A[:, :, 0], A[:, :, 1]
        c = np.stack([np.einsum("ti,ti->t", a0, a0), np.einsum("ti,ti->t", a1, a1),
                      np.einsum("ti,ti->t", a0, a1)], axis=1)
        D = c[:, 0] * c[:, 1] - c[:, 2] ** 2
        bad = ~(D > 0) | ~np.isfinite(D)
        D = np.where(bad, 1.0, D)
        g = D**-0.5
        p, q = 0.5 * (c[:, 0] - c[:, 1]), c[:, 2]
        grad_D = np.stack([c[:, 1], c[:, 0], -2.0 * c[:, 2]], axis=1)
        grad_g = -0.5 * (g / D)[:, None] * grad_D
        grad = np.empty((len(A), 3, 3))
        grad[:, 0] = 0.5 * S * grad_D / D[:, None]
        grad[:, 1] = S * (g[:, None] * GRAD_P + p[:, None] * grad_g)
        grad[:, 2] = S * (g[:, None] * GRAD_Q + q[:, None] * grad_g)
        return A, c, D, bad, g, p, q, grad_D, grad_g, grad

    def _evaluate(self, Q: FloatArray, jacobian: bool):
        A, c, D, bad, g, p, q, *_, grad = self._invariants(Q)
        phi = S * np.stack([0.5 * np.log(D), p * g, q * g], axis=1)
        phi[bad] = np.inf
        if not jacobian:
            return phi, None
        J = np.matmul(grad, self._c_jacobian(A))
        J[bad] = 0.0
        return phi, J

    def _c_jacobian(self, A: FloatArray) -> FloatArray:
        """``∂c/∂Q`` (T, 3, 9): ``∂C_bb'/∂x_j = γ_jb a_b' + γ_jb' a_b`` (``a_b`` = column
        ``b`` of ``A``)."""
        G = self.gradients
        a0, a1 = A[:, None, :, 0], A[:, None, :, 1]  # (T, 1, 3)
        out = np.empty((len(A), 3, 3, 3))
        out[:, 0] = 2.0 * G[:, :, 0, None] * a0
        out[:, 1] = 2.0 * G[:, :, 1, None] * a1
        out[:, 2] = G[:, :, 0, None] * a1 + G[:, :, 1, None] * a0
        return out.reshape(len(A), 3, 9)

    def second_order(self, Q: FloatArray, rho: FloatArray) -> FloatArray:
        """``Σ_i ρ_ti ∇²φ_ti`` per triangle in the coordinates of
        :meth:`values_and_jacobian`: (T, 9, 9), symmetric.

        In ``c = (C₁₁, C₂₂, C₁₂)`` with ``D = det C``, ``g = D^{-½}``, ``p = (C₁₁ − C₂₂)/2``,
        ``q = C₁₂``, ``s = 1/√2``: ``φ_0 = (s/2) log D``, ``φ_1 = s p g``, ``φ_2 = s q g``;
        ``∇²g = ¾ g ∇D∇Dᵀ/D² − ½ g ∇²D/D``. ``c`` is quadratic in the vertices,
        ``∂²C_bb'/∂x_j∂x_k = (γ_jb γ_kb' + γ_jb' γ_kb) I₃``, so

            ∇²_Q(ρ·φ) = J_cᵀ (Σ_i ρ_i ∇²_c φ_i) J_c + Σ_m (Σ_i ρ_i ∂φ_i/∂c_m) ∇²_Q c_m.

        Parameters
        ----------
        Q : (N, 3) float array
            Current positions (no degenerate triangle).
        rho : (T, 3) float array
        """
        A, c, D, bad, g, p, q, grad_D, grad_g, grad = self._invariants(Q)
        rho = np.asarray(rho, float)
        outer = lambda u, v: u[:, :, None] * v[:, None, :]  # noqa: E731
        col = lambda x: x[:, None, None]  # noqa: E731
        dd = outer(grad_D, grad_D)
        hess_g = 0.75 * col(g / D**2) * dd - 0.5 * col(g / D) * HESS_D
        gp = np.broadcast_to(GRAD_P, grad_g.shape)
        gq = np.broadcast_to(GRAD_Q, grad_g.shape)
        H_c = (col(rho[:, 0] * 0.5 * S) * (HESS_D / col(D) - dd / col(D**2))
               + col(rho[:, 1] * S) * (outer(gp, grad_g) + outer(grad_g, gp) + col(p) * hess_g)
               + col(rho[:, 2] * S) * (outer(gq, grad_g) + outer(grad_g, gq) + col(q) * hess_g))
        Jc = self._c_jacobian(A)
        out = np.matmul(np.swapaxes(Jc, 1, 2), np.matmul(H_c, Jc))
        r = np.einsum("ti,tim->tm", rho, grad)  # Σ_i ρ_i ∂φ_i/∂c_m
        G = self.gradients
        S_c = (2.0 * r[:, 0, None, None] * outer(G[:, :, 0], G[:, :, 0])
               + 2.0 * r[:, 1, None, None] * outer(G[:, :, 1], G[:, :, 1])
               + r[:, 2, None, None] * (outer(G[:, :, 0], G[:, :, 1])
                                        + outer(G[:, :, 1], G[:, :, 0])))
        blocks = out.reshape(-1, 3, 3, 3, 3)  # [j, a, k, e]: S_c ⊗ I₃
        for a in range(3):
            blocks[:, :, a, :, a] += S_c
        out[bad] = 0.0
        return out

    def columns(self) -> IntArray:
        """Global coordinate index ``3·vertex + d`` of each block column: (T, 9)."""
        return coordinate_columns(self.triangles, 3)

    def jacobian_matrix(self, blocks: FloatArray) -> sp.csr_matrix:
        """Assemble per-triangle blocks (T, 3, 9) into the sparse ``J`` (3T × 3N)."""
        return block_jacobian(blocks, self.columns(), 3 * self.n_vertices)

def surface_quality_bound(inverse_quality_reference: FloatArray, change: FloatArray) -> FloatArray:
    """Upper bound of ``1/ψ_t`` (5.23, in the triangle's own plane) from the reference's
    value and ``δ ≥ |φ_t(Q) − φ_t(Q₀)|`` (``Q₀`` the reference):
    ``1/ψ_t(Q) ≤ exp(asinh(√2 δ)) · 1/ψ_t(Q₀)``, as in the plane."""
    return shape_quality_bound(inverse_quality_reference, change)


def surface_path_quality_bound(inverse_quality_start: FloatArray, length: FloatArray) -> FloatArray:
    """Upper bound of ``1/ψ_t`` at the end of any path from its value at the start and
    the triangle's φ-length ``L`` along the path (``L ≤ ℓ/w``):
    ``1/ψ(end) ≤ 1/ψ(start) · exp(√2 L)``."""
    with np.errstate(over="ignore"):  # a path too long for any bound: +inf, still true
        return np.asarray(inverse_quality_start) * np.exp(np.sqrt(2.0) * np.asarray(length))
