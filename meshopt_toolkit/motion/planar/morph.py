"""Morphing with the per-triangle distortion metric: frames as healthy as their ends.

The pair is factored as the similarity that best fits the target's boundary to the
source's (Procrustes with scale, followed exactly) and a residual pair with the same
similarity class; the residual frames are the nodes of a discrete geodesic of
``g = M + w² JᵀJ`` (:mod:`.path`) started from the as-rigid-as-possible interpolation
(else linear, else a continuation of the boundary with the interior relaxed towards
interpolated distortions) or, for a pair made by uniform refinement, from the coarser
pair's refined frames (:mod:`.refinement`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..._typing import FloatArray, IntArray
from ...errors import InvalidMeshError
from ...kernels.admissibility import BoundaryCheck, area_problem
from ...kernels.triangles import aspect_ratios, inverse_shape_quality, signed_areas
from ...mesh import PlanarMesh, require_admissible
from ...results import PathFrames
from ...riemannian.discrete_geodesic import discrete_geodesic
from ...riemannian.geodesic_result import DiscreteGeodesic
from ...riemannian.path_options import LevenbergMarquardtOptions
from ..engine.continuation import check_frames_and_weight
from ..engine.similarity import HandlePath, Similarity, fit_similarity, handle_groups
from .continuation import continuation_path
from .metric import GraphMetric
from .refinement import refine_frames, unrefined


@dataclass
class FrameStats:
    """Per-frame quality of a sequence of frames: ``min 2r/R``, mean ``1/ψ``, inverted."""

    min_aspect_ratio: FloatArray
    mean_quality: FloatArray
    inverted: IntArray

    @classmethod
    def of(cls, frames: FloatArray, triangles: IntArray) -> FrameStats:
        ar, lam, inv = [], [], []
        for Q in frames:
            a = signed_areas(Q, triangles)
            inv.append(int(np.sum(a <= 0)))
            with np.errstate(divide="ignore", invalid="ignore"):
                ar.append(float(np.min(aspect_ratios(Q, triangles))) if inv[-1] == 0
                          else float("nan"))
                lam.append(float(np.mean(inverse_shape_quality(Q, triangles))) if inv[-1] == 0
                           else float("nan"))
        return cls(np.array(ar), np.array(lam), np.array(inv))

    def as_dict(self) -> dict:
        return {"min_aspect_ratio": [float(v) for v in self.min_aspect_ratio],
                "mean_quality": [float(v) for v in self.mean_quality],
                "inverted": [int(v) for v in self.inverted]}


@dataclass
class DistortionMorph(PathFrames):
    """Result of :func:`distortion_morph`.

    Attributes
    ----------
    points : (F, N, 2) float array
        The frames; ``points[0]`` is the source, ``points[-1]`` the target, bitwise.
    times : (F,) float array
    stats, linear, rigid : FrameStats
        Quality per frame of this morph, of linear and of as-rigid-as-possible
        interpolation at the same times.
    status : str
        The discrete geodesic's status ("converged", "stalled", "max_iter").
    gradient_norm, energy : float
    strain_bound : (F,) float array
        ``ℓ_k / w``: no triangle's distortion changed by more than this up to frame ``k``.
    initial_path : str
        "rigid", "linear", "continuation", or "coarse-to-fine (…)" with the coarsest
        level's kind.
    details : dict
        ``levels``: per level of a coarse-to-fine morph (coarsest first; one entry
        otherwise), its triangles, iterations, status and seconds.
    """

    points: FloatArray
    times: FloatArray
    stats: FrameStats
    linear: FrameStats
    rigid: FrameStats
    status: str
    gradient_norm: float
    energy: float
    nit: int
    strain_bound: FloatArray
    similarity: Similarity
    initial_path: str
    seconds: float
    details: dict = field(default_factory=dict)

    triangles: IntArray | None = None
    method: str = "discrete"
    metric_name: str = "distortion metric"
    #: the source mesh: the frames carry its tags
    source: PlanarMesh | None = None

    @property
    def frames(self) -> list[PlanarMesh]:
        """The frames as meshes with the source's tags (first = source, last = target)."""
        return self.meshes(like=self.source)

    @property
    def mesh(self) -> PlanarMesh:
        """The last frame (the target's points, the source's tags)."""
        return self.frames[-1]

    @property
    def min_aspect_ratio(self) -> FloatArray:
        return self.stats.min_aspect_ratio

    @property
    def linear_min_aspect_ratio(self) -> FloatArray:
        return self.linear.min_aspect_ratio

    @property
    def rigid_min_aspect_ratio(self) -> FloatArray:
        return self.rigid.min_aspect_ratio

    def meshes(self, like: PlanarMesh | None = None) -> list[PlanarMesh]:
        """The frames as meshes (tags of ``like`` kept when given)."""
        if like is not None:
            return [like.as_planar().with_points(p) for p in self.points]
        return [PlanarMesh(p, self.triangles) for p in self.points]

    def summary(self) -> dict:
        worst_end = float(min(self.stats.min_aspect_ratio[0], self.stats.min_aspect_ratio[-1]))
        return {
            "metric": "distortion",
            "frames": int(len(self.points)),
            "admissible": bool((self.stats.inverted == 0).all()) and _admissible_path(
                self.points, self.triangles, PlanarMesh(self.points[0], self.triangles)
                .boundary_edges),
            "min_aspect_ratio": float(np.min(self.stats.min_aspect_ratio)),
            "worse_end_min_aspect_ratio": worst_end,
            "target_error": 0.0,
            "linear_inverts": bool((self.linear.inverted > 0).any()),
            "rigid_inverts": bool((self.rigid.inverted > 0).any()),
            **self.path_summary(),
            "rigid": self.rigid.as_dict(),
            **self.details,
        }


