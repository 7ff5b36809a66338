"""Handles pulled along their path instead of placed on it: the surface motion's
increments (:mod:`.move`) from the point where the handles' prescribed path runs into a
free part of the surface, IPC's augmented Lagrangian for prescribed boundary motion
(Li et al. 2020, §4).

The handles become unknowns with the free vertices, pulled to their increment's targets
``x̂`` by

    P(Q) = κ_a/2 Σ_h m_h |x_h − x̂_h|² − Σ_h √m_h λ_hᵀ (x_h − x̂_h)

added to the increment's energy, every step capped by CCD over the whole surface (the
handles included): no iterate passes through the surface, the handles stop at what is in
their way and slide along it. An increment is a sequence of solves (rounds of
``ROUND_ITERATIONS`` Gauss–Newton steps) with IPC's schedule between them: a round that
used all its steps and brought the handles at least 1 % closer is not at a minimizer and
the next goes on with the same ``κ_a`` and ``λ``; at a minimizer ``κ_a`` is doubled while
the handles' progress ``η = 1 − |x − x̂|_m / |x⁰ − x̂|_m`` over the increment is below
0.99, else the multipliers are updated, ``λ ← λ − κ_a √m (x − x̂)``. An intermediate
increment ends at ``η ≥ 0.99`` (or after ``ROUNDS``) and keeps the handles where the pull
leaves them. The last one goes on (``FINAL_ROUNDS``; ended where two rounds in a row bring
the handles less than 1 % closer) until their straight remaining step, the rest still, is
clear of the surface and the ordinary increment (handles fixed) from there places them
exactly, its steps checked by CCD. Where they do not get there the motion is refused.
Targets whose handles alone make the surface intersect itself
(:func:`placed_targets_problem`) are refused before any increment.

The mode is entered only where an ordinary increment fails and either the handles' own
prescribed step is not clear of the surface or the increment cannot be halved further;
motions that never need it are unchanged bit for bit.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...errors import NotAdmissibleError
from ...kernels.intersections3d import self_intersections
from ...solvers import factorize_spd
from ..engine.contact import ContactTerm

__all__ = ["HandlePenalty", "HandlePull", "PulledContact", "placed_targets_problem",
           "require_placeable"]

#: ``κ_a`` at entry over the mean diagonal of the normal matrix at the handles over their mass
KAPPA_START = 10.0
#: the largest ``κ_a`` over its value at entry
KAPPA_GROWTH = 1e3
#: augmented-Lagrangian rounds of an intermediate increment and of the last one
ROUNDS, FINAL_ROUNDS = 4, 64
#: IPC's progress ``η`` of the handles towards their targets below which ``κ_a`` doubles
#: (else the multipliers are updated); an intermediate increment ends at it
PROGRESS = 0.99
#: a round of the last increment stalls where the handles' weighted distance to their
#: targets stays above this fraction of the last one; two in a row end the pull
STALL = 0.99
#: the Gauss–Newton iterations of one round
ROUND_ITERATIONS = 8


def placed_targets_problem(triangles: IntArray, handles: IntArray, targets: FloatArray,
                           n: int) -> str | None:
    """Why no motion of the free vertices keeps the surface from intersecting itself with
    the handles at ``targets``, or None: two triangles whose every vertex is a handle
    (placed by the targets alone) intersect there, or such an edge meets such a triangle
    with which it shares no vertex (exact, :func:`...kernels.intersections3d.
    self_intersections`; an edge is a flat triangle on a copy of its end)."""
    F = np.asarray(triangles, np.int64)
    placed = np.zeros(n, bool)
    placed[handles] = True
    faces = np.flatnonzero(placed[F].all(axis=1))
    E = np.unique(np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    E = E[placed[E].all(axis=1)]
    if len(faces) + len(E) < 2:
        return None
    P = np.zeros((n + len(E), 3))
    P[handles] = targets
    P[n:] = P[E[:, 1]]  # the copies of the edges' ends
    flat = np.c_[E, n + np.arange(len(E))]
    G = np.vstack([F[faces], flat])
    pairs = self_intersections(P, G)
    ends = np.vstack([F[faces], np.c_[E, E[:, 1]]])[pairs]  # (k, 2, 3) original vertices
    pairs = pairs[~(ends[:, 0, :, None] == ends[:, 1, None, :]).any(axis=(1, 2))
                  | (pairs < len(faces)).all(axis=1)]
    if not len(pairs):
        return None

    def name(k: int) -> str:
        return (f"triangle {faces[k]} {tuple(F[faces[k]].tolist())}" if k < len(faces)
                else f"edge {tuple(E[k - len(faces)].tolist())}")

    i, j = pairs[0]
    return (f"the handles' targets alone make the surface intersect itself ({len(pairs)} "
            f"pairs of triangles and edges whose every vertex is a handle; {name(i)} and "
            f"{name(j)})")


def require_placeable(contact, triangles: IntArray, handles: IntArray,
                      targets: FloatArray) -> None:
    """Refuse, before any increment, a motion with ``contact`` (a :class:`ContactTerm`)
    whose targets alone make the surface intersect itself (:func:`placed_targets_problem`;
    :class:`NotAdmissibleError` naming a pair)."""
    if isinstance(contact, ContactTerm) and (why := placed_targets_problem(
            triangles, handles, targets, contact.contact.n)):
        raise NotAdmissibleError(why)


class HandlePenalty:
    """``P(Q)`` (module docstring) on the flattened coordinates of ``n`` vertices.

    Parameters
    ----------
    handles : (H,) int array
    mass : (N,) float array
        The vertex masses ``m``.
    kappa : float
        ``κ_a``.
    """

    def __init__(self, handles: IntArray, mass: FloatArray, kappa: float) -> None:
        self.n = len(mass)
        self.handles = np.asarray(handles, np.int64)
        self.mass = np.asarray(mass, float)[self.handles]
        self.kappa = float(kappa)
        self.targets = np.zeros((len(self.handles), 3))
        self.multipliers = np.zeros((len(self.handles), 3))

    def gap(self, Q: FloatArray) -> FloatArray:
        """``x_h − x̂_h`` (H, 3)."""
        return np.asarray(Q).reshape(-1, 3)[self.handles] - self.targets

    def distance(self, Q: FloatArray) -> float:
        """``(Σ_h m_h |x_h − x̂_h|²)^½``."""
        g = self.gap(Q)
        return float(np.sqrt(self.mass @ np.sum(g * g, axis=1)))

    def value(self, Q: FloatArray) -> float:
        g = self.gap(Q)
        return float(0.5 * self.kappa * self.mass @ np.sum(g * g, axis=1)
                     - np.sum(np.sqrt(self.mass)[:, None] * self.multipliers * g))

    def gradient(self, Q: FloatArray) -> FloatArray:
        """(3N,) over ``Q.ravel()``."""
        out = np.zeros((self.n, 3))
        out[self.handles] = (self.kappa * self.mass[:, None] * self.gap(Q)
                             - np.sqrt(self.mass)[:, None] * self.multipliers)
        return out.ravel()

    def hessian(self) -> sp.csr_matrix:
        """(3N, 3N): ``κ_a m_h`` on the handles' coordinates."""
        d = np.zeros((self.n, 3))
        d[self.handles] = self.kappa * self.mass[:, None]
        return sp.diags(d.ravel(), format="csr")

    def update(self, Q: FloatArray) -> None:
        """The multipliers' update ``λ ← λ − κ_a √m (x − x̂)``."""
        self.multipliers -= self.kappa * np.sqrt(self.mass)[:, None] * self.gap(Q)


