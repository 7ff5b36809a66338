"""Prescribed motion of tetrahedral meshes: handles exactly at their targets, every tet
positively oriented in every frame.

``move_tets`` factors the motion into the similarity that best fits the handles (followed
exactly, free of shape strain: :mod:`..engine.similarity`) and a residual motion of the handles
(each connected piece of boundary turns and scales with its own best similarity), built
in steps as a minimizing movement of the tet distortion (:mod:`.distortion`) in the
graph metric ``M + w² JᵀJ``: each step moves the handles a little, starts the other
vertices at the first admissible of the extension of the handles' increment by the
linearized metric, the last step's velocity continued, or their last positions (a step
where all three invert a tet is halved), and minimizes ``½|Q − Q_prev|²_M + ½w²|φ(Q)|²``
(the distortion from the rest shape) with the handles fixed (:mod:`.least_squares`,
every accepted iterate admissible). A quality finish
with the handles fixed then fits the distortion from regular tets, pressing on the worst,
and a local polish raises the worst tets' mean ratio (:mod:`.polish`).

With ``contact`` (the default, where the rest's boundary is free of self-intersections and
some boundary vertex is free) the free parts of the boundary cannot pass through each
other or through the handles (:mod:`.contact`, IPC): the barrier joins the energy of
the steps and the quality rounds, a step starts only at a prediction reached from the last
frame along a straight path free of contact (CCD; else it is halved), and every trial of
the line searches and of the polish is capped by CCD. IPC has no pair for two boundary
triangles sharing a vertex: a step whose end has two such triangles intersecting (exact)
is halved, and a finish or polish whose result has is dropped.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..._options import require_at_least
from ..._typing import FloatArray, IntArray
from ...cells.base import lumped_mass
from ...errors import InvalidMeshError
from ...kernels.tetrahedra import mean_ratios as tet_mean_ratios
from ...kernels.tetrahedra import orientations as tet_orientations
from ...kernels.tetrahedra import signed_volumes as tet_signed_volumes
from ...mesh import TetMesh
from ...results import WrappedMotion
from ...scaling import UnitScale
from ..engine.contact import NoContact
from ..engine.continuation import NoAdmissiblePathError, frame_times, march
from ..engine.handles import SolvedVertices, check_handles, distinct_handles
from ..engine.pinned_cells import pinned, turned_over_problem
from ..engine.polish import quality_rounds
from ..engine.similarity import HandlePath, Similarity3, fit_similarity_3d, handle_groups
from ..engine.similarity_3d import tet_boundary_faces
from .contact import tet_contact_term
from .distortion import SQRT3, TetDistortion
from .least_squares import Problem, extend, minimize
from .polish import fixed_ceiling, polish_worst_tets

__all__ = ["TetMeshMoveResult", "TetMoveResult", "move_tet_mesh", "move_tets"]

# A step's relaxation stops when its gradient fell by this factor (the frames need only be
# admissible and near the minimizing movement; the finish does the rest).
STEP_RTOL = 1e-2
# A quality round stops when its gradient fell by this factor (its weights change next).
QUALITY_RTOL = 1e-2


@dataclass
class TetMoveResult:
    """Result of :func:`move_tets`.

    Attributes
    ----------
    points : (N, 3) float array
        The moved vertices, handles bitwise at their targets.
    frames : list of (N, 3) float arrays
        The motion (first = input, last = ``points``) when ``frames`` was asked for.
    min_mean_ratio : (F,) float array
        ``min η`` per returned frame (first and last at least).
    similarity : Similarity3
        The similarity factored out of the motion.
    strain_bound : float
        ``ℓ/w + √3 |log s|``: a bound on every tet's ``Σ_k |φ_c(Q_{k+1}) − φ_c(Q_k)|``
        along the frames returned (``ℓ`` their chord length in the metric, ``s`` the scale).
    seconds : float
    """

    points: FloatArray
    frames: list[FloatArray]
    min_mean_ratio: FloatArray
    similarity: Similarity3
    strain_bound: float
    seconds: float
    inverted: int = 0
    handle_error: float = 0.0
    details: dict = field(default_factory=dict)

    def summary(self) -> dict:
        return {
            "inverted": int(self.inverted),
            "min_mean_ratio": float(self.min_mean_ratio[-1]),
            "min_mean_ratio_per_frame": [float(v) for v in self.min_mean_ratio],
            "handle_error": float(self.handle_error),
            "strain_bound": float(self.strain_bound),
            "seconds": float(self.seconds),
            "similarity": self.similarity.as_dict(),
            **self.details,
        }

    def scaled_up(self, scale: UnitScale) -> TetMoveResult:
        """This motion of the mesh at unit size, at the user's scale (points, frames, the
        similarity's centre and shift, the handle error; the rest is scale-free)."""
        return replace(
            self, points=scale.up(self.points), frames=[scale.up(F) for F in self.frames],
            similarity=self.similarity.scaled_up(scale),
            handle_error=float(scale.up(self.handle_error)))


