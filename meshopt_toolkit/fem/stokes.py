"""Stokes flow by Taylor–Hood P2–P1 elements on triangles and tetrahedra, and the
dissipation objective with its exact node derivative.

Find the velocity ``u`` (P2, ``u = g`` on the Dirichlet facet groups) and pressure ``p``
(P1) with ``∫ 2μ ε(u):ε(v) − ∫ p div v = 0`` for every ``v`` vanishing on the Dirichlet
facets and ``−∫ q div u = 0`` for every ``q``; in matrices ``A u + Bᵀp = 0`` (free rows),
``B u = 0``. Where every boundary facet is Dirichlet ``p`` is unique up to a constant:
one pressure node is fixed and ``p`` is returned with zero mean.

The dissipation ``J = ∫ 2μ |ε(u)|² = uᵀ A u`` (for a body moved at unit speed through
fluid at rest, its drag) is the minimum of ``uᵀAu`` over the divergence-free ``u`` with
the Dirichlet data, so with the Lagrangian ``ℒ = uᵀAu + 2 pᵀ B u`` the adjoint of ``J``
is the state itself: adjoint velocity ``0`` and adjoint pressure ``2p`` solve the adjoint
system ``A w + Bᵀq = 2 Bᵀp − 2(Au + Bᵀp) = 2Bᵀp``, ``B w = 0``. For Dirichlet values
constant per group (attached to the nodes), ``dJ/dx = ∂_x ℒ`` at fixed ``(u, p)``, whose
Eshelby tensor (:mod:`.simplex`) is, per cell, with ``G = ∇u`` and ``σ = 2μ ε(u)``,

``S = |K| Σ_q w_q [(σ:G) I − 2 Gᵀσ − 2 p tr G I + 2 p Gᵀ]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..errors import MeshoptError
from .linear_elasticity import strain_energy_tensor, vector_dofs, vector_stiffness
from .cached import CachedObjective, SimplexState
from .simplex import (Geometry, LagrangeSpace, all_boundary_facets, assemble, geometry,
                      node_gradient)
from .stokes_solver import STOKES_SOLVERS, pressure_mass, stokes_method, stokes_saddle_solve

__all__ = ["StokesDissipation"]

@dataclass
class _State(SimplexState):
    u: FloatArray  # (n2, d)
    p: FloatArray  # (N,)
    value: float


class StokesDissipation(CachedObjective):
    """``J = ∫ 2μ |ε(u)|²`` of the Stokes flow with Dirichlet velocities per facet group.

    Parameters
    ----------
    points : (N, d) reference positions
    cells : (T, d+1) positive simplices
    dirichlet : sequence of ``(facets (F, d), value)``: ``u = value`` on the facets' P2
        nodes, a constant ``(d,)`` vector or a callable ``(M, d) → (M, d)`` of the nodes'
        current positions (a later group wins at shared nodes)
    mu : viscosity
    solver : ``"direct"`` (the velocity block's factor, CG on the pressure's Schur
        complement), ``"minres"`` (MINRES preconditioned by the scalar Laplacian's factor
        and the pressure mass), ``"amg"`` (MINRES with a V-cycle of the velocity block) or
        ``"auto"`` (by size: :func:`.stokes_solver.stokes_method`)
    rtol : relative residual of CG on the Schur complement or of MINRES

    Notes
    -----
    :meth:`derivative` is exact for constant Dirichlet values; with a callable value it
    raises (the data's own motion is not differentiated).
    """

    def __init__(self, points: FloatArray, cells: IntArray, dirichlet, *, mu: float = 1.0,
                 solver: str = "auto", rtol: float = 1e-10) -> None:
        points = np.asarray(points, dtype=float)
        self.cells = np.asarray(cells, dtype=np.int64)
        self.dim = d = points.shape[1]
        if not mu > 0:
            raise MeshoptError(f"the viscosity must be > 0, got {mu}")
        self.mu = float(mu)
        self.space = LagrangeSpace(self.cells, len(points), degree=2)
        self._groups = []
        for facets, value in dirichlet:
            dofs = np.unique(self.space.facet_dofs(np.asarray(facets, dtype=np.int64)))
            if not callable(value):
                value = np.asarray(value, dtype=float)
                if value.shape != (d,) or not np.isfinite(value).all():
                    raise MeshoptError(f"a Dirichlet velocity is a finite vector of {d} components")
            self._groups.append((dofs, value))
        if not self._groups:
            raise MeshoptError("the Stokes problem needs Dirichlet velocities")
        fixed = np.unique(np.concatenate([g[0] for g in self._groups]))
        self.dirichlet = vector_dofs(fixed, d).ravel()
        bnd = self.space.facet_dofs(all_boundary_facets(self.cells))
        self.fix_pressure = bool(np.isin(bnd, fixed).all())
        self.constant_data = not any(callable(g[1]) for g in self._groups)
        n_unknowns = d * self.space.n_dofs + len(points)
        if solver not in STOKES_SOLVERS:
            raise ValueError(f"solver must be one of {STOKES_SOLVERS}, got {solver!r}")
        self.method = stokes_method(solver, n_unknowns, d)
        self.rtol = float(rtol)

    def _lift(self, Q: FloatArray) -> FloatArray:
        g = np.zeros((self.space.n_dofs, self.dim))
        X = self.space.dof_points(Q)
        for dofs, value in self._groups:
            g[dofs] = np.asarray(value(X[dofs]), dtype=float) if callable(value) else value
        return g.ravel()

    def matrices(self, Q: FloatArray, geo: Geometry | None = None
                 ) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """The velocity block ``A`` ``(d n2, d n2)`` and the divergence ``B`` ``(N, d n2)``."""
        geo = geometry(Q, self.cells) if geo is None else geo
        d, n2 = self.dim, self.space.n_dofs
        vdofs = vector_dofs(self.space.cell_dofs, d)
        A = assemble(vdofs, vdofs, vector_stiffness(self.space, geo, 0.0, self.mu), (d * n2,) * 2)
        lam, w = self.space.reference[3], self.space.reference[2]
        g = self.space.gradients(geo)  # (T, Q, nb, d)
        local = -np.einsum("q,qa,tqbe->tabe", w, lam, g) * geo.volumes[:, None, None, None]
        B = assemble(self.cells, vdofs, local.reshape(len(self.cells), d + 1, -1),
                     (len(Q), d * n2))
        return A, B

    def _solve(self, Q: FloatArray, geo: Geometry) -> tuple[FloatArray, FloatArray, sp.csr_matrix]:
        """Velocity ``(d n2,)``, pressure ``(N,)`` and the velocity block ``A``."""
        A, B = self.matrices(Q, geo)
        nv, n_p = A.shape[0], B.shape[0]
        g = self._lift(Q)
        free_v = np.setdiff1d(np.arange(nv), self.dirichlet)
        keep_p = np.arange(1 if self.fix_pressure else 0, n_p)
        Aff = A[free_v][:, free_v]
        Bf = B[keep_p][:, free_v]
        rhs = -np.concatenate([(A @ g)[free_v], (B @ g)[keep_p]])
        mass = pressure_mass(geo, self.cells, n_p)
        nodes = free_v[::self.dim] // self.dim  # whole nodes: Dirichlet fixes all components
        x = stokes_saddle_solve(self.method, Aff, Bf, mass[keep_p][:, keep_p], self.mu,
                                self.rtol, space=self.space, geo=geo, free_nodes=nodes,
                                node_points=self.space.dof_points(Q)[nodes])(rhs)
        u = g.copy()
        u[free_v] = x[:len(free_v)]
        p = np.zeros(n_p)
        p[keep_p] = x[len(free_v):]
        if self.fix_pressure:
            p -= (mass @ p).sum() / mass.sum()
        return u, p, A

    def _compute(self, Q) -> _State:
        Q = np.array(Q, dtype=float)
        geo = geometry(Q, self.cells)
        u, p, A = self._solve(Q, geo)
        return _State(Q, geo, u.reshape(-1, self.dim), p, float(u @ (A @ u)))

    def velocity(self, Q: FloatArray) -> FloatArray:
        """Nodal velocities ``(n2, d)``: vertices, then edge midpoints."""
        return self._state(Q).u.copy()

    def pressure(self, Q: FloatArray) -> FloatArray:
        """Nodal pressures ``(N,)`` (zero mean where every boundary facet is Dirichlet)."""
        return self._state(Q).p.copy()

    def derivative(self, Q: FloatArray) -> FloatArray:
        """Exact ``dJ/dQ`` ``(N, d)`` for constant Dirichlet values (module docstring)."""
        if not self.constant_data:
            raise MeshoptError("the dissipation's derivative needs constant Dirichlet velocities")
        s = self._state(Q)
        S = strain_energy_tensor(self.space, s.geo, s.u, 0.0, self.mu)
        G = np.einsum("tqbj,tbi->tqij", self.space.gradients(s.geo), s.u[self.space.cell_dofs])
        pq = np.einsum("qa,ta->tq", self.space.reference[3], s.p[self.cells])
        tr = np.trace(G, axis1=2, axis2=3)
        per_q = 2.0 * pq[..., None, None] * (G.transpose(0, 1, 3, 2)
                                             - tr[..., None, None] * np.eye(self.dim))
        S += np.einsum("q,tqij->tij", self.space.reference[2], per_q) * s.geo.volumes[:, None, None]
        return node_gradient(S, s.geo, self.cells, len(s.Q))