class PulledContact:
    """A :class:`..engine.contact.ContactTerm` over every coordinate with a
    :class:`HandlePenalty` added: the contact protocol of :mod:`.move`'s increments
    (energy, gradient, Hessian, the factor's signature; CCD and the rest delegated)."""

    def __init__(self, contact: ContactTerm, penalty: HandlePenalty) -> None:
        self.contact, self.penalty = contact, penalty

    def __getattr__(self, name: str):  # clear, embedded, step_cap, active
        return getattr(self.contact, name)

    def set_stiffness(self, Q: FloatArray, energy_gradient: FloatArray) -> bool:
        """``κ`` against the energy's gradient with the pull's (IPC: the augmented
        Lagrangian is part of the energy the barrier balances)."""
        return self.contact.set_stiffness(Q, energy_gradient + self.penalty.gradient(Q))

    def energy(self, Q: FloatArray) -> float:
        return self.contact.energy(Q) + self.penalty.value(Q)

    def gradient(self, Q: FloatArray) -> FloatArray:
        return self.contact.gradient(Q) + self.penalty.gradient(Q)

    def hessian(self, Q: FloatArray) -> sp.csr_matrix:
        H = self.contact.hessian(Q)
        return self.penalty.hessian() if H is None else (H + self.penalty.hessian()).tocsr()

    def signature(self, Q: FloatArray) -> tuple:
        return self.contact.signature(Q), self.penalty.kappa


