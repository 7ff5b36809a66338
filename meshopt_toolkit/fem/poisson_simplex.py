"""The Poisson model objective on triangles and tetrahedra alike: P1 state and adjoint, the
integral ``j = ∫y`` or the tracking functional, and the exact derivative w.r.t. the nodes.

The discretization is that of the planar :class:`~.poisson.PoissonObjective` in any
dimension ``d``: ``K y = b`` with ``K = Σ_K |K| ∇λ ∇λᵀ``, the centroid load
``b_a = Σ_{K∋a} r(ξ_K) |K| / (d+1)``, ``y = g_D`` on the Dirichlet nodes, and
``j = mᵀy`` with ``m_a = Σ_{K∋a} |K| / (d+1)`` (or ``Σ_a m_a ½(y_a − y_d(x_a))²``).
With the adjoint ``K p = −∂j/∂y`` (0 on Dirichlet nodes), ``dj/dx`` is the partial
derivative of ``Σ_K Φ_K`` at fixed ``y, p``,

``Φ_K = |K| [∇y·∇p + (s_z − r(ξ_K) s_p)/(d+1)]``, ``s_z = Σ_a z_a``, ``s_p = Σ_a p_a``

(``z = y`` for ∫y, ``z = ½(y − y_d)²`` for tracking), whose Eshelby tensor
(:mod:`.simplex`) is ``S_K = Φ_K I − |K| (∇y ∇pᵀ + ∇p ∇yᵀ)``, plus the data terms
``−|K| s_p ∇r(ξ_K) / (d+1)²`` at each vertex of ``K`` and, for tracking,
``−m_a (y_a − y_d) ∇y_d(x_a)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from numbers import Real

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..errors import ExpressionError, MeshoptError
from ..expressions import parse_expression
from ..kernels.cell_maps import scatter_corners
from .p1 import PoissonSolver
from .cached import CachedPoisson, SimplexState, poisson_value, tracking_terms
from .simplex import Geometry, assemble, geometry, node_gradient

__all__ = ["SimplexPoisson", "data_function", "p1_matrices", "poisson_node_gradient"]


class _Constant:
    """``x ↦ c`` with its zero gradient."""

    def __init__(self, c: float) -> None:
        self.c = c

    def __call__(self, X: FloatArray) -> FloatArray:
        return np.full(len(X), self.c)

    def gradient(self, X: FloatArray) -> FloatArray:
        return np.zeros_like(np.asarray(X, dtype=float))


def data_function(value):
    """A datum as a callable with ``.gradient``: a number, an expression string
    (:func:`~meshopt_toolkit.expressions.parse_expression`, exact gradient) or a callable
    ``(M, d) → (M,)`` that has a ``gradient`` attribute ``(M, d) → (M, d)``."""
    if isinstance(value, Real) and not isinstance(value, bool):
        if not np.isfinite(value):
            raise ExpressionError(f"datum {value!r} is not finite")
        return _Constant(float(value))
    if isinstance(value, str):
        return parse_expression(value)
    if callable(value) and callable(getattr(value, "gradient", None)):
        return value
    raise ExpressionError("a datum is a number, an expression or a callable with a .gradient")


def p1_matrices(points: FloatArray, cells: IntArray) -> tuple[Geometry, sp.csr_matrix, FloatArray]:
    """The geometry, the P1 stiffness matrix ``(N, N)`` and the lumped mass ``m`` ``(N,)``."""
    geo = geometry(points, cells)
    local = geo.volumes[:, None, None] * np.einsum("tad,tbd->tab", geo.grads, geo.grads)
    n = len(points)
    K = assemble(cells, cells, local, (n, n))
    m = np.bincount(cells.ravel(), weights=np.repeat(geo.volumes / cells.shape[1], cells.shape[1]),
                    minlength=n)
    return geo, K, m


def poisson_node_gradient(geo: Geometry, cells: IntArray, y: FloatArray, p: FloatArray,
                          r: FloatArray, grad_r: FloatArray, z: FloatArray | None = None
                          ) -> FloatArray:
    """``∂/∂x Σ_K Φ_K`` at fixed state ``y``, adjoint ``p`` (module docstring).

    Parameters
    ----------
    geo : the cells' geometry (:func:`.simplex.geometry`)
    cells : (T, d+1)
    y, p : (N,) state and adjoint
    r, grad_r : (T,), (T, d) the load and its gradient at the centroids
    z : (N,) the values whose lumped integral is ``j`` (default ``y``)

    Returns
    -------
    (N, d)
    """
    m = cells.shape[1]
    vol = geo.volumes
    gy = np.einsum("ta,tad->td", y[cells], geo.grads)
    gp = np.einsum("ta,tad->td", p[cells], geo.grads)
    sz = (y if z is None else z)[cells].sum(axis=1)
    sp_ = p[cells].sum(axis=1)
    phi = vol * ((gy * gp).sum(axis=1) + (sz - r * sp_) / m)
    d = geo.dim
    S = phi[:, None, None] * np.eye(d) - vol[:, None, None] * (
        gy[:, :, None] * gp[:, None, :] + gp[:, :, None] * gy[:, None, :])
    g = node_gradient(S, geo, cells, len(y))
    data = -(vol * sp_ / m**2)[:, None] * grad_r  # (T, d), the same at every vertex of K
    return g + scatter_corners(cells, np.repeat(data[:, None, :], m, axis=1), len(y))


@dataclass
class _State(SimplexState):
    solver: PoissonSolver
    m: FloatArray
    r: FloatArray
    xi: FloatArray
    y: FloatArray
    value: float
    p: FloatArray | None = None


class SimplexPoisson(CachedPoisson):
    """``j = ∫y`` (or ``½∫(y − y_d)²``) subject to ``−Δy = r``, ``y = g_D`` on Dirichlet
    nodes, P1 on triangles ``(N, 2)``/``(T, 3)`` or tetrahedra ``(N, 3)``/``(T, 4)``.

    Parameters
    ----------
    cells : (T, d+1) positively oriented simplices
    dirichlet : (D,) Dirichlet vertices (at least one)
    rhs : number, expression or callable with ``.gradient`` (:func:`data_function`)
    dirichlet_values : (D,) values ``g_D`` (default 0)
    tracking : ``y_d`` in the same forms, or None for ``∫y``
    solver : ``"auto"``, ``"direct"`` or ``"amg"`` (:class:`~.p1.PoissonSolver`)
    rtol : relative residual of the AMG iteration

    Notes
    -----
    The last configuration's state and factorization are cached: ``value(Q)`` then
    ``derivative(Q)`` costs one state and one adjoint solve with one factorization.
    """

    def __init__(self, cells: IntArray, dirichlet: IntArray, rhs=1.0, *, dirichlet_values=None,
                 tracking=None, solver: str = "auto", rtol: float = 1e-10) -> None:
        self.cells = np.asarray(cells, dtype=np.int64)
        self.dirichlet = np.unique(np.asarray(dirichlet, dtype=np.int64))
        if self.dirichlet.size == 0:
            raise MeshoptError("the Poisson problem needs at least one Dirichlet node")
        self._g = None if dirichlet_values is None else np.broadcast_to(
            np.asarray(dirichlet_values, dtype=float), np.shape(dirichlet)).copy()
        self._g_nodes = np.asarray(dirichlet, dtype=np.int64)
        self.rhs = data_function(rhs)
        self.tracking = None if tracking is None else data_function(tracking)
        self.solver, self.rtol = solver, float(rtol)

    def _compute(self, Q) -> _State:
        Q = np.array(Q, dtype=float)
        geo, K, m = p1_matrices(Q, self.cells)
        solver = PoissonSolver(K, self.dirichlet, method=self.solver, rtol=self.rtol)
        xi = Q[self.cells].mean(axis=1)
        r = np.asarray(self.rhs(xi), dtype=float)
        k = self.cells.shape[1]
        b = np.bincount(self.cells.ravel(), weights=np.repeat(r * geo.volumes / k, k),
                        minlength=len(Q))
        lift = np.zeros(len(Q))
        if self._g is not None:
            lift[self._g_nodes] = self._g
        y = solver.solve(b - K @ lift) + lift
        value = poisson_value(m, y, self._target(Q))
        return _State(Q, geo, solver, m, r, xi, y, value)

    def _target(self, Q: FloatArray) -> FloatArray | None:
        return None if self.tracking is None else self.tracking(Q)

    def derivative(self, Q: FloatArray) -> FloatArray:
        """Exact ``dj/dQ`` ``(N, d)``, every node included."""
        s = self._state(Q)
        p = self._adjoint(s)
        z = None
        if self.tracking is not None:
            z, weight = tracking_terms(s.m, s.y, self._target(s.Q))
        g = poisson_node_gradient(s.geo, self.cells, s.y, p, s.r, self.rhs.gradient(s.xi), z)
        if self.tracking is not None:
            g -= weight[:, None] * self.tracking.gradient(s.Q)
        return g
