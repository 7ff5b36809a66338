"""Handle deformation of triangle surfaces in R³: ``move_surface`` places the handles
exactly at their targets and every other vertex so that the triangles keep their shapes
as well as the motion allows, with no degenerate and no folded triangle.

The handles travel along :class:`..engine.similarity.HandlePath` (each connected group's
similarity followed along its screw motion, the remainder linearly) in ``steps`` increments, an
increment halved where it cannot be taken. Each increment is a minimizing movement:

    min_Q  ½|Q − Q_prev|²_M + ½ w² Σ_t a_t c_t |φ_t(Q) − φ̄_t|² + ½ b Σ_e c_e (θ_e(Q) − θ̄_e)²

over the free vertices (handles fixed at the increment's end), with ``φ`` the membrane
distortion of :class:`.distortion.SurfaceDistortion`, ``φ̄ = 0`` (elastic, the
default: each increment relaxes towards the rest shapes) or ``φ̄ = φ(Q_prev)``
(``anchor="previous"``: the planar minimizing movement), the dihedral bending of
:class:`.bending.ShellBending`, and ``M`` the lumped vertex areas (dimensionless,
:func:`lumped_mass`), ``a_t`` the rest triangle's area over the mean (the membrane energy
a sum over the surface, not over the triangles: a mesh's density does not decide where a
deformation goes; ``area_weights=False``: ``a_t = 1``), ``c_t = max(1, |φ_t|/rms|φ|)^p ≥ 1``
at the increment's start (the triangles distorted most weigh more; ``p = emphasis``).
Gauss–Newton on the stacked residuals: a linearized predictor carries the handles'
displacement into the free vertices, then steps on the normal equations (CHOLMOD; the
increment's first factor is kept while full steps are taken), each iterate accepted only
where the energy decreases, every triangle keeps ``det C > 0`` and none folds
(:class:`.folds.FoldTest`). The last increment, whose end is the result, is iterated further
(``final_iterations``, ``final_rtol``), its factor kept through shortened steps until they
stall (``final_stall``: chord steps). With ``cg_iterations > 0`` a step on a kept
factor is conjugate gradients preconditioned by the factor turned with the surface.

With ``contact`` (the default, where the rest is free of self-intersections) the energy
gains IPC's barrier and every step, the predictor included, starts its backtracking at the
fraction CCD allows (:mod:`..engine.contact`; the handles move alone, then with a half or a
quarter of the predictor, where it is folded or would pass through): no iterate passes
through the surface (docs/move-3d.md, "Contact"). The factor is kept while the barrier's
pairs and ``κ`` are those it holds. Where the handles' own path runs into the surface they
are pulled along it instead (:mod:`.handle_pull`), exactly at their targets at the end.

Where one similarity moves all handles, the whole surface follows it exactly (φ moves by
``√2 log s`` in its first component, bending not at all), so a rigid motion of the
handles is a rigid motion of the surface.

The bound: along the frames ``Q_0, …, Q_K``, the polygon's length in the embedding ``Q ↦
(M^½ Q, w φ(Q))``, ``ℓ = Σ_k (|ΔQ_k|²_M + w²|Δφ_k|²)^½``, bounds every triangle's summed
change of distortion, ``Σ_k |Δφ_t| ≤ ℓ/w`` (``SurfaceMoveResult.phi_lengths``, ``.length``;
a property of the frames, whatever weights chose them); from the rest, ``1/ψ_t ≤ 1/ψ_t(rest)
· e^{asinh(√2|φ_t|)}`` (:func:`.distortion.surface_quality_bound`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator

from ..._typing import FloatArray, IntArray
from ...cells.base import scale_free_mass
from ...descent import backtrack, halvings
from ...errors import InvalidMeshError, NotAdmissibleError
from ...kernels.surface import areas, aspect_ratios
from ...scaling import UnitScale
from ...solvers import factorize_spd, pcg
from ..engine.contact import NoContact, contact_term
from ..engine.similarity import HandlePath, handle_groups
from ..engine.similarity_3d import global_similarity
from .bending import ShellBending
from .distortion import SurfaceDistortion
from .folds import FoldTest
from .handle_pull import HandlePull, require_placeable
from .normal_equations import FreePattern, turned_solve, upper_products
from .polish import polish_worst_triangles

SQRT2 = np.sqrt(2.0)
#: the fractions of a fresh linearized predictor tried in turn (0: the handles alone)
PREDICTOR = (1.0, 0.0, 0.5, 0.25)


def lumped_mass(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Vertex weights (:func:`..cells.base.scale_free_mass` of the triangles' areas)."""
    return scale_free_mass(points, triangles, areas(points, triangles))