class HandlePull:
    """The increments of one motion with the handles pulled (module docstring).

    Parameters
    ----------
    problem : the motion's increment problem (:class:`.least_squares.Problem`, handles fixed)
    free_problem : the same energy with every vertex free (its contact replaced here)
    handles : (H,) int array
    step : :func:`.least_squares.solve_increment`, one increment of a problem
    """

    def __init__(self, problem, free_problem, handles: IntArray, step) -> None:
        self.main, self.problem, self.step = problem, free_problem, step
        self.handles = np.asarray(handles, np.int64)
        self.none = self.handles[:0]
        contact = problem.contact
        free = np.ones(free_problem.free.size, bool)
        term = ContactTerm(contact.contact, free, contact.mean_mass)
        self.penalty = HandlePenalty(self.handles, problem.mass, 0.0)
        free_problem.contact = PulledContact(term, self.penalty)
        self.kappa0 = None

    @classmethod
    def where_blocked(cls, problem, start: FloatArray, H1: FloatArray, handles: IntArray,
                      exhausted: bool, free_problem, step) -> HandlePull | None:
        """The pull from ``start`` where an ordinary increment to handles at ``H1`` failed
        and the motion has contact, and either the handles' straight step (the rest
        still) is not clear or the increment cannot be halved further (``exhausted``);
        else None. ``free_problem``: a callable making the problem with every vertex free."""
        if not isinstance(problem.contact, ContactTerm):
            return None
        end = start.copy()
        end[handles] = H1
        if not exhausted and problem.contact.clear(start, end):
            return None
        return cls(problem, free_problem(), handles, step)

    def increment(self, start: FloatArray, H1: FloatArray, last: bool, max_iterations: int,
                  rtol: float, stall: float | None):
        """One increment from ``start`` (the last frame, handles where the pull left them)
        to handles pulled towards ``H1``: the positions and iterations, or None (halved).
        The last increment ends with the handles exactly at ``H1``; where they do not get
        there, or their exact placement is not clear, :class:`NotAdmissibleError`."""
        p, m = self.problem, self.main
        p.previous, p.phi_ref, p.row_weights = m.previous, m.phi_ref, m.row_weights
        p.cg_iterations = m.cg_iterations
        pen = self.penalty
        pen.targets, pen.multipliers = np.asarray(H1, float), np.zeros_like(pen.multipliers)
        if self.kappa0 is None:  # κ_a against the elastic stiffness at the handles
            rm, Jm, rb, Jb = p.linearization(start)
            diag = p.normal_matrix(Jm, Jb).diagonal().reshape(-1, 3)[self.handles]
            self.kappa0 = KAPPA_START * float(np.mean(diag / pen.mass[:, None]))
            pen.kappa = self.kappa0
        Q, iterations, initial = start, 0, pen.distance(start)
        before, stalled = initial, 0
        limit = min(max_iterations, ROUND_ITERATIONS)
        for _ in range(FINAL_ROUNDS if last else ROUNDS):
            out = self.step(p, Q, H1[:0], self.none, limit, rtol, None)
            if out is None:
                break
            Q, its = out
            iterations += its
            if last and (placed := self._place(Q, H1, max_iterations, rtol, stall)):
                return placed[0], iterations + placed[1]
            now = pen.distance(Q)
            if not last and now <= (1.0 - PROGRESS) * initial:
                break
            if its == limit and now < STALL * before:  # not converged, still gaining:
                before = now  # the same κ_a and λ (IPC updates them at a minimizer)
                continue
            stalled = stalled + 1 if now > STALL * before else 0
            if stalled == 2:
                break
            # IPC's schedule: κ_a doubled while the progress η = 1 − now/initial < 0.99
            if now > (1.0 - PROGRESS) * initial and pen.kappa < KAPPA_GROWTH * self.kappa0:
                pen.kappa *= 2.0
            else:
                pen.update(Q)
            before = now
        if Q is start:
            return None
        if not last:
            return Q, iterations
        gap = float(np.abs(pen.gap(Q)).max())
        raise NotAdmissibleError(
            f"the handles, pulled along their path, stop {gap:.3g} short of their targets "
            "(no step placing them there clear of the surface)")

    def _place(self, Q: FloatArray, H1: FloatArray, max_iterations: int, rtol: float,
               stall: float | None):
        """The ordinary increment (handles fixed) from the pulled ``Q`` with the handles
        moved exactly to ``H1``: the rest still, or else carried to first order
        (:meth:`_carried`), where that step is admissible and clear of the surface; None
        where neither is or the increment fails (the pull goes on). The motion's barrier
        takes the pull's stiffness where that is larger."""
        pulled, main = self.problem.contact.contact, self.main.contact
        end = Q.copy()
        end[self.handles] = H1
        if not pulled.clear(Q, end):
            end = self._carried(Q, H1)
            if not (self.problem.admissible(end, self.problem.parts(end)[0])
                    and pulled.clear(Q, end)):
                return None
        if pulled.kappa is not None and (main.kappa is None or main.kappa < pulled.kappa):
            main.max_kappa = pulled.max_kappa if main.kappa is None else max(
                main.max_kappa, pulled.max_kappa)
            main.kappa, main.closest = pulled.kappa, min(main.closest, pulled.closest)
        return self.step(self.main, end, H1, self.handles, max_iterations, rtol, stall)

    def _carried(self, Q: FloatArray, H1: FloatArray) -> FloatArray:
        """``Q`` with the handles at ``H1`` and the rest moved by ``−K_ff⁻¹ K_fh δ_h``,
        ``K`` the Gauss–Newton matrix of the pull's increment with the barrier's Hessian
        (its pairs carried along with the handles, so they keep their distance to first
        order), ``δ_h`` the handles' remaining step."""
        p = self.problem
        _, Jm, _, Jb = p.linearization(Q)
        L = p.normal_matrix(Jm, Jb)
        if (H := p.contact.contact.hessian(Q)) is not None:
            L = (L + sp.tril(H)).tocsr()
        on = np.zeros(Q.shape, bool)
        on[self.handles] = True
        on = on.ravel()
        d = np.zeros(Q.shape)
        d[self.handles] = H1 - Q[self.handles]
        K = (L + L.T - sp.diags(L.diagonal())).tocsr()
        Kff = L[~on][:, ~on].tocsr()
        Kff = (Kff + sp.diags(1e-6 * Kff.diagonal())).tocsr()
        out = Q + d
        out.ravel()[~on] -= factorize_spd(Kff)(K[~on][:, on] @ d.ravel()[on])
        return out