def _check(points, tets, handles, targets) -> tuple[FloatArray, IntArray, IntArray, FloatArray]:
    P = np.asarray(points, dtype=float)
    T = np.asarray(tets)
    if P.ndim != 2 or P.shape[1] != 3 or T.ndim != 2 or T.shape[1] != 4 or len(T) == 0:
        raise InvalidMeshError("a tet motion needs (N, 3) points and non-empty (C, 4) tets")
    if not np.issubdtype(T.dtype, np.integer) or T.min() < 0 or T.max() >= len(P):
        raise InvalidMeshError("tets must hold vertex indices of the points")
    if not np.isfinite(P).all():
        raise InvalidMeshError("the points are not all finite")
    vol = tet_signed_volumes(P, T)
    if not (vol > 0).all():
        raise InvalidMeshError(f"{int(np.sum(~(vol > 0)))} tets are not positively oriented "
                               f"(first: tet {int(np.flatnonzero(~(vol > 0))[0])})")
    h, t = distinct_handles(*check_handles(handles, targets, len(P)))
    final = P.copy()
    final[h] = t
    if problem := turned_over_problem(tet_orientations(final, T) <= 0,
                                      pinned(T, h, len(P)), "tet"):
        raise InvalidMeshError(problem)
    return P, T.astype(np.int64), h, t


def _finish(strain_source: FloatArray, tets: IntArray, problem: Problem, Q: FloatArray,
            rounds: int, max_iter: int, newton: bool, ceiling: float = np.inf,
            contact=None) -> tuple[FloatArray, dict]:
    """Quality rounds with the handles fixed: proximal least squares of the distortion
    from regular tets of the source's volumes, each round's tet weights those of the last
    times ``max(1, |φ_shape|/rms)^½`` (the tets that stay the worst weigh more and more);
    the iterate with the best minimum mean ratio is kept (the unfinished one included).
    The rounds stop once it reaches ``ceiling`` (the worst mean ratio of the tets with
    only fixed corners: no later round can beat it). ``contact``: the motion's contact
    term (:func:`.minimize`)."""
    absolute = TetDistortion.regular(strain_source, tets)
    quality = replace(problem, strain=absolute)  # the same pattern, factor and settings
    zero = np.zeros((len(tets), 7))

    def relax(Q, weights):
        weights = np.ones(len(tets)) if weights is None else weights
        res = minimize(quality, Q, Q, zero, weights, rtol=QUALITY_RTOL, max_iterations=max_iter,
                       newton=newton, contact=contact)
        return res.points, res.iterations

    best, nit, kept = quality_rounds(
        Q, rounds, relax, lambda Q: float(tet_mean_ratios(Q, tets).min()),
        lambda Q: np.linalg.norm(absolute.values(Q)[:, 1:], axis=1), ceiling)
    return best, {"finish_iterations": nit, "finish_rounds_kept": kept}