@dataclass
class SurfaceMoveResult:
    """What :func:`move_surface` returns.

    Attributes
    ----------
    points : (N, 3) final positions (handles bitwise at their targets)
    frames : list of (N, 3) arrays, the accepted increments' ends (the rest first)
    times : the handle-path fraction of each frame
    phi_lengths : (T,) each triangle's ``Σ_k |Δφ_t|`` along the frames
    length : the frames' polygon length ``ℓ`` (module docstring); ``phi_lengths ≤ ℓ/w``
    worst_quality, folds : the result's lowest aspect ratio over its rest one and its
        folded triangles, over all triangles (those of handles only included)
    """

    points: FloatArray
    frames: list
    times: list
    phi_lengths: FloatArray
    length: float
    weight: float
    worst_quality: float
    folds: int
    handle_error: float
    iterations: int
    seconds: float
    steps: int = field(default=0)
    factorizations: int = field(default=0)
    cg_iterations: int = field(default=0)
    polished: int = field(default=0)

    def summary(self) -> dict:
        """Worst relative quality, folds, handle error, seconds, steps (and the
        Gauss–Newton iterations and factorizations)."""
        return {"worst_relative_quality": self.worst_quality, "folds": self.folds,
                "handle_error": self.handle_error, "seconds": self.seconds,
                "steps": self.steps, "iterations": self.iterations,
                "factorizations": self.factorizations, "polished_vertices": self.polished}

    def scaled_up(self, scale: UnitScale) -> SurfaceMoveResult:
        """This unit-size motion at the user's scale (the rest is scale-free)."""
        return replace(self, points=scale.up(self.points),
                       frames=[scale.up(F) for F in self.frames],
                       handle_error=float(scale.up(self.handle_error)))


class _Problem:
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
        #: ``w √c_t``: the membrane rows' weights (``c_t ≥ 1``, :func:`move_surface`)
        self.row_weights = np.full(len(F), float(weight))
        #: the contact barrier on the free coordinates (:func:`..engine.contact.contact_term`)
        self.contact = NoContact()

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


def _step(problem: _Problem, Q0, H1, handles, max_iterations: int, rtol: float,
          stall: float | None = None):
    """One increment from the admissible ``Q0`` to handles at ``H1``: the converged
    positions and the iterations, or None where no admissible predictor exists; the factor
    is kept while full steps are taken. ``stall=None``: renewed after every shortened step.
    A number: kept (chord steps) while each shortened step lowers the energy by at least
    ``stall`` times the first step on that factor and by more than ``rtol·E``; the increment
    ends where a full step, or one on a factor of its own linearization, lowers it by
    ``rtol·E`` or less."""
    d = np.zeros_like(Q0)
    d[handles] = H1 - Q0[handles]
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


