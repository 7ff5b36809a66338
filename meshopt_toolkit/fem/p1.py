"""P1 finite elements for the Poisson model problem (SPEC §6, thesis (6.2), (6.12)).

Plain, vectorized kernels over all triangles at once plus a small solver that factorizes
the Dirichlet-reduced stiffness matrix once and serves several right-hand sides (state and
adjoint).

Notation for triangle ``K = (i0, i1, i2)`` (counter-clockwise): edge vectors
``e_l = q_{l+2} − q_{l+1}`` (edge ``l`` opposite vertex ``l``, indices mod 3), area
``A = ½ (e_2 × e_0)``, ``J v = (−v_y, v_x)`` the rotation by +90°. Then

- barycentric gradients ``∇λ_l = J e_l / (2A)``;
- element stiffness ``K_ab = A ∇λ_a·∇λ_b = e_a·e_b / (4A)``;
- ``∂A/∂q_l = ½ J e_l``.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from .._typing import FloatArray, IntArray
from ..errors import MeshoptError
from ..kernels.triangles import areas_from_edges, edges_xy
from ..solvers import amg_pcg_solve, choose_method, factorize_spd, import_pyamg

__all__ = [
    "AMG_THRESHOLD",
    "PoissonSolver",
    "centroids",
    "element_stiffness",
    "lumped_load",
    "nodal_mass_weights",
    "p1_stiffness",
    "poisson_shape_derivative",
]

logger = logging.getLogger(__name__)

#: ``method="auto"`` uses the direct solver below this many free unknowns, AMG above.
AMG_THRESHOLD = 100_000


def _edges_and_areas(points: FloatArray, triangles: IntArray
                     ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Edge components ``e_x, e_y`` ``(T, 3)`` (``e_l = q_{l+2} − q_{l+1}``) and signed
    areas ``(T,)``, from :mod:`~meshopt_toolkit.kernels.triangles` (their one owner)."""
    ex, ey = edges_xy(points[:, 0], points[:, 1], np.asarray(triangles).T)
    return ex.T, ey.T, areas_from_edges(ex, ey)