def _admissible_path(frames: FloatArray, triangles: IntArray, boundary_edges: IntArray) -> bool:
    """Every frame admissible: the exact test of ``kernels.admissibility`` (areas, a
    simple boundary, loops nested as the boundary of an embedded region)."""
    tri_t = np.ascontiguousarray(np.asarray(triangles).T)
    check = BoundaryCheck(boundary_edges, np.unique(boundary_edges))
    return all(area_problem(Q, tri_t) is None and check.test(Q) is None for Q in frames)


#: CG residual of the path's Levenberg–Marquardt steps: looser costs no frame quality and
#: saves CG iterations (docs/design-notes.md, "Morph solver settings"; bench_morph.py --growth).
PATH_CG_RTOL = 0.1

#: The morph's convergence test ``|∇E| ≤ GTOL·√E`` (:func:`.discrete_geodesic`), relative so
#: that it is resolution-independent; below it no reported digit of a frame changes.
GTOL = 1e-6

#: A level started from the coarser level's refined frames is close to its minimizer: its
#: steps are Newton's (:func:`.discrete_geodesic`) with CG to this relative residual.
REFINED_CG_RTOL = 1e-2

#: The damping's decrease after a well-predicted step on such a level, so that Newton's
#: convergence turns quadratic (not for ``move``, whose relaxations start far away).
REFINED_LAMBDA_DECREASE = 0.01

#: A pair that is a uniform refinement of a pair with at least this many triangles is
#: morphed coarse-to-fine (cheaper iterations on the finest level).
COARSE_MIN_TRIANGLES = 5000


def distortion_morph(
    source: PlanarMesh,
    target: PlanarMesh,
    frames: int = 9,
    *,
    weight: float = 1.0,
    max_iterations: int = 200,
    callback: Callable[[int, float, float], None] | None = None,
    coarse_min_triangles: int = COARSE_MIN_TRIANGLES,
    gtol: float = GTOL,
) -> DistortionMorph:
    """Morph ``source`` into ``target`` (same connectivity) along a discrete geodesic of the
    per-triangle distortion metric.

    Parameters
    ----------
    source, target : PlanarMesh
        Admissible meshes with the same triangles.
    frames : int
        Number of frames (≥ 2) including both ends.
    weight : float
        ``w`` in ``g = M + w² JᵀJ``.
    max_iterations : int
        Levenberg–Marquardt iterations of the discrete geodesic.
    callback : callable ``(iteration, E, |∇E|) -> bool | None``, optional
        Called at every iteration of the finest level; returning True stops it.
    coarse_min_triangles : int
        A pair made by :meth:`~meshopt_toolkit.mesh.PlanarMesh.refine` from a pair with at
        least this many triangles (and admissible ends) is morphed coarse-to-fine: the
        coarser pair's frames, refined, start the finer pair's discrete geodesic
        (:mod:`.refinement`; recursively, while the coarser pair is large enough). The
        result is the same minimizer's frames; ``details["levels"]`` lists each level.
    gtol : float
        Every level stops at ``|∇E| ≤ gtol · √E`` (or at the minimum to machine
        precision); the finest level's status and gradient are reported.

    Returns
    -------
    DistortionMorph
    """
    from ...fem.interpolation import arap_interpolation

    t_start = time.perf_counter()
    check_frames_and_weight(frames, weight)
    source = require_admissible(source, "morph (source)")
    target = require_admissible(target, "morph (target)")
    if source.n_vertices != target.n_vertices or not np.array_equal(source.triangles,
                                                                    target.triangles):
        raise InvalidMeshError("source and target must have the same vertices and triangles")
    tri = source.triangles
    P0, P1 = source.points, target.points
    be = source.boundary_edges
    boundary = np.unique(be)
    S = fit_similarity(P0[boundary], P1[boundary])  # the domain's motion
    R1 = S.inverse(P1)
    times = np.linspace(0.0, 1.0, int(frames))
    rigid_frames = arap_interpolation(P0, P1, tri, times)
    linear_frames = np.array([(1 - s) * P0 + s * P1 for s in times])
    metric = GraphMetric(P0, tri, weight)
    res, kind, levels = _residual_morph(metric, R1, be, times, max_iterations, callback,
                                        coarse_min_triangles, gtol)
    out = np.array([S.at(float(s))(R) for s, R in zip(times, res.points)])
    out[0], out[-1] = P0, P1
    if np.array_equal(P0, P1):  # the geodesic from a mesh to itself stays, bit for bit
        out[:] = P0
    lengths = metric.segment_lengths(res.points)
    return DistortionMorph(
        points=out, times=times, stats=FrameStats.of(out, tri),
        linear=FrameStats.of(linear_frames, tri), rigid=FrameStats.of(rigid_frames, tri),
        status=res.status, gradient_norm=res.gradient_norm, energy=res.energy, nit=res.nit,
        strain_bound=np.concatenate([[0.0], np.cumsum(lengths)]) / weight, similarity=S,
        initial_path=kind, seconds=time.perf_counter() - t_start, triangles=tri,
        details={"levels": levels}, source=source)