def move_tets(points: FloatArray, tets: IntArray, handles, targets, *, steps: int = 4,
              frames: int | None = None, weight: float = 1.0, relax_iterations: int = 15,
              quality_rounds: int = 4, max_splits: int = 12, polish: int = 300,
              contact: bool = True) -> TetMoveResult:
    """Move the ``handles`` vertices of a tet mesh exactly to ``targets``; place the
    other vertices to keep every tet positively oriented and as good as the motion allows.

    Parameters
    ----------
    points : (N, 3) float array
    tets : (C, 4) int array
        Every tet positively oriented.
    handles : (k,) int array
        Vertex indices (typically the boundary); duplicates must agree.
    targets : (k, 3) float array
    steps : int
        Continuation steps (each halved further where the extension inverts a tet).
    frames : int, optional
        Return the motion as this many frames (≥ 2; at least ``frames − 1`` steps).
    weight : float
        ``w`` of the metric ``M + w² JᵀJ``.
    relax_iterations : int
        Iterations of each step's minimization and of each quality round.
    quality_rounds : int
        Rounds of the quality finish (0: none).
    polish : int
        L-BFGS iterations of the local polish of the worst tets (0: none).
    contact : bool
        Keep the free parts of the boundary from passing through each other and through
        the handles (module docstring) where the rest's boundary is free of
        self-intersections (else a :class:`..engine.contact.ContactWarning` with the count, and
        no contact).

    Returns
    -------
    TetMoveResult

    Raises
    ------
    InvalidMeshError
        Bad points, tets, handles or targets; targets that turn over or flatten a tet
        whose vertices are all handles (a mirror image of the mesh turns every tet over).
    NoAdmissiblePathError
        No admissible step found after ``max_splits`` halvings (with contact: also where
        the handles' own path brings the boundary into contact).
    """
    t_start = time.perf_counter()
    P, T, h, tg = _check(points, tets, handles, targets)
    require_at_least("frames", frames, 2, error=InvalidMeshError)  # the input and the result
    S = fit_similarity_3d(P[h], tg)
    residual_targets = S.inverse(tg)
    times, pick = frame_times(steps, frames)
    strain = TetDistortion(P, T)
    mass = lumped_mass(P, T)
    details: dict = {"continuation_splits": 0, "step_iterations": 0, "finish_iterations": 0,
                     "finish_rounds_kept": 0, "contact": False}
    scale = np.ptp(P, axis=0).max()
    if np.allclose(residual_targets, P[h], rtol=0.0, atol=1e-12 * scale):
        residual = [P.copy() for _ in times]  # the handles move by a similarity: so does all
        length = 0.0
    else:
        path = HandlePath(P[h], residual_targets,
                          handle_groups(h, tet_boundary_faces(T), len(P)))
        problem = Problem.build(strain, weight, mass, h)
        touch = tet_contact_term(P, T, problem.pattern.free, mass, contact)
        residual, cont = _continuation(problem, P, h, path, times, relax_iterations, max_splits,
                                       True, touch)
        details.update(cont)
        if quality_rounds > 0:
            end, fin = _finish(P, T, problem, residual[-1], quality_rounds, relax_iterations, True,
                               fixed_ceiling(residual[-1], T, h), touch)
            residual[-1] = end if touch.embedded(end) else residual[-1]
            details.update(fin)
        if polish > 0:
            end, pol = polish_worst_tets(residual[-1], T, h, iterations=polish,
                                         clear=touch.clear)
            residual[-1] = end if touch.embedded(end) else residual[-1]
            details.update(pol)
        details["contact"] = touch.kappa is not None  # whether the barrier acted
        emb = [np.concatenate([(np.sqrt(mass)[:, None] * residual[i]).ravel(),
                               weight * strain.values(residual[i]).ravel()]) for i in pick]
        length = float(sum(np.linalg.norm(b - a) for a, b in zip(emb[:-1], emb[1:])))
    moved = [S.at(float(s))(R) if not S.is_identity else R.copy() for s, R in zip(times, residual)]
    moved[-1][h] = tg  # bitwise at the targets
    ratios = np.array([tet_mean_ratios(moved[i], T).min() for i in pick])
    inverted = int(np.sum(~(tet_signed_volumes(moved[-1], T) > 0)))
    if inverted:
        raise NoAdmissiblePathError(
            f"{inverted} tets inverted in the result (a bug: please report)")
    return TetMoveResult(
        points=moved[-1], frames=[moved[i] for i in pick] if frames is not None else [],
        min_mean_ratio=ratios, similarity=S,
        strain_bound=length / weight + SQRT3 * abs(S.log_scale),
        seconds=time.perf_counter() - t_start, inverted=inverted,
        handle_error=float(np.abs(moved[-1][h] - tg).max()), details=details)


def _predictions(problem: Problem, Q: FloatArray, h: IntArray, target: FloatArray,
                 velocity: FloatArray | None):
    """Starts for a step that puts the handles at ``target``, best first: the extension of
    the handles' increment by the linearized metric, the last step's motion of the free
    vertices continued (``velocity``: their displacement per unit of ``s`` times the
    step), the free vertices kept; each with its name."""
    yield "extension", extend(problem, Q, h, target)
    if velocity is not None:
        moved = Q + velocity
        moved[h] = target
        yield "velocity", moved
    kept = Q.copy()
    kept[h] = target
    yield "kept", kept