def move_surface(V: FloatArray, F: IntArray, handles: IntArray, targets: FloatArray, *,
                 steps: int = 10, weight: float = 1.0, bending: float = 0.3,
                 anchor: str = "rest", emphasis: float = 1.0, area_weights: bool = True,
                 max_iterations: int = 8, rtol: float = 1e-3, final_iterations: int = 30,
                 final_rtol: float = 1e-6, final_stall: float | None = 0.1,
                 cg_iterations: int = 0,
                 max_halvings: int = 8, polish: int = 100,
                 contact: bool = True) -> SurfaceMoveResult:
    """Move a triangle surface: ``handles`` exactly to ``targets``, the rest placed so
    that each triangle's shape changes as little as the motion allows (module docstring).

    Parameters
    ----------
    V : (N, 3) float array
        Rest positions (no degenerate triangle).
    F : (T, 3) int array
        Triangles, consistently oriented where bending is wanted.
    handles : (H,) int array
        Distinct vertex indices.
    targets : (H, 3) float array
    steps : int
        Increments along the handles' path (each halved where it cannot be taken).
    weight : float
        ``w``, the weight of the membrane distortion against ``M``.
    bending : float
        ``b``, the weight of the dihedral bending energy (0: membrane only).
    anchor : {"rest", "previous"}
        ``φ̄`` of each increment: 0 (elastic) or the previous frame's φ.
    emphasis : float
        ``p``: each increment weighs triangle t's membrane rows by ``c_t = max(1,
        |φ_t|/rms|φ|)^p`` at its start (0: all alike).
    area_weights : bool
        Weigh triangle t's membrane rows by its rest area over the mean, ``a_t``.
    max_iterations, rtol : Gauss–Newton–Marquardt steps per increment; stop when an accepted
        step lowers the energy by less than ``rtol`` times the energy. An increment left
        short of its minimizer is the next one's start: too few steps can carry a transient
        kink to the end (a strip rolled into an arc ends kinked with 4).
    final_iterations, final_rtol : the same for the last increment (the result).
    final_stall : float or None
        The last increment keeps its factor while each shortened step lowers the energy
        by at least this fraction of the first step on it (chord steps; a shortened step's
        small decrease is convergence only on a renewed factor); None: renewed after
        every shortened step, as in the other increments.
    cg_iterations : int
        Steps on a kept factor are this many conjugate gradients on the current normal
        equations, preconditioned by the factor turned with the surface; 0: chord steps.
    max_halvings : an increment is at least ``2^-max_halvings / steps`` (a halved increment
        doubles again, up to ``1/steps``, after two taken in a row).
    contact : bool
        Keep the surface from passing through itself (:mod:`..engine.contact`: the barrier in the
        energy, every step capped by CCD) where its rest is free of self-intersections
        (else a :class:`..engine.contact.ContactWarning` with the count, and no contact).
    polish : L-BFGS iterations of the last frame's local polish of the worst triangles
        (:mod:`.polish`; 0: none).

    Raises
    ------
    InvalidMeshError
        Bad shapes, repeated or out-of-range handles, a degenerate rest triangle.
    NotAdmissibleError
        Where an increment cannot be taken without a fold or a degenerate triangle.
    """
    t_start = time.perf_counter()
    V = np.asarray(V, float)
    F = np.asarray(F, np.int64)
    handles = np.asarray(handles, np.int64).ravel()
    targets = np.asarray(targets, float)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise InvalidMeshError("move_surface needs (N, 3) points and (T, 3) triangles")
    if targets.shape != (len(handles), 3):
        raise InvalidMeshError(f"{len(handles)} handles but targets of shape {targets.shape}")
    if len(handles) and (handles.min() < 0 or handles.max() >= len(V)
                         or len(np.unique(handles)) != len(handles)):
        raise InvalidMeshError("handles must be distinct vertex indices")
    if anchor not in ("rest", "previous"):
        raise InvalidMeshError(f"anchor must be 'rest' or 'previous', not {anchor!r}")
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise InvalidMeshError("a triangle refers to a vertex that does not exist")
    diameter = float(np.linalg.norm(V.max(0) - V.min(0)))
    whole = global_similarity(V[handles], targets, diameter) if len(handles) else None
    path = HandlePath(V[handles], targets, handle_groups(handles, F, len(V)), motion="screw")
    problem = _Problem(V, F, handles, weight, bending, lumped_mass(V, F))
    problem.cg_iterations = int(cg_iterations)
    problem.contact = contact_term(V, F, problem.free, problem.mass, contact)
    require_placeable(problem.contact, F, handles, targets)  # targets alone intersecting
    area_w = np.ones(len(F))  # √a_t
    if area_weights and len(F):
        area_w = np.sqrt(areas(V, F) / areas(V, F).mean())
    problem.row_weights = weight * area_w
    Q, t, iterations, frames, times = V.copy(), 0.0, 0, [V.copy()], [0.0]
    phi = problem.membrane.values(V)
    phi_lengths = np.zeros(len(F))
    length = 0.0
    dt0 = 1.0 / max(int(steps), 1)
    dt, halvings, taken, pull = dt0, 0, 0, None
    while t < 1.0:
        t1 = min(1.0, t + dt) if 1.0 - (t + dt) > 1e-12 else 1.0
        start, shift = Q, 0.0
        if whole is not None:  # the whole surface follows the handles' similarity
            a, b = whole.screw(t), whole.screw(t1)
            start = b((Q - a.image) @ a.rotation / a.scale + a.centre)
            shift = SQRT2 * np.log(b.scale)
        H1 = path(t1) if whole is None or t1 >= 1.0 else whole.screw(t1)(V[handles])
        problem.previous = start
        if emphasis > 0 and problem.free_triangles.any():  # the worst weigh more (c_t ≥ 1)
            size = np.linalg.norm(problem.membrane.values(start), axis=1)
            rms = float(np.sqrt(np.mean(size[problem.free_triangles] ** 2)))
            if rms > 1e-8:  # φ is dimensionless: below, the rest's rounding noise
                problem.row_weights = (weight * area_w
                                       * np.maximum(1.0, size / rms) ** (0.5 * emphasis))
        problem.phi_ref = np.zeros_like(phi) if anchor == "rest" else problem.membrane.values(start)
        problem.phi_ref[:, 0] += shift if anchor == "rest" else 0.0
        last = t1 >= 1.0  # the end state is the result: converged further
        budget = ((max(max_iterations, final_iterations), final_rtol, final_stall) if last
                  else (max_iterations, rtol, None))
        out = (_step(problem, start, H1, handles, *budget) if pull is None
               else pull.increment(start, H1, last, *budget))
        if out is None and pull is None and (pull := HandlePull.where_blocked(
                problem, start, H1, handles, dt / 2.0 < dt0 / 2.0**max_halvings,
                lambda: _Problem(V, F, handles[:0], weight, bending, problem.mass), _step)):
            dt, halvings = dt0, 0  # from here on the handles are pulled (.handle_pull)
            continue
        if out is None:  # halved, at most max_halvings times below 1/steps
            halvings += 1
            if dt / 2.0 < dt0 / 2.0**max_halvings:
                raise NotAdmissibleError(
                    f"no fold-free increment of the handles' path from t = {t:.4g}")
            dt /= 2.0
            continue
        taken, halvings = (taken + 1 if halvings == 0 else 1), 0
        if taken >= 2 and dt < dt0:  # a halved increment grows back after two taken
            dt, taken = min(2.0 * dt, dt0), 0
        Q, n_it = out
        if t1 >= 1.0 and polish > 0:  # the result's worst triangles polished
            Qp, polished = polish_worst_triangles(V, F, Q, handles, iterations=polish,
                                                  clear=problem.contact.clear)
            if not problem.contact.embedded(Qp):  # two triangles of a fan meet: dropped
                Qp, polished = Q, {"polish_vertices": 0}
            Q = Qp
        iterations += n_it
        new_phi = problem.membrane.values(Q)
        dphi = np.linalg.norm(new_phi - phi, axis=1)
        dQ = Q - frames[-1]
        length += float(np.sqrt(problem.mass @ np.sum(dQ * dQ, axis=1)
                                + weight**2 * np.sum(dphi**2)))
        phi_lengths += dphi
        phi, t = new_phi, t1
        frames.append(Q.copy())
        times.append(t)
    Q[handles] = targets
    # the result's measures over all its triangles, those the targets alone place included
    rq = aspect_ratios(Q, F) / aspect_ratios(V, F)
    return SurfaceMoveResult(
        points=Q, frames=frames, times=times, phi_lengths=phi_lengths, length=length,
        weight=weight, worst_quality=float(rq.min()) if rq.size else 1.0,
        folds=int(np.sum(problem.folds.mask(Q))),
        handle_error=float(np.abs(Q[handles] - targets).max()) if len(handles) else 0.0,
        iterations=iterations, seconds=time.perf_counter() - t_start, steps=len(frames) - 1,
        factorizations=problem.factorizations, cg_iterations=problem.cg_total,
        polished=polished["polish_vertices"] if polish > 0 else 0)
