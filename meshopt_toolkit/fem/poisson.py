"""The PDE model objective ``j(Q) = ∫ y`` with its exact adjoint shape derivative (SPEC §6).

Boundary data per physical group (:mod:`.boundary_data`: Dirichlet values, Neumann
fluxes) and the tracking functional ``j(Q) = ½∫(y − y_d)²`` (lumped:
``½ Σ_a m_a (y_a − y_d(q_a))²``) use the same state and adjoint solves; every derivative is
that of the discrete functional.

For node positions ``Q (N, 2)``: ``y`` is the P1 solution of ``−Δy = r`` with ``y = 0`` on
the Dirichlet nodes (all boundary vertices by default), load by centroid quadrature, and
``j(Q) = mᵀy`` with ``m_a = Σ_{K∋a}|K|/3`` (thesis (6.2)). The derivative is that of the
discrete functional, by the adjoint method (6.12), w.r.t. every node including boundary
nodes; see :func:`meshopt_toolkit.fem.poisson_shape_derivative`.

:class:`PoissonObjective` is the reference implementation of the optimizers' objective
interface, :class:`meshopt_toolkit.optimize.Objective` (``value``, ``derivative``,
optionally ``value_and_derivative``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from numbers import Real

import numpy as np

from . import p1 as fem
from .cached import CachedPoisson, poisson_value, tracking_terms
from .boundary_data import BoundaryData, neumann_load, neumann_shape_derivative
from .._options import require_shape
from .._typing import FloatArray, IntArray
from ..errors import ExpressionError, InvalidMeshError, MeshoptError, NotAdmissibleError
from ..expressions import DEFAULT_RHS, Expression, parse_expression
from ..kernels.admissibility import BoundaryCheck, area_problem, first_non_finite_row
from ..mesh import PlanarMesh, TriangleMesh, require_admissible

__all__ = ["DEFAULT_RHS", "PoissonObjective"]

logger = logging.getLogger(__name__)



RhsFunction = Callable[[FloatArray], FloatArray]


def _finite_difference_gradient(r: RhsFunction, h: float) -> RhsFunction:
    """Central differences ``(r(X + h e_k) − r(X − h e_k)) / 2h``, error ``O(h²)``."""

    def gradient(X: FloatArray) -> FloatArray:
        cols = []
        for k in (0, 1):
            step = np.zeros(2)
            step[k] = h
            cols.append((r(X + step) - r(X - step)) / (2.0 * h))
        return np.stack(cols, axis=1)

    return gradient


def _resolve_rhs(rhs, rhs_gradient, scale: float) -> tuple[str, RhsFunction, RhsFunction]:
    """(description, r, ∇r) for the accepted forms of ``rhs``."""
    if isinstance(rhs, str):
        expr = parse_expression(DEFAULT_RHS if rhs == "default" else rhs)
        if expr.uses_z:
            raise ExpressionError(f"right-hand side {rhs!r}: z is not defined for a planar mesh")
        rhs = expr
    if isinstance(rhs, Real) and not isinstance(rhs, bool):
        c = float(rhs)
        if not np.isfinite(c):
            raise ExpressionError(f"right-hand side {rhs!r} is not finite")
        return (
            repr(c),
            lambda X: np.full(len(X), c),
            lambda X: np.zeros((len(X), 2)),
        )
    if isinstance(rhs, Expression):
        return rhs.text, rhs, rhs.gradient
    if not callable(rhs):
        raise ExpressionError(
            f"rhs must be an expression string, a number or a callable, not {type(rhs).__name__}"
        )
    if rhs_gradient is None:
        rhs_gradient = getattr(rhs, "gradient", None)
    if rhs_gradient is None or not callable(rhs_gradient):
        h = np.cbrt(np.finfo(float).eps) * scale
        logger.info("rhs has no gradient: central differences with step %.3g", h)
        rhs_gradient = _finite_difference_gradient(rhs, h)
    return getattr(rhs, "__name__", repr(rhs)), rhs, rhs_gradient


@dataclass
class _State:
    """Everything computed at one configuration ``Q`` (the cache)."""

    Q: FloatArray
    solver: fem.PoissonSolver
    xi: FloatArray  # (T, 2) centroids
    r: FloatArray  # (T,) r(ξ_K)
    m: FloatArray  # (N,) nodal mass weights
    y: FloatArray  # (N,) state
    value: float
    p: FloatArray | None = None  # (N,) adjoint, on demand


class PoissonObjective(CachedPoisson):
    """``j(Q) = ∫ y`` subject to ``−Δy = r``, ``y = 0`` on Dirichlet nodes, P1 (6.2).

    Parameters
    ----------
    mesh : PlanarMesh
        Connectivity and reference positions; must be admissible.
    rhs : str, float or callable, default ``"default"``
        ``"default"`` is :data:`DEFAULT_RHS`; any other string is parsed by
        :func:`~meshopt_toolkit.expressions.parse_expression` (exact gradient); a number is
        a constant; a callable maps points ``(M, 2)`` to values ``(M,)``. A callable's
        gradient is ``rhs_gradient`` if given, else its ``.gradient`` attribute, else central
        differences with step ``h = cbrt(machine eps) · diameter(mesh)`` (error
        ``O(h²) ≈ 1e-11`` relative for smooth ``r`` — fine for optimization and Taylor
        tests, but supply the gradient when you have it).
    dirichlet : None, index array, tag name/number, list of those, or ``{group: value}``
        Nodes with ``y = 0``. Default: all boundary vertices. A name or tag selects the
        vertices of the tagged line elements (:meth:`PlanarMesh.tagged_vertices`). A
        mapping sets ``y = value`` on each group's vertices and keeps ``y = 0`` on the
        rest of the boundary (:class:`~.boundary_data.BoundaryData`).
    rhs_gradient : callable, optional
        ``∇r``: points ``(M, 2)`` to ``(M, 2)``.
    solver : ``"auto"``, ``"direct"`` or ``"amg"``
        See :class:`~meshopt_toolkit.fem.PoissonSolver`. ``"auto"`` is direct below
        :data:`~meshopt_toolkit.fem.AMG_THRESHOLD` free nodes and AMG-CG above.
    rtol : float
        Relative residual of the AMG iteration.
    neumann : ``{group: value}``, optional
        ``∂y/∂n = value`` on each group's edges (their vertices leave the default
        ``y = 0`` set unless they also lie on another boundary part).
    tracking : str, float or callable, optional
        ``y_d``: minimize ``½∫(y − y_d)²`` (lumped mass) instead of ``∫y``; the same forms
        as ``rhs``.

    Notes
    -----
    The last configuration's state, factorization and adjoint are cached, so
    ``value(Q)`` followed by ``derivative(Q)`` solves the state once; ``derivative``
    adds one adjoint solve with the same factorization.

    Examples
    --------
    >>> from meshopt_toolkit.mesh import PlanarMesh
    >>> m = PlanarMesh([[-1, -1], [1, -1], [1, 1], [-1, 1], [0, 0]],
    ...                [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    >>> j = PoissonObjective(m, rhs=1.0)
    >>> round(j.value(m.points), 6)
    0.444444
    """

    def __init__(
        self,
        mesh: TriangleMesh,
        rhs="default",
        dirichlet=None,
        *,
        rhs_gradient: RhsFunction | None = None,
        solver: str = "auto",
        rtol: float = 1e-10,
        neumann: Mapping | None = None,
        tracking=None,
    ) -> None:
        if solver not in ("auto", "direct", "amg"):
            raise ValueError(f"unknown solver {solver!r}; use 'auto', 'direct' or 'amg'")
        self.mesh: PlanarMesh = require_admissible(mesh, "the Poisson objective")
        self.triangles: IntArray = self.mesh.triangles
        self.n_vertices = self.mesh.n_vertices
        self._tri_t = np.ascontiguousarray(self.triangles.T)
        self._boundary_check = BoundaryCheck(self.mesh.boundary_edges,
                                             self.mesh.boundary_vertices)
        scale = max(self.mesh.diameter, np.finfo(float).tiny)
        if isinstance(dirichlet, Mapping) or neumann:
            if dirichlet is not None and not isinstance(dirichlet, Mapping):
                raise MeshoptError("with Neumann data give Dirichlet data as {group: value}")
            bc = BoundaryData.of(self.mesh, dirichlet, neumann)
            self.dirichlet, self._lift = bc.dirichlet, bc.lift
            self._n_edges, self._n_values = bc.neumann_edges, bc.neumann_values
        else:
            self.dirichlet = self._resolve_dirichlet(dirichlet)
            self._lift = self._n_edges = self._n_values = None
        self.rhs_text, self._r, self._grad_r = _resolve_rhs(rhs, rhs_gradient, scale)
        self.tracking_text = None
        if tracking is not None:
            self.tracking_text, self._yd, self._grad_yd = _resolve_rhs(tracking, None, scale)
        self.solver = solver
        self.rtol = float(rtol)

    def __repr__(self) -> str:
        return (
            f"PoissonObjective(N={self.n_vertices}, T={len(self.triangles)}, "
            f"rhs={self.rhs_text!r}, {self.dirichlet.size} Dirichlet nodes)"
        )

    # ---------------------------------------------------------------- set-up helpers

    def _resolve_dirichlet(self, dirichlet) -> IntArray:
        mesh = self.mesh
        if dirichlet is None:
            idx = mesh.boundary_vertices
        elif isinstance(dirichlet, (str, np.integer, int)) and not isinstance(dirichlet, bool):
            idx = (
                mesh.tagged_vertices(dirichlet)
                if isinstance(dirichlet, str)
                else np.asarray([dirichlet])
            )
        elif isinstance(dirichlet, (list, tuple)) and any(isinstance(d, str) for d in dirichlet):
            idx = np.concatenate([mesh.tagged_vertices(d) for d in dirichlet])
        else:
            idx = np.asarray(dirichlet)
            if idx.dtype == bool:
                if idx.shape != (self.n_vertices,):
                    raise InvalidMeshError(
                        f"a Dirichlet mask needs shape ({self.n_vertices},), got {idx.shape}"
                    )
                idx = np.flatnonzero(idx)
            elif idx.size and not np.issubdtype(idx.dtype, np.integer):
                raise InvalidMeshError("dirichlet must hold vertex indices (integers)")
        idx = np.unique(np.asarray(idx, dtype=np.int64).ravel())
        if idx.size == 0:
            raise MeshoptError("the Poisson problem needs at least one Dirichlet node")
        if idx[0] < 0 or idx[-1] >= self.n_vertices:
            raise InvalidMeshError(
                f"Dirichlet vertex index out of range 0..{self.n_vertices - 1}"
            )
        return idx

    def _check_Q(self, Q) -> FloatArray:
        Q = require_shape("Q", np.asarray(Q, dtype=float), (self.n_vertices, 2),
                          error=InvalidMeshError)
        problem = area_problem(Q, self._tri_t) or self._boundary_check.problem(Q)
        if problem is not None:
            raise NotAdmissibleError(problem)
        return Q

    def _eval_r(self, xi: FloatArray) -> FloatArray:
        r = np.asarray(self._r(xi), dtype=float)
        if r.shape != (len(xi),):
            raise ExpressionError(f"rhs returned shape {r.shape}, expected ({len(xi)},)")
        if not np.isfinite(r).all():
            i = int(np.flatnonzero(~np.isfinite(r))[0])
            raise ExpressionError(f"rhs is not finite at {tuple(xi[i])}")
        return r

    def _eval_grad_r(self, xi: FloatArray) -> FloatArray:
        g = np.asarray(self._grad_r(xi), dtype=float)
        if g.shape != (len(xi), 2):
            raise ExpressionError(f"rhs gradient returned shape {g.shape}, expected ({len(xi)}, 2)")
        if not np.isfinite(g).all():
            i = first_non_finite_row(g)
            raise ExpressionError(f"rhs gradient is not finite at {tuple(xi[i])}")
        return g

    # ---------------------------------------------------------------- evaluation

    def _compute(self, Q) -> _State:
        Q = self._check_Q(Q)
        tri = self.triangles
        K = fem.p1_stiffness(Q, tri)
        solver = fem.PoissonSolver(K, self.dirichlet, method=self.solver, rtol=self.rtol)
        xi = fem.centroids(Q, tri)
        r = self._eval_r(xi)
        m = fem.nodal_mass_weights(Q, tri)
        b = fem.lumped_load(Q, tri, r)
        if self._n_edges is not None and len(self._n_edges):
            b = b + neumann_load(Q, self._n_edges, self._n_values, self.n_vertices)
        if self._lift is not None and self._lift.any():
            y = solver.solve(b - K @ self._lift) + self._lift  # y = g_D on Dirichlet nodes
        else:
            y = solver.solve(b)
        value = poisson_value(m, y, self._target(Q))
        return _State(Q.copy(), solver, xi, r, m, y, value)

    def _target(self, Q: FloatArray) -> FloatArray | None:
        if self.tracking_text is None:
            return None
        yd = np.asarray(self._yd(Q), dtype=float)
        if yd.shape != (len(Q),) or not np.isfinite(yd).all():
            raise ExpressionError("the tracking target is not finite (or not one value per node)")
        return yd

    def value_and_derivative(self, Q: FloatArray) -> tuple[float, FloatArray]:
        """``j(Q)`` and its exact derivative ``(N, 2)`` w.r.t. all nodes, (6.12)."""
        s = self._state(Q)
        self._adjoint(s)
        z = None
        if self.tracking_text is not None:
            z, weight = tracking_terms(s.m, s.y, self._target(s.Q))
        g = fem.poisson_shape_derivative(
            s.Q, self.triangles, s.y, s.p, s.r, self._eval_grad_r(s.xi), mass_values=z
        )
        if self._n_edges is not None and len(self._n_edges):
            g -= neumann_shape_derivative(s.Q, self._n_edges, self._n_values, s.p)
        if self.tracking_text is not None:
            grad_yd = np.asarray(self._grad_yd(s.Q), dtype=float)
            g -= weight[:, None] * grad_yd
        return s.value, g

    def derivative(self, Q: FloatArray) -> FloatArray:
        """Exact derivative ``dj/dQ`` of shape ``(N, 2)`` (boundary nodes included), (6.12)."""
        return self.value_and_derivative(Q)[1]
