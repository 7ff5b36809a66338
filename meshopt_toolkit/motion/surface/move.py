"""Handle deformation of triangle surfaces in R³: ``move_surface`` places the handles
exactly at their targets and every other vertex so that the triangles keep their shapes
as well as the motion allows, with no degenerate and no folded triangle.

The handles travel along :class:`..engine.similarity.HandlePath` (each connected group's
similarity followed along its screw motion, the remainder linearly; with contact a half
turn, which the fit could take either way round, goes the way
:meth:`..engine.similarity.HandlePath.oriented_half_turns` takes about the surface's
centroid and, where that motion is refused, the way along which the group's handles sweep
through fewer of the triangles at rest, :func:`clearer_half_turns`) in ``steps``
increments: the engine's continuation :func:`..engine.continuation.march` with its
:class:`..engine.continuation.GrowingSteps` (an increment halved where it cannot be
taken, doubled back after two taken in a row), every increment a frame. Each increment
is a minimizing movement (:mod:`.least_squares`):

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
Gauss–Newton on the stacked residuals (:func:`.least_squares.solve_increment`): a
linearized predictor carries the handles' displacement into the free vertices, then steps
on the normal equations (CHOLMOD; the increment's first factor is kept while full steps
are taken), each iterate accepted only where the energy decreases, every triangle keeps
``det C > 0`` and none folds (:class:`.folds.FoldTest`). The last increment, whose end is
the result, is iterated further (``final_iterations``, ``final_rtol``), its factor kept
through shortened steps until they stall (``final_stall``: chord steps); where that does
not converge it goes on (``final_late_iterations``), and of the two iterates the one
better after the polish is the result (pressed walls converge slowly under the barrier). With
``cg_iterations > 0`` a step on a kept factor is conjugate gradients preconditioned by the
factor turned with the surface.

With ``contact`` (the default, where the rest is free of self-intersections) the energy
gains IPC's barrier and every step, the predictor included, starts its backtracking at the
fraction CCD allows (:mod:`..engine.contact`; the handles move alone, then with a half or a
quarter of the predictor, where it is folded or would pass through): no iterate passes
through the surface (docs/move-3d.md, "Contact"). The factor is kept while the barrier's
pairs and ``κ`` are those it holds. Where the handles' own path runs into the surface they
are pulled along it instead (:mod:`.handle_pull`, the ``fallback`` of ``march``), exactly
at their targets at the end. The last frame's worst triangles are then polished
(:mod:`.polish`).

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

from ..._typing import FloatArray, IntArray
from ..._options import options_of
from ...cells.base import scale_free_mass
from ...errors import InvalidMeshError, NotAdmissibleError, OptionError
from ...kernels.intersections3d import candidate_pairs, intersecting_pairs
from ...kernels.surface import areas, aspect_ratios
from ...scaling import UnitScale
from ..engine.contact import contact_term
from ..engine.continuation import GrowingSteps, march
from ..engine.similarity import HandlePath, handle_groups
from ..engine.similarity_3d import global_similarity
from .handle_pull import HandlePull, require_placeable
from .least_squares import Problem, solve_increment
from .polish import polish_worst_triangles

SQRT2 = np.sqrt(2.0)


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


def _path_lengths(frames: list, membrane, mass: FloatArray, weight: float):
    """Each triangle's ``Σ_k |Δφ_t|`` (T,) along ``frames`` and their polygon's length
    ``ℓ`` in the embedding ``Q ↦ (M^½ Q, w φ(Q))`` (module docstring)."""
    phi = membrane.values(frames[0])
    phi_lengths, length = np.zeros(len(phi)), 0.0
    for before, Q in zip(frames, frames[1:]):
        new_phi = membrane.values(Q)
        dphi = np.linalg.norm(new_phi - phi, axis=1)
        dQ = Q - before
        length += float(np.sqrt(mass @ np.sum(dQ * dQ, axis=1) + weight**2 * np.sum(dphi**2)))
        phi_lengths += dphi
        phi = new_phi
    return phi_lengths, length


def clearer_half_turns(path: HandlePath, V: FloatArray, F: IntArray, handles: IntArray,
                       samples: int = 16) -> HandlePath:
    """``path`` with each group that turns by a half turn (:meth:`HandlePath.half_turns`:
    the two ways round equally short) turned the way along which its handles, as points
    on ``samples`` chords of their arcs, cross fewer of the triangles at rest that touch
    none of them (exact, :func:`...kernels.intersections3d.intersecting_pairs`); the way
    ``path`` takes where both cross as many. A finger curled back over its palm goes over
    it, not under and through it."""
    for k in path.half_turns():
        g = path.pieces[k][0]
        near = np.zeros(len(V), bool)
        near[handles[g]] = True
        faces = F[~near[F].any(axis=1)]
        counts = []
        for way in (path, path.turned_the_other_way(k)):
            P = np.stack([way(t)[g] for t in np.linspace(0.0, 1.0, samples + 1)])
            m = P[:-1].size // 3  # the chords (p, q, copy of q) as flat triangles
            X = np.vstack([V, P[:-1].reshape(-1, 3), P[1:].reshape(-1, 3),
                           P[1:].reshape(-1, 3)])
            chords = len(V) + np.arange(m)[:, None] + np.array([0, m, 2 * m])
            T = np.vstack([faces, chords])
            lo, hi = X[T].min(axis=1), X[T].max(axis=1)
            pairs = candidate_pairs(lo, hi)
            pairs = pairs[(pairs < len(faces)).sum(axis=1) == 1]
            counts.append(int(intersecting_pairs(X, T, pairs).sum()))
        if counts[1] < counts[0]:
            path = path.turned_the_other_way(k)
    return path


@dataclass(frozen=True)
class SurfaceMoveOptions:
    """The settings of :func:`move_surface` (the energy's weights and the solver's limits).

    Attributes
    ----------
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
    max_iterations, rtol : int, float
        Gauss–Newton–Marquardt steps per increment; stop when an accepted step lowers
        the energy by less than ``rtol`` times the energy. An increment left short of its
        minimizer is the next one's start: too few steps can carry a transient kink to
        the end (a strip rolled into an arc ends kinked with 4).
    final_iterations, final_rtol : int, float
        The same for the last increment (the result).
    final_late_iterations : int
        Where the last increment is not converged after ``final_iterations`` steps (under
        a stiff contact barrier, walls pressed together and ``κ`` doubled many times, it
        may be far from its minimizer), it goes on up to this many steps in all; the result
        is then whichever of the two iterates is better (the worst relative quality after
        the polish).
    final_stall : float or None
        The last increment keeps its factor while each shortened step lowers the energy
        by at least this fraction of the first step on it (chord steps; a shortened step's
        small decrease is convergence only on a renewed factor); None: renewed after
        every shortened step, as in the other increments.
    cg_iterations : int
        Steps on a kept factor are this many conjugate gradients on the current normal
        equations, preconditioned by the factor turned with the surface; 0: chord steps.
    max_halvings : int
        An increment is at least ``2^-max_halvings / steps`` (a halved increment doubles
        again, up to ``1/steps``, after two taken in a row).
    polish : int
        L-BFGS iterations of the last frame's local polish of the worst triangles
        (:mod:`.polish`; 0: none).
    """

    weight: float = 1.0
    bending: float = 0.3
    anchor: str = "rest"
    emphasis: float = 1.0
    area_weights: bool = True
    max_iterations: int = 8
    rtol: float = 1e-3
    final_iterations: int = 30
    final_late_iterations: int = 400
    final_rtol: float = 1e-6
    final_stall: float | None = 0.1
    cg_iterations: int = 0
    max_halvings: int = 8
    polish: int = 100


def move_surface(V: FloatArray, F: IntArray, handles: IntArray, targets: FloatArray, *,
                 steps: int = 10, contact: bool = True,
                 options: SurfaceMoveOptions | dict | None = None) -> SurfaceMoveResult:
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
    contact : bool
        Keep the surface from passing through itself (:mod:`..engine.contact`: the barrier in the
        energy, every step capped by CCD) where its rest is free of self-intersections
        (else a :class:`..engine.contact.ContactWarning` with the count, and no contact).
    options : SurfaceMoveOptions, a mapping of its fields, or None (the defaults)
        The energy's weights and the solver's limits.

    Raises
    ------
    InvalidMeshError
        Bad shapes, repeated or out-of-range handles, a degenerate rest triangle.
    OptionError
        ``options`` of another type or with a field :class:`SurfaceMoveOptions` lacks.
    NotAdmissibleError
        Where an increment cannot be taken without a fold or a degenerate triangle.
    """
    o = options_of(SurfaceMoveOptions, options, {}, error=OptionError,
                   what="move_surface option(s)")
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
    if o.anchor not in ("rest", "previous"):
        raise InvalidMeshError(f"anchor must be 'rest' or 'previous', not {o.anchor!r}")
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise InvalidMeshError("a triangle refers to a vertex that does not exist")
    diameter = float(np.linalg.norm(V.max(0) - V.min(0)))
    whole = global_similarity(V[handles], targets, diameter) if len(handles) else None
    mass = lumped_mass(V, F)
    path = HandlePath(V[handles], targets, handle_groups(handles, F, len(V)),
                      motion="screw").oriented_half_turns(mass @ V / mass.sum())
    try:
        return _move_along(V, F, handles, targets, (path, whole), steps, contact, o, t_start)
    except NotAdmissibleError:  # a half turn refused its way: the clearer way, if other
        clearer = clearer_half_turns(path, V, F, handles) if contact and whole is None else path
        if clearer is path:
            raise
        return _move_along(V, F, handles, targets, (clearer, whole), steps, contact, o,
                           t_start)