def element_stiffness(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Local P1 stiffness matrices ``K_ab = e_a·e_b / (4A)``, shape ``(T, 3, 3)``.

    Parameters
    ----------
    points : (N, 2) node positions
    triangles : (T, 3) counter-clockwise vertex indices
    """
    ex, ey, a = _edges_and_areas(points, triangles)
    s = np.sqrt(1.0 / (4.0 * a))[:, None]
    ex *= s
    ey *= s
    return ex[:, :, None] * ex[:, None, :] + ey[:, :, None] * ey[:, None, :]


def p1_stiffness(points: FloatArray, triangles: IntArray) -> sp.csr_matrix:
    """Global P1 stiffness matrix of ``∫ ∇u·∇v``, (6.2). Returns CSR ``(N, N)``."""
    n = len(points)
    ke = element_stiffness(points, triangles)
    tri = np.asarray(triangles, dtype=np.int32 if n < 2**31 else np.int64)
    rows = np.repeat(tri, 3, axis=1).ravel()
    cols = np.tile(tri, (1, 3)).ravel()
    return sp.csr_matrix((ke.ravel(), (rows, cols)), shape=(n, n))


def centroids(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Centroids ``ξ_K = (q0 + q1 + q2)/3`` of every triangle, shape ``(T, 2)``."""
    return points[triangles].mean(axis=1)


def _scatter(triangles: IntArray, values: FloatArray, n: int) -> FloatArray:
    """Sum per-corner values ``(T, 3)`` to nodes ``(n,)``."""
    return np.bincount(triangles.ravel(), weights=values.ravel(), minlength=n)


def nodal_mass_weights(points: FloatArray, triangles: IntArray) -> FloatArray:
    """``m_a = Σ_{K∋a} |K|/3``, so that ``∫ y ≈ mᵀy`` is exact for P1 ``y``. Returns ``(N,)``."""
    a = _edges_and_areas(points, triangles)[2]
    return _scatter(triangles, np.repeat(a[:, None] / 3.0, 3, axis=1), len(points))


def lumped_load(points: FloatArray, triangles: IntArray, r_values: FloatArray) -> FloatArray:
    """Load vector with centroid quadrature ``b_a = Σ_{K∋a} r(ξ_K)|K|/3`` (SPEC §6).

    Parameters
    ----------
    points : (N, 2)
    triangles : (T, 3)
    r_values : (T,) right-hand side at the centroids

    Returns
    -------
    (N,) load vector.
    """
    a = _edges_and_areas(points, triangles)[2]
    w = np.asarray(r_values, dtype=float) * a / 3.0
    return _scatter(triangles, np.repeat(w[:, None], 3, axis=1), len(points))


def poisson_shape_derivative(
    points: FloatArray,
    triangles: IntArray,
    y: FloatArray,
    p: FloatArray,
    r_values: FloatArray,
    r_gradients: FloatArray,
    mass_values: FloatArray | None = None,
) -> FloatArray:
    """Exact derivative of ``j(Q) = mᵀy`` w.r.t. all node positions, (6.12).

    With the state ``K y = b`` and adjoint ``K p = −m`` (both zero on Dirichlet nodes),
    ``dj/dQ = ∂_Q[mᵀy] + pᵀ(∂_Q K)y − pᵀ ∂_Q b`` is the partial derivative of the
    Lagrangian ``Σ_K φ_K`` at fixed ``y, p`` with, per triangle,

    ``φ_K = A s_y/3 + (u·w)/(4A) − r(ξ_K) A s_p/3``,

    where ``s_y = Σ_a y_a``, ``s_p = Σ_a p_a``, ``u = Σ_a p_a e_a``, ``w = Σ_a y_a e_a``
    (so ``pᵀ K_loc y = u·w/(4A)``). Since ``u = Σ_l (p_{l+1} − p_{l+2}) q_l``,

    ``∂φ_K/∂q_l = c ∂A/∂q_l + [(p_{l+1}−p_{l+2}) w + (y_{l+1}−y_{l+2}) u]/(4A)
    − (A s_p/9) ∇r(ξ_K)``,  with ``c = s_y/3 − r s_p/3 − (u·w)/(4A²)``, ``∂A/∂q_l = ½ J e_l``.

    Parameters
    ----------
    points : (N, 2)
    triangles : (T, 3)
    y, p : (N,) state and adjoint
    r_values : (T,) ``r(ξ_K)``
    r_gradients : (T, 2) ``∇r(ξ_K)``
    mass_values : (N,) ``z``, optional
        Differentiate ``m(Q)ᵀz`` at fixed ``z`` instead of ``m(Q)ᵀy`` (the mass term of
        another objective, e.g. ``z = ½(y − y_d)²`` for a tracking functional; its
        remaining explicit terms are the caller's).

    Returns
    -------
    (N, 2) derivative, including Dirichlet (boundary) vertices.
    """
    ex, ey, a = _edges_and_areas(points, triangles)
    yk = y[triangles]
    pk = p[triangles]
    ux, uy = (pk * ex).sum(axis=1), (pk * ey).sum(axis=1)
    wx, wy = (yk * ex).sum(axis=1), (yk * ey).sum(axis=1)
    uw = ux * wx + uy * wy
    sy = yk.sum(axis=1) if mass_values is None else np.asarray(mass_values)[triangles].sum(axis=1)
    sp_ = pk.sum(axis=1)
    y0, y1, y2 = yk[:, 0], yk[:, 1], yk[:, 2]
    p0, p1, p2 = pk[:, 0], pk[:, 1], pk[:, 2]
    dy = np.stack([y1 - y2, y2 - y0, y0 - y1], axis=1)  # y_{l+1} − y_{l+2}
    dp = np.stack([p1 - p2, p2 - p0, p0 - p1], axis=1)
    r = np.asarray(r_values, dtype=float)
    grad_r = np.asarray(r_gradients, dtype=float)
    inv4a = (0.25 / a)[:, None]
    c = (sy / 3.0 - r * sp_ / 3.0 - uw / (4.0 * a * a))[:, None]
    f = (a * sp_ / 9.0)[:, None]
    # ∂A/∂q_l = ½ J e_l = ½ (−e_y, e_x)
    gx = -0.5 * c * ey + (dp * wx[:, None] + dy * ux[:, None]) * inv4a - f * grad_r[:, 0:1]
    gy = 0.5 * c * ex + (dp * wy[:, None] + dy * uy[:, None]) * inv4a - f * grad_r[:, 1:2]
    n = len(points)
    return np.stack([_scatter(triangles, gx, n), _scatter(triangles, gy, n)], axis=1)


class PoissonSolver:
    """Solve ``K y = b`` with ``y = 0`` on Dirichlet nodes, factorizing once.

    Parameters
    ----------
    K : (N, N) sparse symmetric positive semi-definite stiffness matrix
    dirichlet : (D,) indices of the nodes where ``y = 0`` (at least one)
    method : ``"direct"`` (SuperLU, reverse Cuthill–McKee then symmetric minimum degree),
        ``"amg"`` (pyamg classical Ruge–Stüben AMG as a preconditioner for CG, iterated to
        relative residual ``rtol``; one hierarchy serves every right-hand side) or
        ``"auto"`` (direct below :data:`AMG_THRESHOLD` free nodes, AMG above).
    rtol : relative residual tolerance of the AMG-CG iteration

    Notes
    -----
    The AMG path needs ``pyamg`` (imported lazily). Its solutions are accurate to
    ``rtol`` only; use ``method="direct"`` when the last digits matter (Taylor tests).
    """

    def __init__(self, K, dirichlet: IntArray, method: str = "auto", rtol: float = 1e-10):
        K = sp.csr_matrix(K)
        n = K.shape[0]
        fixed = np.zeros(n, dtype=bool)
        dirichlet = np.asarray(dirichlet, dtype=np.int64).ravel()
        if dirichlet.size == 0:
            raise MeshoptError("the Poisson problem needs at least one Dirichlet node")
        if dirichlet.min() < 0 or dirichlet.max() >= n:
            raise MeshoptError(f"Dirichlet node index out of range 0..{n - 1}")
        fixed[dirichlet] = True
        self.n = n
        self.free = np.flatnonzero(~fixed)
        method = choose_method(method, self.free.size, AMG_THRESHOLD + 1)
        self.method = method
        self.rtol = float(rtol)
        kff = K[self.free][:, self.free].tocsr()
        # a bandwidth-reducing order first: it makes the AMG setup and smoothing cache
        # friendly and halves SuperLU's fill (minimum degree alone is sensitive to the
        # input numbering, e.g. after repeated refinement)
        if self.free.size == 0:
            self._order = self.free
            self._solve = lambda b: b
            return
        perm = reverse_cuthill_mckee(kff, symmetric_mode=True)
        self._order = self.free[perm]  # unknown k of the permuted system is node _order[k]
        kp = kff[perm][:, perm].tocsr()
        if method == "direct":
            self._solve = factorize_spd(kp)
        else:
            ml = import_pyamg().ruge_stuben_solver(kp, coarse_solver="splu")
            self._solve = amg_pcg_solve(kp, ml, self.rtol)

    def solve(self, b: FloatArray) -> FloatArray:
        """Solution ``(N,)`` of ``K y = b`` on free nodes, ``y = 0`` on Dirichlet nodes."""
        b = np.asarray(b, dtype=float)
        y = np.zeros(self.n)
        if self.free.size:
            y[self._order] = self._solve(b[self._order])
        return y