def _continuation(problem: Problem, P: FloatArray, h: IntArray, path: HandlePath,
                  times: FloatArray, relax_iterations: int, max_splits: int, newton: bool,
                  contact=None) -> tuple[list[FloatArray], dict]:
    """Frames at ``times`` of the minimizing movement (see :func:`move_tets`):
    :func:`..engine.continuation.march` with each step started at the first admissible of
    :func:`_predictions` (with a ``contact`` term: reached along a straight path free of
    contact, :meth:`..engine.contact.ContactTerm.clear`)."""
    contact = NoContact() if contact is None else contact
    nit, rate = 0, None  # the last step's motion per unit of s
    used = {"extension": 0, "velocity": 0, "kept": 0}  # steps started by each prediction
    # each step's distortion is measured from the rest shape: anchored at the last frame
    # instead, nothing pulls a sheared tet back and the worst flattens step after step
    # (a box's ball turned 180°, 5k tets: min η 0.1 at s = 0.6, 0.0003 at s = 0.99, stuck)
    rest = np.zeros((len(problem.strain.tets), 7))

    def advance(Q: FloatArray, s_now: float, s_try: float) -> FloatArray | None:
        nonlocal nit, rate
        velocity = None if rate is None else rate * (s_try - s_now)
        for name, start in _predictions(problem, Q, h, path(s_try), velocity):
            if (problem.strain.determinants(start) > 0).all() and contact.clear(Q, start):
                used[name] += 1
                break
        else:
            return None
        res = minimize(problem, start, Q, rest, rtol=STEP_RTOL, max_iterations=relax_iterations,
                       newton=newton, contact=contact)
        nit += res.iterations
        if not contact.embedded(res.points):  # two boundary triangles of a fan meet
            return None
        rate = (res.points - Q) / (s_try - s_now)
        return res.points

    frames, splits = march(P, times, advance, max_splits=max_splits)
    return frames, {"continuation_splits": splits, "step_iterations": nit,
                    "predictions_used": used}


@dataclass
class TetMeshMoveResult(WrappedMotion):
    """What :func:`meshopt_toolkit.move` returns for a :class:`~meshopt_toolkit.mesh.TetMesh`:
    a :class:`~meshopt_toolkit.results.WrappedMotion` of :class:`TetMesh` frames around a
    :class:`TetMoveResult` (per-frame ``min η``, similarity, strain bound)."""

    points = property(lambda self: self.mesh.points, doc="The moved points ``(N, 3)``.")
    strain_bound = property(lambda self: self.motion.strain_bound, doc="See TetMoveResult.")
    min_mean_ratio = property(lambda self: self.motion.min_mean_ratio,
                              doc="``min η`` per returned frame.")


def move_tet_mesh(mesh: TetMesh, handles, targets, *, frames: int | None = None,
                  steps: int = 4, weight: float = 1.0, relax_iterations: int = 15,
                  quality_rounds: int = 4, max_splits: int = 12,
                  progress: Callable[[float], None] | None = None,
                  contact: bool = True) -> TetMeshMoveResult:
    """:func:`move_tets` on a :class:`TetMesh`: the moved mesh and frames keep its tets,
    tags and names (``mt.move`` calls this for a TetMesh, at unit size:
    :func:`~meshopt_toolkit.scaling.at_unit_size`); ``contact`` as there.

    Raises
    ------
    NotAdmissibleError
        The mesh has inverted or flat tets (their count).
    InvalidMeshError, NoAdmissiblePathError
        As :func:`move_tets`.
    """
    mesh.require_admissible()
    if progress is not None:
        progress(0.0)
    # each handle once, in the file's numbering (a clash names the file's vertex)
    h, tg = distinct_handles(*check_handles(handles, targets, mesh.n_vertices))
    # vertices in no tet (a file may hold some) are left out of the solve and stay put
    solved = SolvedVertices(mesh.points, mesh.tets, h, tg)
    res = move_tets(solved.points, solved.cells, solved.handles, solved.targets, steps=steps,
                    frames=frames, weight=weight, relax_iterations=relax_iterations,
                    quality_rounds=quality_rounds, max_splits=max_splits,
                    contact=contact)

    moved = mesh.with_points(solved.full(res.points))
    out = ([mesh.with_points(solved.full(F)) for F in res.frames[:-1]] + [moved]
           if frames is not None else [mesh, moved])
    if progress is not None:
        progress(1.0)
    return TetMeshMoveResult(mesh=moved, frames=out, motion=res)
