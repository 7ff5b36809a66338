"""Morphing tetrahedral meshes with the tet distortion metric: every frame admissible
(every tet positively oriented), frames as healthy as their ends.

The pair is factored as the similarity that best fits the target's boundary to the
source's (Umeyama, followed exactly: it costs no shape strain) and a residual pair; the
residual frames are the nodes of a discrete geodesic of ``g = M + w² JᵀJ`` of the tet
distortion relative to the source (:mod:`.path`, minimized by the Riemannian layer's
:func:`...riemannian.discrete_geodesic.discrete_geodesic`, the metric's ``path_model``
by Levenberg–Marquardt, every accepted iterate admissible) between the two fixed
ends. The start is the linear interpolation of the residual pair where every frame of it
is admissible, else a minimizing movement: the boundary along each boundary piece's
similarity to its target, the interior relaxed at each step towards the interpolated
distortion ``s·φ(target)`` (:mod:`.least_squares`, admissible by construction).

No frame's boundary passes through itself: the ends are refused if theirs does, the
linear start is taken only if no frame's does, every frame of the result is checked
exactly (:class:`..engine.handles.SelfIntersectionGuard`), and on request the geodesic refuses
trials whose frames' boundaries intersect (where its start is free of it).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..._options import check_choice
from ..._typing import FloatArray, IntArray
from ...errors import InvalidMeshError, NotAdmissibleError, OptionError
from ...kernels.intersections3d import self_intersections
from ...kernels.tetrahedra import mean_ratios, signed_volumes
from ...mesh import TetMesh
from ...mesh.kinds import is_tets
from ...results import PathFrames
from ...riemannian.discrete_geodesic import discrete_geodesic
from ...riemannian.path_options import LevenbergMarquardtOptions
from ..engine.continuation import NoAdmissiblePathError, check_frames_and_weight, march
from ..engine.handles import SelfIntersectionGuard
from ..engine.similarity import HandlePath, Similarity3, fit_similarity_3d, handle_groups
from ..engine.similarity_3d import tet_boundary_faces
from .distortion import SQRT3
from .least_squares import Problem, extend, minimize
from .metric import TetGraphMetric

__all__ = ["TetMorphResult", "morph_tets"]

#: the convergence test ``|∇E| ≤ GTOL·√E`` of the discrete geodesic (as the planar morph)
GTOL = 1e-6
#: CG residual of the path's Levenberg–Marquardt steps (as the planar morph)
PATH_CG_RTOL = 0.1
#: the initial path's kinds, "auto" the first admissible of linear and continuation
INITIAL_PATHS = ("auto", "linear", "continuation")
#: a continuation step's relaxation stops when its gradient fell by this factor
STEP_RTOL = 1e-2


@dataclass
class TetFrameStats:
    """Per frame: the worst mean ratio (signed: negative where a tet is inverted) and the
    number of tets not positively oriented."""

    min_mean_ratio: FloatArray
    inverted: IntArray

    @classmethod
    def of(cls, frames, tets: IntArray) -> TetFrameStats:
        return cls(np.array([float(mean_ratios(Q, tets).min()) for Q in frames]),
                   np.array([int(np.sum(~(signed_volumes(Q, tets) > 0))) for Q in frames]))

    def as_dict(self) -> dict:
        return {"min_mean_ratio": [float(v) for v in self.min_mean_ratio],
                "inverted": [int(v) for v in self.inverted]}


@dataclass
class TetMorphResult(PathFrames):
    """Result of :func:`morph_tets` (the :class:`~meshopt_toolkit.results.Result`
    protocol).

    Attributes
    ----------
    points : (F, N, 3) float array
        The frames; ``points[0]`` is the source, ``points[-1]`` the target, bitwise.
    source : TetMesh
        The frames carry its tets, tags and names.
    stats, linear : TetFrameStats
        Per frame of this morph and of the linear interpolation of the vertices.
    status : str
        The discrete geodesic's ("converged", "stalled", "max_iter", "stopped").
    strain_bound : (F,) float array
        ``ℓ_k / w + √3 |log s| t_k``: no tet's ``Σ_j |Δφ_c|`` up to frame ``k`` exceeds it
        (``ℓ_k`` the residual frames' chord length in the metric, ``s`` the scale).
    initial_path : str
        "identity", "similarity", "linear" or "continuation".
    """

    points: FloatArray
    source: TetMesh
    times: FloatArray
    stats: TetFrameStats
    linear: TetFrameStats
    status: str
    nit: int
    energy: float
    gradient_norm: float
    strain_bound: FloatArray
    similarity: Similarity3
    initial_path: str
    seconds: float
    details: dict = field(default_factory=dict)

    @property
    def frames(self) -> list[TetMesh]:
        """The frames as meshes with the source's tets and tags (first = source)."""
        return [self.source.with_points(p) for p in self.points]

    @property
    def mesh(self) -> TetMesh:
        """The last frame: the target's points, the source's tags."""
        return self.source.with_points(self.points[-1])

    @property
    def min_mean_ratio(self) -> FloatArray:
        return self.stats.min_mean_ratio

    def summary(self) -> dict:
        q = self.stats.min_mean_ratio
        return {
            "metric": "distortion",
            "cells": "tetrahedra",
            "frames": int(len(self.points)),
            "admissible": bool((self.stats.inverted == 0).all()),
            "min_mean_ratio": float(q.min()),
            "worse_end_min_mean_ratio": float(min(q[0], q[-1])),
            "linear_inverts": bool((self.linear.inverted > 0).any()),
            "linear_min_mean_ratio": float(self.linear.min_mean_ratio.min()),
            **self.path_summary(),
            **self.details,
        }


def _check_pair(source, target) -> None:
    if not (is_tets(source) and is_tets(target)):
        raise InvalidMeshError("a tet morph needs two tetrahedral meshes, got "
                               f"{type(source).__name__} and {type(target).__name__}")
    if source.n_vertices != target.n_vertices or not np.array_equal(source.tets, target.tets):
        which = (f"{target.source}: not the same vertices and tetrahedra as {source.source}"
                 if source.source and target.source else
                 "source and target must have the same vertices and tetrahedra")
        raise InvalidMeshError(
            f"{which} (source: {source.n_vertices} vertices, {source.n_tets} tets; target: "
            f"{target.n_vertices} vertices, {target.n_tets} tets"
            + (", the tets differ)" if source.n_tets == target.n_tets
               and source.n_vertices == target.n_vertices else ")"))
    for name, mesh in (("source", source), ("target", target)):
        if not mesh.is_admissible:
            raise NotAdmissibleError(f"{mesh.source or 'the morph ' + name}: "
                                     f"{mesh.problems[0]}")


def morph_tets(source: TetMesh, target: TetMesh, frames: int = 9, *, weight: float = 1.0,
               max_iterations: int = 200, gtol: float = GTOL, newton: bool = False,
               initial: str = "auto", max_splits: int = 12, avoid_crossings: bool = False,
               callback: Callable[[int, float, float], bool | None] | None = None
               ) -> TetMorphResult:
    """Morph ``source`` into ``target`` (same vertices and tets) along a discrete geodesic
    of the tet distortion metric; every frame has every tet positively oriented and a
    boundary that does not intersect itself.

    Parameters
    ----------
    source, target : TetMesh
        Admissible meshes with the same tets.
    frames : int
        Frames (≥ 2), both ends included.
    weight : float
        ``w`` of ``M + w² JᵀJ``.
    max_iterations : int
        Levenberg–Marquardt iterations of the discrete geodesic.
    gtol : float
        Stop at ``|∇E| ≤ gtol·√E`` (or at the minimum to machine precision).
    newton : bool
        Newton steps (the residual curvature of the tet distortion) instead of
        Gauss–Newton.
    initial : "auto", "linear" or "continuation"
        The start of the geodesic (module docstring; "auto": linear where admissible).
    max_splits : int
        Halvings of a continuation step whose starts all invert a tet.
    avoid_crossings : bool
        Refuse a geodesic trial whose frames' boundaries intersect, as an inverted one
        (where the start's do not): an exact check of every interior frame per trial,
        a fifth to a third of an iteration's time at 23k tets. Without it a geodesic through
        itself is refused at the end.
    callback : callable ``(iteration, E, |∇E|) -> bool | None``, optional
        Called at every iteration; returning True stops it (status "stopped", the frames
        admissible).

    Returns
    -------
    TetMorphResult

    Raises
    ------
    OptionError
        ``frames < 2``, ``weight ≤ 0``, an unknown ``initial``.
    InvalidMeshError
        Not two tet meshes with the same vertices and tets.
    NotAdmissibleError
        An end with a tet not positively oriented.
    SelfIntersectionError
        An end whose boundary intersects itself (named), or a frame of the morph whose
        boundary does (no frame is returned).
    NoAdmissiblePathError
        ``initial="linear"`` inverts a tet, or the continuation found no admissible step.
    """
    t_start = time.perf_counter()
    check_frames_and_weight(frames, weight)
    check_choice(initial, INITIAL_PATHS, "initial path", error=OptionError)
    _check_pair(source, target)
    guard = SelfIntersectionGuard.of_morph(source, target)  # refuses crossing ends
    times = np.linspace(0.0, 1.0, int(frames))
    # vertices in no tet are left out of the solve and move linearly
    used = np.unique(source.tets)
    local = np.full(source.n_vertices, -1)
    local[used] = np.arange(len(used))
    T = local[source.tets]
    A0, A1 = np.asarray(source.points), np.asarray(target.points)
    P0, P1 = A0[used], A1[used]
    faces = tet_boundary_faces(T)
    boundary = np.unique(faces)
    crosses = None if not guard.active else (
        lambda Q: bool(len(self_intersections(Q, faces))))
    S = fit_similarity_3d(P0[boundary], P1[boundary])
    metric = TetGraphMetric(P0, T, weight)
    if np.array_equal(P0, P1):
        S = Similarity3(np.zeros(3), np.zeros(3), 0.0, np.zeros(3))
        residual, kind, geo = np.array([P0] * len(times)), "identity", None
    else:
        R1 = S.inverse(P1)
        scale = float(np.ptp(P0, axis=0).max())
        if np.allclose(R1, P0, rtol=0.0, atol=1e-12 * scale):
            # the pair differs by a similarity: so do all frames, exactly
            residual, kind, geo = np.array([P0] * len(times)), "similarity", None
        else:
            init, kind = _initial_path(metric, P0, R1, T, boundary, times, initial,
                                       max_splits, crosses)
            # trials through themselves refused on request, unless the start is one
            avoid = avoid_crossings and crosses is not None and not any(
                crosses(Q) for Q in init[1:-1])
            geo = discrete_geodesic(metric, P0, R1, len(times) - 1, path=init,
                                    boundary_edges=faces if avoid else None,
                                    options=LevenbergMarquardtOptions(
                                        max_iterations=int(max_iterations), gtol=gtol,
                                        cg_rtol=PATH_CG_RTOL, newton=newton),
                                    callback=callback)
            residual = geo.points
    moved = np.array([R if S.is_identity else S.at(float(s))(R) for s, R in zip(times, residual)])
    moved[0], moved[-1] = P0, P1
    out = np.empty((len(times),) + A0.shape)
    out[:] = (1.0 - times)[:, None, None] * A0 + times[:, None, None] * A1
    out[0], out[-1] = A0, A1  # bitwise ends, the vertices in no tet linear
    out[:, used] = moved
    stats = TetFrameStats.of(out, source.tets)
    if stats.inverted.any():
        raise NoAdmissiblePathError(f"{int(stats.inverted.max())} tets inverted in a frame "
                                    "after the similarity was put back (a bug: please report)")
    guard.check(out, motion="the morph", last=False)  # exactly, the frames written
    lengths = metric.segment_lengths(residual)
    return TetMorphResult(
        points=out, source=source, times=times, stats=stats,
        linear=TetFrameStats.of((1.0 - times)[:, None, None] * A0
                                + times[:, None, None] * A1, source.tets),
        status="converged" if geo is None else geo.status,
        nit=0 if geo is None else int(geo.nit),
        energy=0.0 if geo is None else float(geo.energy),
        gradient_norm=0.0 if geo is None else float(geo.gradient_norm),
        strain_bound=np.concatenate([[0.0], np.cumsum(lengths)]) / weight
        + SQRT3 * abs(S.log_scale) * times,
        similarity=S, initial_path=kind, seconds=time.perf_counter() - t_start)


def _initial_path(metric: TetGraphMetric, P0: FloatArray, R1: FloatArray, T: IntArray,
                  boundary: IntArray, times: FloatArray, initial: str, max_splits: int,
                  crosses=None) -> tuple[FloatArray, str]:
    """A path from ``P0`` to ``R1`` at ``times`` with every tet positive, and its kind;
    "auto" takes the linear path only where no frame's boundary intersects itself
    (``crosses`` of a frame, if given)."""
    if initial in ("auto", "linear"):
        linear = (1.0 - times)[:, None, None] * P0 + times[:, None, None] * R1
        linear[0], linear[-1] = P0, R1
        if all((metric.strain.determinants(Q) > 0).all() for Q in linear[1:-1]):
            if initial == "linear" or crosses is None or not any(
                    crosses(Q) for Q in linear[1:-1]):
                return linear, "linear"
        elif initial == "linear":
            raise NoAdmissiblePathError(
                "the linear interpolation inverts a tet (use the continuation start)")
    return _continuation(metric, P0, R1, T, boundary, times, max_splits), "continuation"


def _continuation(metric: TetGraphMetric, P0: FloatArray, R1: FloatArray, T: IntArray,
                  boundary: IntArray, times: FloatArray, max_splits: int,
                  max_iterations: int = 15) -> FloatArray:
    """Frames at ``times`` of a minimizing movement from ``P0``: the boundary along each
    boundary piece's similarity to its place in ``R1`` (:class:`.HandlePath`), each
    step started at the first admissible of the linearized extension of the boundary's
    increment and the interior kept (halved where both invert a tet), then
    ``½|Q − Q_prev|²_M + ½w²|φ(Q) − s·φ(R1)|²`` minimized with the boundary fixed (every
    accepted iterate admissible); the last frame is ``R1``."""
    problem = Problem.build(metric.strain, metric.weight, metric.mass, boundary)
    path = HandlePath(P0[boundary], R1[boundary],
                      handle_groups(boundary, tet_boundary_faces(T), len(P0)))
    phi1 = metric.strain.values(R1)

    def advance(Q: FloatArray, s_now: float, s_try: float) -> FloatArray | None:
        goal = path(s_try)
        kept = Q.copy()
        kept[boundary] = goal
        for start in (extend(problem, Q, boundary, goal), kept):
            if (metric.strain.determinants(start) > 0).all():
                return minimize(problem, start, Q, s_try * phi1, rtol=STEP_RTOL,
                                max_iterations=max_iterations, newton=True).points
        return None

    out, _ = march(P0, times[:-1], advance, max_splits=max_splits,
                   what="frame of the morph's start")
    out.append(R1.copy())
    return np.array(out)
