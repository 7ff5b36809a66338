"""Least squares of the tet distortion with fixed vertices: the one solver of the
tet motion (:mod:`.move`), for its continuation steps and its quality rounds.

It minimizes

    E(Q) = ½ Σ_i m_i |Q_i − P_i|² + ½ w² Σ_c ω_c |φ_c(Q) − a_c|²

over the free vertices (``P`` the proximal centre, ``a`` the anchor distortion, ``ω`` the
tet weights) by Newton (the residual curvature taken on the tets far from their anchor;
Gauss–Newton where that matrix is not positive definite; optionally each tet's block
projected onto the positive semidefinite cone instead): the undamped configuration of
the package's one Gauss–Newton step (:func:`...least_squares.damped_step`), backtracking
(:func:`...descent.halvings`) over trials that lower ``E`` enough: ``E`` is ``+inf``
where a tet is inverted, so every accepted iterate has every tet positively oriented. The
sparse matrices are lower triangles on a pattern built once
(:class:`..engine.sparse_pattern.FreePattern`), factorized by CHOLMOD on a kept analysis.

With a contact term (:mod:`.contact`) ``E`` gains ``κ B(Q)``, the IPC barrier of the
boundary: its gradient and PSD-projected Hessian join the Gauss–Newton equations where a
pair is within ``d̂`` (a matrix of its own pattern, factorized afresh), and every trial
of the line search starts at the fraction of the step that CCD finds free of contact.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...descent import halvings, sufficient_decrease
from ...least_squares import damped_step
from ...solvers import cholesky_spd, cholmod_available, factorize_spd, pcg
from ..engine.contact import NoContact
from ..engine.sparse_pattern import FreePattern
from .distortion import TetDistortion


class Factor:
    """A kept sparse Cholesky factorization (CHOLMOD, refactorized on its analysis), or a
    fresh SuperLU factorization per matrix where CHOLMOD is not installed; ``solve`` is
    the last successful one. A matrix is factorized into a second factor (analysed once),
    which replaces the kept one only where it succeeds: a matrix found not positive
    definite leaves the kept one to precondition the next steps."""

    def __init__(self) -> None:
        self._chol = None
        self._spare = None
        self.solve = None

    def __call__(self, lower: sp.csc_matrix):
        """Factorize the SPD matrix whose lower triangle is ``lower``; returns its solve.
        Raises RuntimeError where it is not positive definite (``solve`` unchanged)."""
        if not cholmod_available():
            full = lower + sp.tril(lower, -1).T
            self.solve = factorize_spd(full.tocsc())
        elif self._spare is None:
            self._spare = cholesky_spd(lower)
            self._chol, self._spare = self._spare, self._chol
            self.solve = self._chol
        else:
            self._spare.refactorize(lower)
            self._chol, self._spare = self._spare, self._chol
            self.solve = self._chol
        return self.solve


def _restricted(strain: TetDistortion, cells: IntArray) -> TetDistortion:
    """The same distortion on a subset of the tets (shares the reference)."""
    out = copy.copy(strain)
    out.tets, out.gradients = strain.tets[cells], strain.gradients[cells]
    return out


def _psd(blocks: FloatArray) -> FloatArray:
    """Each symmetric block with its negative eigenvalues set to zero (projected Newton:
    the assembled matrix stays positive definite)."""
    lam, V = np.linalg.eigh(blocks)
    return np.matmul(V * np.maximum(lam, 0.0)[:, None, :], np.swapaxes(V, 1, 2))


@dataclass
class Problem:
    """The least-squares problem: distortion, metric weight, lumped masses, free
    coordinates and their pattern."""

    strain: TetDistortion
    weight: float
    mass: FloatArray  # (N,)
    pattern: FreePattern
    factor: Factor
    #: Newton's curvature term is taken on the tets whose weighted residual exceeds this
    #: times its root mean square (0: all)
    newton_threshold: float = 1.0
    #: project each tet's Newton block onto the PSD cone (False: the exact Hessian, and
    #: Gauss–Newton where it is not positive definite; without the projection, fewer
    #: iterations to the same worst mean ratio)
    project: bool = False
    #: steps solved by conjugate gradients to this relative residual, preconditioned by
    #: the kept factorization (0: a factorization per step; the same iterations and worst
    #: mean ratio, in less time)
    cg_rtol: float = 0.1
    cg_maxiter: int = 25

    @classmethod
    def build(cls, strain: TetDistortion, weight: float, mass: FloatArray,
              fixed_vertices: IntArray) -> Problem:
        free = np.ones((len(mass), 3), bool)
        free[fixed_vertices] = False
        return cls(strain, float(weight), np.asarray(mass, float),
                   FreePattern(strain.columns(), free.ravel()), Factor())

    def energy(self, Q: FloatArray, centre: FloatArray, anchor: FloatArray,
               cell_weights: FloatArray) -> float:
        phi = self.strain.values(Q)
        if not np.isfinite(phi).all():
            return np.inf
        d = np.sum((phi - anchor) ** 2, axis=1)
        move = float(self.mass @ np.sum((Q - centre) ** 2, axis=1))
        return 0.5 * move + 0.5 * self.weight**2 * float(cell_weights @ d)

    def normal_equations(self, Q: FloatArray, centre: FloatArray, anchor: FloatArray,
                         cell_weights: FloatArray, newton: bool):
        """Gradient over the free coordinates and the lower triangles of the Gauss–Newton
        matrix and (with ``newton``) of the projected Newton matrix: ``w² ω_c (J_cᵀJ_c +
        (φ_c − a_c)·∇²φ_c)`` projected onto the PSD cone per tet, where the residual is
        large (see ``newton_threshold``)."""
        phi, jb = self.strain.values_and_jacobian(Q)
        res = (phi - anchor) * (self.weight**2 * cell_weights)[:, None]
        cols = self.strain.columns()
        back = np.matmul(res[:, None, :], jb)[:, 0]  # J_cᵀ r_c
        g = np.bincount(cols.ravel(), back.ravel(), minlength=Q.size)
        g += (self.mass[:, None] * (Q - centre)).ravel()
        blocks = np.matmul(np.swapaxes(jb, 1, 2) * (self.weight**2 * cell_weights)[:, None, None],
                           jb)
        diag = np.repeat(self.mass, 3)[self.pattern.free]
        gn = self.pattern.matrix(blocks, diag)
        full = None
        if newton:
            # the residual curvature of the tets far from their anchor only: the others'
            # is small against their JᵀJ, and it is the costly part of an iteration
            size = np.linalg.norm(res, axis=1)
            cells = np.flatnonzero(size > self.newton_threshold * np.sqrt(np.mean(size**2)))
            blocks[cells] += _restricted(self.strain, cells).second_order(Q, res[cells])
            if self.project:
                blocks[cells] = _psd(blocks[cells])
            full = self.pattern.matrix(blocks, diag)
        return g[self.pattern.free], gn, full

    def solve_step(self, lower: sp.csc_matrix, rhs: FloatArray, *,
                   maybe_indefinite: bool = False, fresh: bool = False) -> FloatArray:
        """Solve with the matrix of lower triangle ``lower``: by conjugate gradients
        preconditioned with the kept factorization of an earlier matrix where they reach
        ``cg_rtol`` within ``cg_maxiter`` iterations, else by factorizing it.

        With ``maybe_indefinite``, a direction of non-positive curvature met by the
        conjugate gradients raises RuntimeError at once (the matrix is not positive
        definite: its factorization would fail, and the kept one would be lost).
        With ``fresh`` (a matrix off the kept pattern: the contact barrier's) a
        factorization is made for this matrix alone, the kept one unchanged."""
        if self.cg_rtol > 0 and self.factor.solve is not None:
            d = lower.diagonal()
            upper = lower.T.tocsr()
            operator = _Symmetric(lower.tocsr(), upper, d)
            try:
                x, _, rel = pcg(operator, rhs, self.factor.solve, self.cg_rtol,
                                self.cg_maxiter)
                if rel <= self.cg_rtol:
                    return x
            except FloatingPointError as exc:
                if maybe_indefinite and "pᵀAp" in str(exc):  # not "non-finite"
                    raise RuntimeError("the matrix is not positive definite") from exc
        return (Factor() if fresh else self.factor)(lower)(rhs)


@dataclass
class _Symmetric:
    lower: sp.csr_matrix
    upper: sp.csr_matrix
    diagonal: FloatArray

    def __matmul__(self, x: FloatArray) -> FloatArray:
        return self.lower @ x + self.upper @ x - self.diagonal * x


@dataclass
class Minimized:
    points: FloatArray
    iterations: int
    energy: float
    gradient_ratio: float


def minimize(problem: Problem, Q: FloatArray, centre: FloatArray, anchor: FloatArray,
             cell_weights: FloatArray | None = None, *, rtol: float = 1e-2, gtol: float = 1e-10,
             max_iterations: int = 20, newton: bool = False, contact=None) -> Minimized:
    """Minimize ``E`` from the admissible ``Q`` (its fixed coordinates kept bitwise).

    Stops when the free gradient fell by ``rtol`` (or below ``gtol``), after ``max_iterations``
    iterations, or when no step along the (Gauss–)Newton direction lowers ``E``. Once the
    Newton matrix is found not positive definite (or its step not a descent direction),
    the remaining iterations take Gauss–Newton steps without trying it again: it rarely
    becomes definite again within a few iterations, and each failed factorization costs
    as much as a successful one.

    ``contact``: a :class:`..engine.contact.ContactTerm` on the problem's free coordinates (its
    ``κ`` set and raised here by IPC's rule); None: none. Where a pair is within ``d̂``
    the step is Gauss–Newton's with the barrier's Hessian.
    """
    contact = NoContact() if contact is None else contact
    Q = np.array(Q, float)
    w = np.ones(len(problem.strain.tets)) if cell_weights is None else np.asarray(cell_weights)
    E = problem.energy(Q, centre, anchor, w) + contact.energy(Q)
    if not np.isfinite(E):
        raise ValueError("the start of a tet least-squares problem must be admissible")
    free = problem.pattern.free
    g0 = None
    ratio = 1.0
    for it in range(max_iterations):
        g, gn, full = problem.normal_equations(Q, centre, anchor, w, newton)
        if contact.set_stiffness(Q, g):  # κ set or raised: the energy changes
            E = problem.energy(Q, centre, anchor, w) + contact.energy(Q)
        barrier = contact.hessian(Q)
        if barrier is not None:
            g = g + contact.gradient(Q)
            gn, full = (gn + sp.tril(barrier)).tocsc(), None
        gnorm = float(np.linalg.norm(g))
        g0 = gnorm if g0 is None else g0
        ratio = gnorm / g0 if g0 > 0 else 0.0
        if gnorm <= gtol or ratio <= rtol:
            return Minimized(Q, it, E, ratio)

        def solve(damping: float, attempt: int, g=g, gn=gn, full=full, barrier=barrier):
            nonlocal newton
            step = None
            if full is not None:
                try:
                    step = -problem.solve_step(full, g, maybe_indefinite=True)
                    if step @ g >= 0:
                        step = None
                except RuntimeError:  # not positive definite: Gauss–Newton
                    step = None
                newton = step is not None  # from now on Gauss–Newton where it failed
            if step is None:
                step = -problem.solve_step(gn, g, fresh=barrier is not None)
            return step

        def try_step(step: FloatArray, t: float, Q=Q, E=E, g=g):
            trial = Q.copy()
            trial.reshape(-1)[free] += t * step
            Et = problem.energy(trial, centre, anchor, w)
            if np.isfinite(Et):
                Et += contact.energy(trial)
            return (trial, Et) if sufficient_decrease(Et, E, t, float(step @ g)) else None

        # undamped: one step, backtracked from the contact's cap
        found = damped_step(solve, try_step, 0.0,
                            lengths=lambda step, Q=Q: halvings(contact.step_cap(Q, -step),
                                                               count=40))
        if not found.accepted:
            return Minimized(Q, it, E, ratio)
        Q, E = found.payload
    return Minimized(Q, max_iterations, E, ratio)


def extend(problem: Problem, Q: FloatArray, handles: IntArray,
           positions: FloatArray) -> FloatArray:
    """``Q`` with the ``handles`` at ``positions`` and the free vertices moved by the
    linearized metric: ``δ_f = −H_ff⁻¹ H_fh δ_h``, ``H = M + w² JᵀJ`` at ``Q`` (``M`` is
    diagonal, so ``H_fh δ_h = w² (JᵀJ δ_h)_f``)."""
    delta = np.zeros_like(Q)
    delta[handles] = positions - Q[handles]
    _, jb = problem.strain.values_and_jacobian(Q)
    cols = problem.strain.columns()
    strain = np.matmul(jb, delta.reshape(-1)[cols][:, :, None])  # J_c δ_c
    back = np.matmul(np.swapaxes(jb, 1, 2), strain)[:, :, 0] * problem.weight**2
    rhs = -np.bincount(cols.ravel(), back.ravel(), minlength=Q.size)[problem.pattern.free]
    blocks = np.matmul(np.swapaxes(jb, 1, 2), jb) * problem.weight**2
    lower = problem.pattern.matrix(blocks, np.repeat(problem.mass, 3)[problem.pattern.free])
    out = Q.copy()
    out.reshape(-1)[problem.pattern.free] += problem.solve_step(lower, rhs)
    out[handles] = positions
    return out
