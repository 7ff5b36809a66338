"""Morphing two poses of a triangle surface in R³ (same triangles): a discrete geodesic
of the membrane distortion plus shell bending.

A surface ``Q`` is embedded as ``X(Q) = (m^½ ⊙ Q, w φ(Q), √b √c_e θ_e(Q))``: the lumped
vertex areas ``m`` (:func:`..cells.base.scale_free_mass`), the membrane distortion ``φ``
of :class:`.distortion.SurfaceDistortion` (the planar φ through each triangle's
first fundamental form) and the dihedral angles ``θ`` with the weights ``c_e = ℓ̄²/Ā`` of
:class:`.bending.ShellBending`. The frames ``Q_0 = source, Q_1, …, Q_K = target`` minimize
the discrete path energy of the metric ``JᵀJ`` of this embedding
(:class:`.metric.SurfaceGraphMetric`)

    E = ½ Σ_k |X(Q_{k+1}) − X(Q_k)|²      (angle differences wrapped into [−π, π))

over the interior frames, by Levenberg–Marquardt (the block-tridiagonal normal equations
solved by conjugate gradients, preconditioned by one kept Cholesky factor per frame,
:class:`.path_system.PathSystem`), started from the as-rigid-as-possible interpolation
(:mod:`.interpolation`) or, where that folds, linear interpolation. While one of
its frames has a worst relative quality below the worse end's, all its interior frames
take as-rigid-as-possible local/global steps toward their interpolated stretches together
(at most ``START_ITERATIONS``): they straighten the shear where neighbouring triangles'
rotations, interpolated one by one, disagree (residual rotations near a half turn).

It stops first where the path is *healthy* (the start included, then after each step):
every interior frame's worst relative quality (aspect ratio 2r/R over the source's) at
least the worse end's. No path has a better worst frame than its worse end, so a healthy
path is optimal in that measure; its energy is not minimized further (a healthy start is
returned without a Gauss–Newton model: 0.2–26 % above the converged path's energy on the
pairs of the tests and of ``bench_surface_morph.py``, the worst quality the same). Else
it stops where the Gauss–Newton model of the next step predicts, or a step achieved, a
decrease below ``rtol·E`` (a start stationary to that tolerance is returned unchanged);
the frames it leaves below the worse end are then polished (:mod:`.morph_polish`).
``stop_when_healthy=False`` leaves both alone. Every accepted iterate has ``det C > 0``
in every triangle of every frame and no fold (:class:`.folds.FoldTest` against the
source) that the target does not have. The mass term fixes the frames' rigid motions (a
rotation of one frame costs ``|ΔQ|²_M``), so nothing is pinned.

With contact (the default, where both ends are free of self-intersections) no frame
passes through the surface, nor the straight motion between two frames (two frames alone
are refused where that motion passes through it, with the frames a clean path needs):
each frame's IPC barrier joins the energy, every step is capped by CCD and taken only on
a clean path, from a clean start (:mod:`.morph_contact`). Where neither
interpolation is clean, the start is the as-rigid-as-possible interpolation that turns each
pair of neighbours whose dihedral angle's short way passes the fold (one triangle laid on
the other) the long way round, through flat (``long_way``,
:func:`.interpolation.fold_crossings`), where that is clean; else a detour of the moving
components; else the homotopy of :mod:`.morph_homotopy`, along either way round.

A pair related by a similarity (to ``1e-10`` of the diameter) is followed along that
similarity exactly (rotation in angle, scale geometrically), an identical pair by copies;
vertices in no triangle move linearly. Along the frames each triangle's summed change of
distortion is at most ``ℓ/w`` (the polygon's length in the embedding), which bounds its
quality (docs/theory-3d.md §5).
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..._typing import FloatArray, IntArray
from ...errors import InvalidMeshError, NotAdmissibleError, OptionError, SelfIntersectionError
from ...kernels.intersections3d import self_intersections
from ...kernels.surface import aspect_ratios
from ...results import PathIteration
from ...riemannian.discrete_geodesic import discrete_geodesic
from ...scaling import unit_scale
from ..engine.contact import ContactWarning, pair_contact
from ..engine.similarity_3d import global_similarity
from .folds import FoldTest
from .interpolation import arap_interpolation, fold_crossings
from .metric import BENDING, WEIGHT, SurfaceGraphMetric
from .morph_contact import PathContact, detour_path, graded_path
from .morph_homotopy import homotopy_start
from .morph_polish import polish_frames
from .path import RTOL, SurfacePathOptions, SurfacePathProblem

logger = logging.getLogger(__name__)

__all__ = ["SurfaceMorph", "morph_surface", "frame_measures"]

#: local/global steps at most of the start while a frame is below the worse end's quality
#: (:func:`.interpolation.arap_interpolation`'s ``iterations``)
START_ITERATIONS = 10
#: the start paths in the order tried (:func:`_initial_path`), as the log names them
STARTS = {"arap": "the as-rigid-as-possible interpolation",
          "linear": "the linear interpolation",
          "long_way": "the as-rigid-as-possible interpolation the long way round",
          "detour": "a detour of the moving parts",
          "homotopy": "the homotopy around the contact"}


def frame_measures(source: FloatArray, frames, triangles: IntArray,
                   folds: FoldTest | None = None) -> tuple[FloatArray, IntArray]:
    """Per frame the worst relative quality (aspect ratio 2r/R over its value in
    ``source``) and the number of folded triangles (against ``source``)."""
    F = np.asarray(triangles)
    q0 = aspect_ratios(source, F)
    folds = FoldTest(source, F) if folds is None else folds
    worst, count = [], []
    for Q in frames:
        with np.errstate(divide="ignore", invalid="ignore"):
            rq = np.where(q0 > 0, aspect_ratios(Q, F) / q0, 0.0)
        worst.append(float(rq.min()) if rq.size else 1.0)
        count.append(int(folds.mask(Q).sum()))
    return np.array(worst), np.array(count)


@dataclass
class SurfaceMorph:
    """What :func:`morph_surface` returns.

    Attributes
    ----------
    points : (K + 1, N, 3) float array
        The frames; the first is the source and the last the target, bitwise.
    times : (K + 1,) float array
    worst_quality, folds : per frame, the worst relative quality and the folds
        (:func:`frame_measures`)
    triangles : (T, 3) int array
    status : "healthy", "converged", "max_iterations", "stalled", "stopped", "similarity" or
        "identical"
    initial_path : "arap", "linear", "long_way", "detour" or "homotopy" (the last three with
        contact), "similarity" or "identical"
    energy : the path energy ``E`` (module docstring) at the end
    length : the frames' polygon length ``ℓ`` in the embedding
    """

    points: FloatArray
    times: FloatArray
    worst_quality: FloatArray
    folds: IntArray
    triangles: IntArray
    status: str
    initial_path: str
    energy: float = 0.0
    initial_energy: float = 0.0
    length: float = 0.0
    iterations: int = 0
    factorizations: int = 0
    seconds: float = 0.0
    weight: float = 1.0
    gradient_norm: float = field(default=0.0)
    polished: int = 0

    def linear_measures(self) -> tuple[FloatArray, IntArray]:
        """:func:`frame_measures` of linear interpolation at the same times (measured at
        unit size: the fold test's products neither overflow nor underflow at 1e±300)."""
        scale = unit_scale(self.points[0], self.points[-1], columns=3)
        V0, V1 = scale.down(self.points[0]), scale.down(self.points[-1])
        return frame_measures(V0, [(1.0 - t) * V0 + t * V1 for t in self.times],
                              self.triangles)

    @property
    def converged(self) -> bool:
        return self.status in ("healthy", "converged", "similarity", "identical")

    def summary(self) -> dict:
        """Worst relative quality over the frames and per frame, folds, linear
        interpolation's, path energy and length, iterations, seconds."""
        lin_worst, lin_folds = self.linear_measures()
        return {
            "status": self.status, "frames": int(len(self.points)),
            "worst_relative_quality": float(self.worst_quality.min()),
            "worst_relative_quality_per_frame": [float(v) for v in self.worst_quality],
            "folds": int(self.folds.sum()),
            "target_worst_relative_quality": float(self.worst_quality[-1]),
            "linear_worst_relative_quality": float(lin_worst.min()),
            "linear_folds": int(lin_folds.sum()),
            "initial_path": self.initial_path, "energy": self.energy,
            "initial_energy": self.initial_energy, "length": self.length,
            "strain_bound": self.length / self.weight, "iterations": self.iterations,
            "factorizations": self.factorizations, "gradient_norm": self.gradient_norm,
            "polished_frames": self.polished, "seconds": self.seconds,
        }


def _PathProblem(V0: FloatArray, V1: FloatArray, F: IntArray, weight: float,
                 bending: float) -> SurfacePathProblem:
    """The path energy's pieces of the frames from ``V0`` to ``V1`` (its metric's)."""
    return SurfaceGraphMetric(V0, F, weight, bending).path_problem(V1)


def _similar_frames(V0, V1, times, S) -> list:
    out = [S.at(float(t))(V0) for t in times]
    out[0], out[-1] = V0.copy(), V1.copy()
    return out


def morph_surface(source: FloatArray, target: FloatArray, triangles: IntArray,
                  frames: int = 9, *, weight: float = WEIGHT, bending: float = BENDING,
                  max_iterations: int = 10, rtol: float = RTOL,
                  stop_when_healthy: bool = True,
                  callback: Callable[[PathIteration], bool | None] | None = None,
                  contact: bool = True) -> SurfaceMorph:
    """Frames from ``source`` to ``target`` (module docstring).

    Parameters
    ----------
    source, target : (N, 3) float arrays
        The two poses (no degenerate triangle in either).
    triangles : (T, 3) int array
        The triangles of both, consistently oriented where bending is wanted.
    frames : int
        Number of frames (≥ 2), both ends included.
    weight, bending : ``w`` and ``b`` of the embedding.
    max_iterations, rtol : Levenberg–Marquardt iterations at most; stop (``"converged"``)
        when the Gauss–Newton model predicts a decrease below ``rtol·E`` for the next step
        (the start path included: then it is returned as it is, stationary to ``rtol``),
        or when a step lowered the energy by less than ``rtol·E``.
    stop_when_healthy : stop (``"healthy"``) as soon as every interior frame of the path,
        the start's included, is as healthy as the worse end (module docstring), before
        the energy tests; where these stop first, polish those below (:mod:`.morph_polish`).
    callback : called once per iteration with a :class:`PathIteration`; True stops.
    contact : keep every frame, and the segments between frames, from passing through the
        surface (:mod:`.morph_contact`) where both ends are free of
        self-intersections (else a :class:`..engine.contact.ContactWarning` gives their count and
        the morph runs without contact).

    Raises
    ------
    InvalidMeshError
        Bad shapes, a degenerate triangle in either pose.
    NotAdmissibleError
        Neither interpolation is free of folds and degenerate triangles.
    SelfIntersectionError
        With contact: no clean start path (neither interpolation, a detour nor the
        homotopy; the homotopy's line says where it stalls or how many frames it needs).
    """
    t_start = time.perf_counter()
    V0, V1 = np.asarray(source, float), np.asarray(target, float)
    F = np.asarray(triangles, np.int64)
    if V0.ndim != 2 or V0.shape[1] != 3 or V1.shape != V0.shape:
        raise InvalidMeshError(f"source and target need the same (N, 3) points, got "
                               f"{V0.shape} and {V1.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or (F.size and (F.min() < 0 or F.max() >= len(V0))):
        raise InvalidMeshError("triangles must be (T, 3) indices of existing points")
    if int(frames) < 2:
        raise OptionError(f"frames must be at least 2, got {frames}")
    K = int(frames) - 1
    times = np.linspace(0.0, 1.0, K + 1)
    used = np.unique(F)
    local = np.full(len(V0), -1)
    local[used] = np.arange(len(used))
    W0, W1, G = V0[used], V1[used], local[F]
    problem = _PathProblem(W0, W1, G, weight, bending)  # raises on a degenerate source
    if problem.embed(W1) is None:
        raise InvalidMeshError("the target has a degenerate triangle")
    diameter = float(np.linalg.norm(W0.max(0) - W0.min(0)))
    S = global_similarity(W0, W1, diameter) if len(W0) > 2 else None
    polished = 0
    if np.array_equal(V0, V1):
        path, status, it, nf, E0, gnorm = [W0.copy() for _ in times], "identical", 0, 0, 0.0, 0.0
        initial = "identical"
    elif S is not None:
        path, status, it, nf, E0, gnorm = _similar_frames(W0, W1, times, S), "similarity", 0, \
            0, 0.0, 0.0
        initial = "similarity"
    else:
        guard = _path_contact(problem, W0, W1, K + 1, contact)
        path, initial = _initial_path(problem, W0, W1, G, times, guard)
        path, status, it, nf, E0, gnorm = _minimize(problem, path, max_iterations, rtol,
                                                    callback, stop_when_healthy, guard)
        path, polished = polish_frames(problem, path, guard) if stop_when_healthy else (path, 0)
    X = [problem.embed(Q) for Q in path]
    residuals = [problem.segment(X[k], X[k + 1]) for k in range(K)]
    energy = 0.5 * float(sum(r @ r for r in residuals))
    if E0 is None or status in ("identical", "similarity"):
        E0 = energy
    length = float(sum(np.linalg.norm(r) for r in residuals))
    # the full point arrays: vertices in no triangle move linearly
    points = np.empty((K + 1,) + V0.shape)
    for k, t in enumerate(times):
        points[k] = V0 if k == 0 else V1 if k == K else (1.0 - t) * V0 + t * V1
        if 0 < k < K:
            points[k][used] = path[k]
    if status in ("identical", "similarity"):
        worst, folds = frame_measures(V0, points, F)
    else:  # the measures of the path's frames, most already taken by the tests above
        worst = np.array([problem.worst(Q) for Q in path])
        # the source against itself: every rotation the identity, no fold
        folds = np.array([0] + [int(problem.fold_mask(Q).sum()) for Q in path[1:]])
    return SurfaceMorph(points=points, times=times, worst_quality=worst, folds=folds,
                        triangles=F, status=status, initial_path=initial, energy=energy,
                        initial_energy=E0, length=length, iterations=it,
                        factorizations=nf, seconds=time.perf_counter() - t_start,
                        weight=float(weight), gradient_norm=gnorm, polished=polished)


def _path_contact(problem: _PathProblem, V0, V1, frames: int, on: bool
                  ) -> PathContact | None:
    """The contact of the path from ``V0`` to ``V1`` where ``on`` and both
    ends are free of self-intersections; a :class:`ContactWarning` with the count where
    one is not."""
    F = problem.triangles
    if not on or len(F) < 2:
        return None
    contact = pair_contact(V0, V1, F)
    if contact is None:
        counts = {end: len(self_intersections(V, F)) for end, V in (("source", V0),
                                                                   ("target", V1))}
        crossing = [f"the {end} intersects itself ({n} pairs of triangles)"
                    for end, n in counts.items() if n]
        if crossing:
            warnings.warn(" and ".join(crossing) + ": morphed without contact",
                          ContactWarning, stacklevel=3)
        return None
    return PathContact(contact, frames, problem.sqrt_m ** 2)


def _initial_path(problem: _PathProblem, V0, V1, F, times,
                  contact: PathContact | None = None) -> tuple[list, str]:
    """The as-rigid-as-possible interpolation (with its local/global steps, else without)
    where every frame is admissible, else the linear one where it is
    (:class:`NotAdmissibleError` else); with ``contact`` only a clean one, else the
    as-rigid-as-possible interpolation turning the neighbours whose short way passes
    the fold the long way round (``long_way``), else a clean
    detour (:func:`.morph_contact.detour_path`), else the homotopy
    (:func:`.morph_homotopy.homotopy_start`, its :class:`SelfIntersectionError`
    where it finds none)."""
    candidates = (("arap", lambda: arap_interpolation(V0, V1, F, times,
                                                      iterations=START_ITERATIONS,
                                                      until=problem.healthy)),
                  ("arap", lambda: arap_interpolation(V0, V1, F, times)),
                  ("linear", lambda: [(1.0 - t) * V0 + t * V1 for t in times]),
                  ("long_way", lambda: graded_path(
                      contact, lambda ts: arap_interpolation(
                          V0, V1, F, ts, long_way=True, iterations=START_ITERATIONS,
                          until=problem.healthy), len(times) - 1)
                   if fold_crossings(V0, V1, F).nnz else None),
                  ("detour", lambda: detour_path(contact, V0, V1, F, len(times) - 1)),
                  ("homotopy", lambda: homotopy_start(problem, contact, V0, V1, F,
                                                     len(times) - 1)))
    crossed = False
    for name, make in candidates[:3] if contact is None else candidates:
        if name == "homotopy" and not crossed:  # only around contact, not folds
            break
        logger.info("start path: %s", STARTS[name])
        path = make()
        if path is None:
            continue
        path[0], path[-1] = V0, V1
        if all(problem.embed(Q) is not None and problem.admissible(Q) for Q in path[1:-1]):
            if contact is None or contact.clean(path):
                return path, name
            crossed = True
    if crossed:
        raise SelfIntersectionError(
            "the morph finds no path free of self-contact: the interpolations of the ends "
            "pass through the surface and no detour of its moving parts is clean")
    raise NotAdmissibleError("neither the as-rigid-as-possible nor the linear "
                             "interpolation of the pair is free of folds and degenerate "
                             "triangles")


def _minimize(problem: SurfacePathProblem, path: list, max_iterations: int, rtol: float,
              callback, healthy: bool = False, contact: PathContact | None = None) -> tuple:
    """The discrete geodesic of the problem's metric from the frames ``path``
    (:meth:`.metric.SurfaceGraphMetric.path_model`, :class:`.path.SurfaceRules`): the
    frames, the status, iterations, factorizations, the initial energy (None where the
    start is returned as healthy, unevaluated) and the last gradient norm. With ``healthy``,
    a path (the start included) whose frames pass :meth:`.path.SurfacePathProblem.healthy`
    ends it. With ``contact`` (a clean start), the frames' barriers join the energy, each
    step is capped by the CCD of the frames' moves and a trial is taken only on a clean
    path."""
    K = len(path) - 1
    options = SurfacePathOptions(max_iterations=max_iterations, rtol=rtol,
                                 stop_when_healthy=healthy)
    report = None if callback is None else (
        lambda steps, E, gnorm: callback(PathIteration(steps, E, gnorm)))
    geo = discrete_geodesic(problem.metric, path[0], path[K], K, path=np.array(path),
                            boundary_edges=contact, options=options, callback=report)
    return (list(geo.points), geo.status, geo.nit, geo.factorizations, geo.initial_energy,
            geo.gradient_norm)