def _residual_morph(metric: GraphMetric, R1: FloatArray, be: IntArray, times: FloatArray,
                    max_iterations: int, callback, coarse_min_triangles: int, gtol: float
                    ) -> tuple[DiscreteGeodesic, str, list[dict]]:
    """The discrete geodesic of ``metric`` from its reference ``P0`` to the residual target
    ``R1``, its initial path's kind and, per level (coarsest first), triangles, iterations,
    status and seconds.

    When the pair is a uniform refinement of a pair with at least ``coarse_min_triangles``
    triangles whose ends are admissible, that pair's path (itself coarse-to-fine where it
    can be), refined, is the start (:mod:`.refinement`)."""
    from ...fem.interpolation import arap_interpolation

    P0, tri = metric.reference, metric.triangles
    init, kind, levels = None, "", []
    coarse = unrefined(P0, tri) if len(tri) >= 4 * coarse_min_triangles else None
    if coarse is not None:
        n = coarse.n_vertices
        if _admissible_path(R1[None, :n], coarse.triangles, coarse.boundary_edges):
            coarse_res, coarse_kind, levels = _residual_morph(
                GraphMetric(coarse.points, coarse.triangles, metric.weight), R1[:n],
                coarse.boundary_edges, times, max_iterations, None, coarse_min_triangles, gtol)
            init = refine_frames(coarse_res.points, coarse)
            init[0], init[-1] = P0, R1
            kind = f"coarse-to-fine ({coarse_kind})"
    refined = init is not None  # from the coarser level's frames
    if init is None:
        init = arap_interpolation(P0, R1, tri, times)
        kind = "rigid"
        if not _admissible_path(init[1:-1], tri, be):
            init = np.array([(1 - s) * P0 + s * R1 for s in times])
            kind = "linear"
            if not _admissible_path(init[1:-1], tri, be):
                b = np.unique(be)
                phi1 = metric.strain.values(R1)
                cont = continuation_path(
                    metric, P0, b, HandlePath(P0[b], R1[b], handle_groups(b, be, len(P0))),
                    times[:-1], boundary_edges=be, strain_target=lambda s: s * phi1)
                init = np.array([*cont.frames, R1])
                kind = "continuation"
    free = np.ones((len(times), len(P0)), bool)
    free[0] = free[-1] = False
    t0 = time.perf_counter()
    steps = (dict(newton=True, cg_rtol=REFINED_CG_RTOL, lambda_decrease=REFINED_LAMBDA_DECREASE)
             if refined else dict(cg_rtol=PATH_CG_RTOL))
    res = discrete_geodesic(metric, init[0], init[-1], len(times) - 1, path=init, free=free,
                            boundary_edges=be, callback=callback,
                            options=LevenbergMarquardtOptions(
                                max_iterations=max_iterations, gtol=gtol, **steps))
    levels.append({"triangles": int(len(tri)), "iterations": int(res.nit),
                   "status": res.status, "seconds": float(time.perf_counter() - t0)})
    return res, kind, levels