def _move_along(V: FloatArray, F: IntArray, handles: IntArray, targets: FloatArray, paths,
                steps: int, contact: bool, o: SurfaceMoveOptions,
                t_start: float) -> SurfaceMoveResult:
    """:func:`move_surface` along ``paths``, the handles' :class:`HandlePath` and the
    similarity moving them all (or None), its arguments checked."""
    path, whole = paths
    weight, bending, anchor, emphasis = o.weight, o.bending, o.anchor, o.emphasis
    max_iterations, rtol, final_iterations = o.max_iterations, o.rtol, o.final_iterations
    final_rtol, final_stall, polish = o.final_rtol, o.final_stall, o.polish
    problem = Problem(V, F, handles, weight, bending, lumped_mass(V, F))
    problem.cg_iterations = int(o.cg_iterations)
    problem.contact = contact_term(V, F, problem.free, problem.mass, contact)
    require_placeable(problem.contact, F, handles, targets)  # targets alone intersecting
    area_w = np.ones(len(F))  # √a_t
    if o.area_weights and len(F):
        area_w = np.sqrt(areas(V, F) / areas(V, F).mean())
    problem.row_weights = weight * area_w
    iterations, pull = 0, None

    def ends(Q, t, t1):
        """The increment's start (the whole surface carried along the handles' one
        similarity, if any), its shift of φ, and the handles at ``t1``."""
        start, shift = Q, 0.0
        if whole is not None:  # the whole surface follows the handles' similarity
            a, b = whole.screw(t), whole.screw(t1)
            start = b((Q - a.image) @ a.rotation / a.scale + a.centre)
            shift = SQRT2 * np.log(b.scale)
        return start, shift, path(t1) if whole is None or t1 >= 1.0 else whole.screw(t1)(
            V[handles])

    def advance(Q, t, t1):  # one increment (:mod:`.least_squares`), or pulled
        nonlocal iterations
        start, shift, H1 = ends(Q, t, t1)
        problem.previous = start
        if emphasis > 0 and problem.free_triangles.any():  # the worst weigh more (c_t ≥ 1)
            size = np.linalg.norm(problem.membrane.values(start), axis=1)
            rms = float(np.sqrt(np.mean(size[problem.free_triangles] ** 2)))
            if rms > 1e-8:  # φ is dimensionless: below, the rest's rounding noise
                problem.row_weights = (weight * area_w
                                       * np.maximum(1.0, size / rms) ** (0.5 * emphasis))
        rest = anchor == "rest"
        problem.phi_ref = np.zeros((len(F), 3)) if rest else problem.membrane.values(start)
        problem.phi_ref[:, 0] += shift if rest else 0.0
        last = t1 >= 1.0  # the end state is the result: converged further
        budget = ((max(max_iterations, final_iterations, o.final_late_iterations), final_rtol,
                   final_stall) if last else (max_iterations, rtol, None))
        problem.keep_at = max(max_iterations, final_iterations) if last else None
        out = (solve_increment(problem, start, H1, handles, *budget) if pull is None
               else pull.increment(start, H1, last, *budget))
        if out is None:
            return None
        iterations += out[1]
        return out[0]

    def fallback(Q, t, t1, exhausted):  # from here on the handles are pulled (.handle_pull)
        nonlocal pull
        if pull is None:
            start, _, H1 = ends(Q, t, t1)
            pull = HandlePull.where_blocked(
                problem, start, H1, handles, exhausted,
                lambda: Problem(V, F, handles[:0], weight, bending, problem.mass),
                solve_increment)
            return pull is not None
        return False

    times = [0.0]
    frames, _ = march(V, [0.0, 1.0], advance, every_step=True, progress=times.append,
                      rule=GrowingSteps(1.0 / max(int(steps), 1), o.max_halvings, lambda t: (
                          NotAdmissibleError(
                              f"no fold-free increment of the handles' path from t = {t:.4g}"))),
                      fallback=fallback)
    # the last increment's iterate after final_iterations, where it went on (and clean)
    early = problem.kept
    candidates = [frames[-1]] + ([early] if early is not None and not np.array_equal(
        early, frames[-1]) and problem.contact.embedded(early) else [])
    rest_q = aspect_ratios(V, F)
    best = None
    for X in candidates:
        done = {"polish_vertices": 0}
        if polish > 0:  # the result's worst triangles polished
            Qp, done = polish_worst_triangles(V, F, X, handles, iterations=polish,
                                              clear=problem.contact.clear)
            if problem.contact.embedded(Qp):  # else two triangles of a fan meet: dropped
                X = Qp
            else:
                done = {"polish_vertices": 0}
        worst = float((aspect_ratios(X, F) / rest_q).min()) if len(F) else 1.0
        if best is None or worst > best[0]:
            best = (worst, X.copy(), done)
    frames[-1], polished = best[1], best[2]
    phi_lengths, length = _path_lengths(frames, problem.membrane, problem.mass, weight)
    Q = frames[-1].copy()
    Q[handles] = targets
    # the result's measures over all its triangles, those the targets alone place included
    rq = aspect_ratios(Q, F) / rest_q
    return SurfaceMoveResult(
        points=Q, frames=frames, times=times, phi_lengths=phi_lengths, length=length,
        weight=weight, worst_quality=float(rq.min()) if rq.size else 1.0,
        folds=int(np.sum(problem.folds.mask(Q))),
        handle_error=float(np.abs(Q[handles] - targets).max()) if len(handles) else 0.0,
        iterations=iterations, seconds=time.perf_counter() - t_start, steps=len(frames) - 1,
        factorizations=problem.factorizations, cg_iterations=problem.cg_total,
        polished=polished["polish_vertices"])
