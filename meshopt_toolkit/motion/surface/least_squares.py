"""The one least-squares step of the surface motion (:mod:`.move`): an increment, a
minimizing movement

    min_Q  ½|Q − Q_prev|²_M + ½ Σ_t |r_t(Q)|² + ½ b Σ_e c_e (θ_e(Q) − θ̄_e)² + κ B(Q)

over the free vertices (handles fixed at the increment's end), ``r_t`` the membrane rows
of :class:`.distortion.SurfaceDistortion` weighed by ``row_weights`` from their anchor
``phi_ref``, the dihedral bending of :class:`.bending.ShellBending`, ``M`` the lumped
vertex areas and, with contact, IPC's barrier (:mod:`..engine.contact`).
Gauss–Newton on the stacked residuals: a linearized predictor carries the handles'
displacement into the free vertices (kept factor, then fresh; its fractions
:data:`PREDICTOR`), then steps on the normal equations (CHOLMOD, :mod:`.normal_equations`;
the factor kept while full steps are taken), each iterate accepted only where the energy
decreases, every triangle keeps ``det C > 0`` and none folds (:class:`.folds.FoldTest`);
every step, the predictor included, starts its backtracking at the fraction CCD allows.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator

from ..._typing import FloatArray
from ...descent import backtrack, halvings
from ...solvers import factorize_spd, pcg
from ..engine.contact import NoContact
from .bending import ShellBending
from .distortion import SurfaceDistortion
from .folds import FoldTest
from .normal_equations import FreePattern, turned_solve, upper_products

__all__ = ["PREDICTOR", "Problem", "solve_increment"]

#: the fractions of a fresh linearized predictor tried in turn (0: the handles alone)
PREDICTOR = (1.0, 0.0, 0.5, 0.25)


class Problem:
    """One increment's energy, residual Jacobian blocks and admissibility."""

    def __init__(self, V, F, handles, weight, bending, mass):
        self.membrane = SurfaceDistortion(V, F)
        self.shell = ShellBending(V, F)
        self.weight, self.bending, self.mass = weight, bending, mass
        self.folds = FoldTest(V, F)
        is_handle = np.zeros(len(V), bool)
        is_handle[handles] = True
        self.free_triangles = ~is_handle[F].all(axis=1)
        free_coord = np.repeat(~is_handle, 3)
        self.free_index = np.full(3 * len(V), -1)
        self.free_index[free_coord] = np.arange(int(free_coord.sum()))
        self.free = free_coord
        self.pattern = FreePattern([self.membrane.columns(), self.shell.columns()],
                                    self.free_index, int(free_coord.sum()))
        self.phi_ref = None
        self.previous = None
        self.factor, self.factor_signature = None, None
        self.fresh = False  # whether the factor is of the matrix at the current iterate
        self.factorizations = 0
        #: conjugate gradients on a kept factor: at most this many, to this relative residual
        self.cg_iterations, self.cg_rtol, self.cg_total = 0, 1e-2, 0
        #: ``w √c_t``: the membrane rows' weights (``c_t ≥ 1``, :func:`.move.move_surface`)
        self.row_weights = np.full(len(F), float(weight))
        #: the contact barrier on the free coordinates (:func:`..engine.contact.contact_term`)
        self.contact = NoContact()
        #: the iterate after this many steps of :func:`solve_increment` is kept in ``kept``
        self.keep_at, self.kept = None, None

    def parts(self, Q):
        phi = self.membrane.values(Q)
        rm = self.row_weights[:, None] * (phi - self.phi_ref)
        rb = np.sqrt(self.bending) * self.shell.residuals(Q)
        return phi, rm, rb

    def energy(self, Q, parts=None) -> float:
        phi, rm, rb = self.parts(Q) if parts is None else parts
        d = Q - self.previous
        return (0.5 * float(self.mass @ np.sum(d * d, axis=1) + np.sum(rm * rm) + rb @ rb)
                + self.contact.energy(Q))

    def admissible(self, Q, phi) -> bool:
        if not np.all(np.isfinite(phi[self.free_triangles])):
            return False
        return not np.any(self.folds.mask(Q) & self.free_triangles)

    def linearization(self, Q):
        """Residuals and Jacobian blocks: membrane (T, 3), (T, 3, 9); bending (E,), (E, 12)."""
        phi, Jm = self.membrane.values_and_jacobian(Q)
        Jm *= self.row_weights[:, None, None]
        rm = self.row_weights[:, None] * (phi - self.phi_ref)
        rb = np.sqrt(self.bending) * self.shell.residuals(Q)
        Jb = np.sqrt(self.bending) * self.shell.jacobian_blocks(Q)
        return rm, Jm, rb, Jb

    def jacobian_products(self, Jm, Jb, d: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``J d`` of a displacement ``d`` (N, 3): membrane (T, 3), bending (E,)."""
        flat = d.ravel()
        return (np.einsum("tij,tj->ti", Jm, flat[self.membrane.columns()]),
                np.einsum("ej,ej->e", Jb, flat[self.shell.columns()]))

    def normal_operator(self, Jm, Jb) -> LinearOperator:
        """``x ↦ (JᵀJ + M) x`` at the free coordinates, without assembly: the gradient of
        the residuals ``J x`` and the displacement ``x``."""
        m = int(self.free.sum())

        def apply(x: FloatArray) -> FloatArray:
            full = np.zeros(self.free.size)
            full[self.free] = np.ravel(x)
            d = full.reshape(-1, 3)
            rm, rb = self.jacobian_products(Jm, Jb, d)
            return self.gradient(rm, Jm, rb, Jb, d)

        return LinearOperator((m, m), matvec=apply, dtype=float)

    def gradient(self, rm, Jm, rb, Jb, displacement) -> FloatArray:
        """``Jᵀ r + M d`` at the free coordinates (d: ``Q − Q_prev``, (N, 3))."""
        n = self.free.size
        g = np.bincount(self.membrane.columns().ravel(),
                        np.einsum("tij,ti->tj", Jm, rm).ravel(), n)
        g += np.bincount(self.shell.columns().ravel(), (Jb * rb[:, None]).ravel(), n)
        g += np.repeat(self.mass, 3) * displacement.ravel()
        return g[self.free]

    def normal_matrix(self, Jm, Jb) -> sp.csr_matrix:
        """The lower triangle of ``JᵀJ + M`` at the free coordinates."""
        return self.pattern.matrix([upper_products(Jm), upper_products(Jb)],
                                   np.repeat(self.mass, 3)[self.free])

    def refactorize(self, Jm, Jb, Q) -> None:
        """Factorize ``JᵀJ + M`` at ``Q`` (``1e-6·diag`` added) on the kept analysis."""
        D = self.normal_matrix(Jm, Jb)
        diag = D.data[self.pattern.diagonal]
        D.data[self.pattern.diagonal] += 1e-6 * diag + 1e-12 * diag.max()
        if (H := self.contact.hessian(Q)) is not None:
            D = (D + sp.tril(H, format="csr")).tocsr()
        self.factorizations += 1
        if not hasattr(self.factor, "refactorize"):  # first call, or SuperLU
            self.factor = factorize_spd(D)
        else:
            self.factor.refactorize(D)
        self.fresh, self.factor_points = True, Q.copy()
        self.factor_signature = self.contact.signature(Q)

    def kept_step(self, Jm, Jb, g, Q) -> FloatArray:
        """A step ``≈ (JᵀJ + M)⁻¹ g`` at ``Q`` on the kept factor ``F``: its own solve where
        it is this matrix's; else ``cg_iterations`` conjugate gradients (or fewer, to the
        relative residual ``cg_rtol``) preconditioned by ``R F⁻¹ Rᵀ``, ``R`` each vertex's
        rotation since the factorization (the matrix turns with the surface: φ and the
        bending are rotation invariant); ``cg_iterations = 0``: ``F⁻¹ g``."""
        if self.fresh or self.cg_iterations == 0:
            self.fresh = False
            return self.factor(g)
        precondition = turned_solve(
            self.factor, self.folds.vertex_rotations(self.factor_points, Q)[self.free[::3]])
        A = self.normal_operator(Jm, Jb)
        try:
            x, its, _ = pcg(A, g, precondition, self.cg_rtol, self.cg_iterations)
        except FloatingPointError:  # not expected (both SPD): the turned factor's solve
            x, its = precondition(g), 1
        self.cg_total += its
        return x


def solve_increment(problem: Problem, Q0, H1, handles, max_iterations: int, rtol: float,
                    stall: float | None = None):
    """One increment from the admissible ``Q0`` to handles at ``H1``: the converged
    positions and the iterations, or None where no admissible predictor exists; the factor
    is kept while full steps are taken. ``stall=None``: renewed after every shortened step.
    A number: kept (chord steps) while each shortened step lowers the energy by at least
    ``stall`` times the first step on that factor and by more than ``rtol·E``; the increment
    ends where a full step, or one on a factor of its own linearization, lowers it by
    ``rtol·E`` or less. The iterate after ``problem.keep_at`` steps, if reached, is kept
    in ``problem.kept``."""
    d = np.zeros_like(Q0)
    d[handles] = H1 - Q0[handles]
    problem.kept = None
    if not problem.free.any():  # every vertex a handle: the step is the handles' path
        Q = Q0 + d
        Q[handles] = H1
        ok = problem.admissible(Q, problem.parts(Q)[0]) and problem.contact.clear(Q0, Q)
        return (Q, 0) if ok else None
    rm, Jm, rb, Jb = problem.linearization(Q0)
    # the residuals' change of the handles' displacement, to first order
    dm, db = problem.jacobian_products(Jm, Jb, d)
    g = problem.gradient(rm + dm, Jm, rb + db, Jb, np.zeros_like(Q0))
    # predictors, each admissible and clear: kept factor, fresh one, PREDICTOR's fractions
    kept = hasattr(problem.factor, "refactorize")
    for fresh, scales in (((False, (1.0,)),) if kept else ()) + ((True, PREDICTOR),):
        if fresh:
            problem.refactorize(Jm, Jb, Q0)
        step = problem.kept_step(Jm, Jb, g, Q0)
        for scale in scales:
            Q = Q0 + d
            Q.ravel()[problem.free] -= scale * step
            Q[handles] = H1
            parts = problem.parts(Q)
            if problem.admissible(Q, parts[0]) and problem.contact.clear(Q0, Q):
                break
        else:
            continue
        break
    else:
        return None
    if not np.isfinite(E := problem.energy(Q, parts)):
        return None
    iterations, stale, first = 0, not fresh, None
    for _ in range(max_iterations):
        rm, Jm, rb, Jb = problem.linearization(Q)
        g = problem.gradient(rm, Jm, rb, Jb, Q - problem.previous)
        if problem.contact.set_stiffness(Q, g):  # κ set: the energy gains the barrier
            E = problem.energy(Q)
        g = g + problem.contact.gradient(Q)
        # the factor is renewed where the barrier's pairs or κ are not those it holds
        stale = stale or problem.contact.signature(Q) != problem.factor_signature
        renewed = stale
        if stale:  # otherwise the factor of the increment's start serves (chord steps)
            problem.refactorize(Jm, Jb, Q)
            first = None
        step = problem.kept_step(Jm, Jb, g, Q)
        iterations += 1
        def at(alpha: float):  # from the CCD bound: lower, every triangle proper, unfolded
            trial = Q.copy()
            trial.ravel()[problem.free] -= alpha * step
            parts = problem.parts(trial)
            if not np.all(np.isfinite(parts[0][problem.free_triangles])):
                return None
            E_trial = problem.energy(trial, parts)
            ok = E_trial < E and problem.admissible(trial, parts[0])
            return (trial, E_trial) if ok else None

        found = backtrack(at, halvings(problem.contact.step_cap(Q, step), count=12))
        if found is None:
            if stale:
                break
            stale = True
            continue
        alpha, (trial, E_trial) = found
        decrease = E - E_trial
        Q, E = trial, E_trial
        if iterations == problem.keep_at:  # this iterate kept: a candidate of the caller
            problem.kept = Q.copy()
        if stall is None:
            if decrease <= rtol * E:
                break
            stale = alpha < 1.0
            continue
        # small decreases converge only from full steps or renewed factors (not old chords)
        if decrease <= rtol * E and (renewed or alpha == 1.0):
            break
        first = decrease if first is None else first
        stale = decrease <= rtol * E or (alpha < 1.0 and decrease < stall * first)
    return (Q, iterations) if problem.contact.embedded(Q) else None
