"""Solves of the Taylor–Hood Stokes system ``[[A, Bᵀ], [B, 0]] (u, p) = (f, g)`` on the free
velocity dofs and the kept pressures, by size (:func:`stokes_method`):

* ``"direct"``: CHOLMOD's factor of the velocity block ``A`` (nested-dissection ordering
  in 2D, CHOLMOD's own in 3D), CG on the pressure's Schur complement ``B A⁻¹ Bᵀ``
  preconditioned by the pressure mass over the viscosity (consistent P1 mass, factorized);
* ``"minres"``: MINRES with the block-diagonal preconditioner ``diag(L⁻¹ ⊗ I, μ M⁻¹)``:
  ``L`` the scalar P2 Laplacian ``μ ∫ ∇φ·∇ψ`` on the free nodes (one CHOLMOD factor, a
  third the size of ``A`` and far less fill), applied to each velocity component, ``M``
  the consistent pressure mass. ``A`` (``2μ ε:ε``) and ``μ ∇:∇`` are spectrally equivalent
  (Korn) and ``M/μ`` is spectrally equivalent to the Schur complement, so the iteration
  count stays bounded as the mesh is refined;
* ``"amg"``: the same MINRES with a pyamg V-cycle of ``A`` instead of ``L``'s factor.

The velocity block's factor costs most in 3D (its fill grows like the square of the
unknowns): the 3D rule switches to MINRES from :data:`MINRES_FROM_3D` unknowns
(``docs/shape-optimization.md``, "Stokes solves in 3D").
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..solvers import (Solve, choose_method, factorize_spd, import_pyamg, minres_block_solve,
                       nested_dissection, schur_complement_solve, v_cycle_precondition)
from .simplex import Geometry, LagrangeSpace, assemble

__all__ = ["MINRES_FROM_3D", "STOKES_AMG_THRESHOLD", "STOKES_SOLVERS", "pressure_mass",
           "scalar_laplacian", "stokes_method", "stokes_saddle_solve"]

#: ``solver="auto"`` uses MINRES with AMG from this many unknowns
STOKES_AMG_THRESHOLD = 200_000
#: ``solver="auto"`` in 3D uses MINRES over the scalar Laplacian's factor from this many
#: unknowns (about 4,000 tets of the drag benchmark's grading), the direct solve below
MINRES_FROM_3D = 20_000
STOKES_SOLVERS = ("auto", "direct", "minres", "amg")


def stokes_method(solver: str, n_unknowns: int, dim: int) -> str:
    """``"direct"``, ``"minres"`` or ``"amg"`` for ``solver`` (one of
    :data:`STOKES_SOLVERS`) on a system of ``n_unknowns`` in ``dim`` dimensions."""
    if solver == "minres":
        return solver
    method = choose_method(solver, n_unknowns, STOKES_AMG_THRESHOLD)
    if solver == "auto" and method == "direct" and dim == 3 and n_unknowns >= MINRES_FROM_3D:
        return "minres"
    return method


def pressure_mass(geo: Geometry, cells: IntArray, n: int) -> sp.csr_matrix:
    """The consistent P1 mass matrix ``∫ φ_a φ_b`` ``(n, n)``."""
    k = cells.shape[1]
    local = (np.ones((k, k)) + np.eye(k)) / ((k + 1) * k)  # ∫ λ_a λ_b / |K|
    return assemble(cells, cells, geo.volumes[:, None, None] * local, (n, n)).tocsr()


def scalar_laplacian(space: LagrangeSpace, geo: Geometry, mu: float) -> sp.csr_matrix:
    """``μ ∫ ∇φ_a·∇φ_b`` over ``space``'s scalar basis ``(n_dofs, n_dofs)``."""
    G = space.gradients(geo)  # (T, Q, nb, d)
    local = mu * np.einsum("q,tqae,tqbe->tab", space.reference[2], G, G)
    local *= geo.volumes[:, None, None]
    return assemble(space.cell_dofs, space.cell_dofs, local, (space.n_dofs,) * 2).tocsr()


def _componentwise(solve: Solve, d: int) -> Solve:
    """``r ↦ (L⁻¹ r_x, L⁻¹ r_y, …)`` on interleaved vector dofs (one solve of ``d``
    right-hand sides)."""
    def apply(r: FloatArray) -> FloatArray:
        return np.asarray(solve(r.reshape(-1, d))).ravel()
    return apply


def stokes_saddle_solve(method: str, A: sp.csr_matrix, B: sp.csr_matrix, mass: sp.csr_matrix,
                        mu: float, rtol: float, *, space: LagrangeSpace, geo: Geometry,
                        free_nodes: IntArray, node_points: FloatArray) -> Solve:
    """``b ↦ (u, p)`` for ``[[A, Bᵀ], [B, 0]]`` with the relative residual ``rtol``.

    Parameters
    ----------
    method : ``"direct"``, ``"minres"`` or ``"amg"`` (module docstring)
    A : (d m, d m) velocity block on the free nodes' dofs (``d`` interleaved per node)
    B : (n_p, d m) divergence block on the kept pressures
    mass : (n_p, n_p) pressure mass on the kept pressures (:func:`pressure_mass`)
    mu : viscosity
    rtol : relative residual ``‖b − K x‖ / ‖b‖`` (of the Schur complement's system for
        ``"direct"``)
    space, geo : the P2 space and geometry (for ``"minres"``'s Laplacian)
    free_nodes : (m,) the P2 nodes whose velocity is free
    node_points : (m, d) their positions (the 2D nested-dissection ordering)
    """
    d = geo.dim
    dual = factorize_spd(sp.csc_matrix(mass / mu))
    if method == "direct":
        order = nested_dissection(node_points, A, block=d) if d == 2 else None
        return schur_complement_solve(factorize_spd(A, order), B, dual, rtol)
    K = sp.bmat([[A, B.T], [B, None]], format="csr")
    if method == "minres":
        L = scalar_laplacian(space, geo, mu)[free_nodes][:, free_nodes]
        primal = _componentwise(factorize_spd(sp.csc_matrix(L)), d)
    else:
        primal = v_cycle_precondition(import_pyamg().smoothed_aggregation_solver(A.tocsr()))
    return minres_block_solve(K, A.shape[0], primal, dual, rtol)

