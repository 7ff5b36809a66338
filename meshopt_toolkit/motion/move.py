"""Prescribed motion: move handle vertices exactly to targets, keep every triangle healthy.

``move`` factors the motion into the similarity that best fits the handles (followed
exactly, free of strain) and a residual motion of the handles along :class:`HandlePath`
(each connected piece of boundary turns and scales with its own best similarity), built
frame by frame as a minimizing movement of the graph metric ``M + w² JᵀJ`` of the triangle
distortion (:mod:`.engine.continuation`), and finished by a quality step with the handles fixed
that presses on the worst triangles. Every frame is admissible by construction (every
accepted step is checked) and the handles end bitwise at their targets.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from .._options import require_at_least, require_positive
from .._typing import FloatArray, IntArray
from ..conversions import Carried
from ..cores import thread_budget
from ..errors import InvalidMeshError
from ..kernels.admissibility import BoundaryCheck, area_problem, target_loop_problem
from ..kernels.triangles import aspect_ratios, inverse_shape_quality, signed_areas
from ..mesh import PlanarMesh, require_admissible
from ..mesh.kinds import SURFACE, TETS, class_kind
from ..riemannian.discrete_geodesic import discrete_geodesic
from ..riemannian.path_options import LevenbergMarquardtOptions
from ..results import DoneMotion
from ..scaling import UnitScale, at_unit_size, size_scale
from .engine.continuation import NoAdmissiblePathError, frame_times
from .engine.handles import (SelfIntersectionGuard, check_handle_indices, check_handles,
                             distinct_handles)
from .engine.pinned_cells import pinned, turned_over_problem
from .engine.polish import quality_rounds
from .engine.similarity import HandlePath, Similarity, fit_similarity, handle_groups
from .planar.continuation import RELAX_CG_RTOL, continuation_path
from .planar.distortion import TriangleDistortion
from .planar.frame_blocks import FrameBlocks
from .planar.metric import GraphMetric
from .surface.mesh_move import move_surface_mesh
from .tets.move import move_tet_mesh

__all__ = ["MoveResult", "move", "NoAdmissiblePathError"]


@dataclass
class MoveResult(DoneMotion):
    """Result of :func:`move`.

    Attributes
    ----------
    mesh : PlanarMesh
        The moved mesh (same connectivity and tags), handles exactly at their targets.
    frames : list of PlanarMesh
        The motion (first = input, last = ``mesh``): ``frames`` meshes when asked for,
        else the input and ``mesh``.
    min_aspect_ratio, mean_quality : (F,) float arrays
        Per frame: ``min 2r/R`` (5.49) and ``Λ`` (6.25).
    handle_error : float
        ``max |q_h − target_h|`` (0.0: handles are set bitwise).
    seconds : float
    similarity : Similarity
        The similarity factored out of the motion.
    strain_bound : (F,) float array
        ``ℓ_k / w``: the bound on every triangle's strain change up to frame k.
    """

    mesh: PlanarMesh
    frames: list[PlanarMesh]
    min_aspect_ratio: FloatArray
    mean_quality: FloatArray
    handle_error: float
    seconds: float
    similarity: Similarity
    strain_bound: FloatArray
    inverted: int = 0
    details: dict = field(default_factory=dict)

    def summary(self) -> dict:
        return {
            "status": self.status,
            "inverted": int(self.inverted),
            "min_aspect_ratio": float(self.min_aspect_ratio[-1]),
            "mean_quality": float(self.mean_quality[-1]),
            "min_aspect_ratio_per_frame": [float(v) for v in self.min_aspect_ratio],
            "handle_error": float(self.handle_error),
            "seconds": float(self.seconds),
            "similarity": self.similarity.as_dict(),
            **self.details,
        }

    def scaled_up(self, scale: UnitScale) -> MoveResult:
        """This motion of the mesh at unit size, at the user's scale (meshes, the
        similarity's centre and shift, the handle error; the rest is scale-free)."""
        return replace(self, mesh=scale.mesh_up(self.mesh),
                       frames=[scale.mesh_up(m) for m in self.frames],
                       similarity=self.similarity.scaled_up(scale),
                       handle_error=float(scale.up(self.handle_error)))


def _check_handles(mesh: PlanarMesh, handles, targets) -> tuple[IntArray, FloatArray | None]:
    """The checks of :func:`~.engine.handles.check_handles` in the plane, each handle once
    (:func:`~.engine.handles.distinct_handles`); a target path takes each handle once."""
    if callable(targets):
        h = check_handle_indices(handles, mesh.n_vertices)
        if np.unique(h).size != h.size:
            raise InvalidMeshError("duplicate handles with a target path: give each once")
        return h, None
    return distinct_handles(*check_handles(handles, targets, mesh.n_vertices, dim=2))


# A quality round stops when its gradient fell by this factor: Newton's steps are then in
# their fast phase, and the rounds' weights change the problem anyway (measured on the
# twelve benchmark cases: the same min AR to 3 digits as running each round to 1e-6, in
# 4 instead of 6–7 iterations per round).
QUALITY_RTOL = 1e-3


def _finish(metric: GraphMetric, Q: FloatArray, handles: IntArray, boundary_edges: IntArray,
            relax_iterations: int, rounds: int) -> tuple[FloatArray, dict]:
    """The final quality step with the handles fixed (see :func:`move`): proximal
    least-squares rounds on the distortion from equilateral triangles of the source's
    areas, each round's triangle weights those of the last times ``max(1, |F_t|/rms|F|)^½``
    (``|F_t|² = 1/ψ_t² − 1``): the triangles that stay the worst weigh more and more, a
    fit that moves from least squares towards the worst triangle. The mesh with the best
    minimum aspect ratio is kept (the unfinished one included).

    Measured on the move benchmarks' twelve cases (2.7k–4.2k triangles), against fresh
    weights ``max(1, |F_t|/rms|F|)`` in three rounds (an ℓ⁴ fit, whose third round undid
    the second's gain on the worst triangles): min AR higher on eleven (90° annulus turn
    0.224 → 0.313, cylinder 0.01 from the wall 0.011 → 0.018); the 180° turn, which moves
    with any change of path (0.027–0.035 with equally valid settings), 0.029 → 0.029.
    Mean Λ within 4 % on nine (cylinder pushed down 0.3 1.15 → 1.20, the wall case 1.45 →
    1.88, the 180° turn 4.67 → 4.41)."""
    tri = metric.triangles
    free = np.ones((2, len(Q)), bool)
    free[0] = False
    free[1, handles] = False
    absolute = TriangleDistortion.equilateral(metric.reference, tri)
    # one preconditioner for the rounds (their matrices differ by the weights only)
    factors = FrameBlocks([np.arange(2 * int(free[1].sum()))], [metric.reference[free[1]]])

    def relax(Q, weights):
        m = GraphMetric(metric.reference, tri, metric.weight, triangle_weights=weights)
        m.strain = absolute
        res = discrete_geodesic(m, Q, Q, 1, free=free, boundary_edges=boundary_edges,
                                anchor=np.zeros((len(tri), 3)),
                                options=LevenbergMarquardtOptions(
                                    gtol=1e-6, rtol=QUALITY_RTOL, max_iterations=relax_iterations,
                                    cg_rtol=RELAX_CG_RTOL, newton=True, factors=factors))
        return res.points[1], res.nit

    def sizes(Q):
        phi = absolute.values(Q)
        return np.hypot(phi[:, 1], phi[:, 2])

    best, nit, kept = quality_rounds(Q, rounds, relax, lambda Q: aspect_ratios(Q, tri).min(),
                                     sizes)
    return best, {"iterations": nit, "kept": kept}


def _frame_quality(points: FloatArray, triangles: IntArray) -> tuple[float, float]:
    return float(aspect_ratios(points, triangles).min()), float(
        inverse_shape_quality(points, triangles).mean())


def _check_options(frames, steps, relax_iterations, quality_rounds, max_splits, weight) -> None:
    """:class:`OptionError` for an option out of range (see :func:`move`)."""
    require_at_least("frames", frames, 2)  # the input and the result
    for name, value in (("steps", steps), ("relax_iterations", relax_iterations),
                        ("quality_rounds", quality_rounds)):
        require_at_least(name, value, 1)
    require_at_least("max_splits", max_splits, 0)
    require_positive("weight", weight)


#: the solver of each kind of mesh that has one by its class
#: (:func:`~..mesh.kinds.class_kind`; a PlanarMesh is moved by :func:`move` itself)
_SOLVERS: dict[str, Callable] = {TETS: move_tet_mesh, SURFACE: move_surface_mesh}


def _solver(mesh) -> Callable | None:
    """The solver of ``mesh``'s kind, None for a planar one."""
    return _SOLVERS.get(class_kind(mesh))


def move(
    mesh: PlanarMesh,
    handles,
    targets,
    *,
    frames: int | None = None,
    steps: int = 4,
    weight: float = 1.0,
    relax_iterations: int = 15,
    quality_rounds: int | None = None,
    finish_frames: bool = True,
    max_splits: int = 12,
    progress: Callable[[float], None] | None = None,
    contact: bool = True,
) -> MoveResult:
    """Move the ``handles`` vertices exactly to ``targets``; place the rest to keep quality.

    Parameters
    ----------
    mesh : PlanarMesh, TetMesh, SurfaceMesh, or a meshio, trimesh or pymeshlab mesh
        An admissible mesh. A :class:`~meshopt_toolkit.mesh.TetMesh` is moved by
        :func:`~meshopt_toolkit.motion.tets.move.move_tet_mesh` (targets ``(k, 3)``, no
        callable path, ``finish_frames`` unused), which returns a ``TetMeshMoveResult``.
        A :class:`~meshopt_toolkit.mesh.SurfaceMesh` is moved by
        :func:`~meshopt_toolkit.motion.surface.mesh_move.move_surface_mesh` (targets
        ``(k, 3)``; no boundary is kept unless its vertices are handles), which returns a
        ``SurfaceMeshMoveResult``. A ``trimesh.Trimesh``, ``pymeshlab.Mesh`` (surfaces) or
        ``meshio.Mesh`` (tets, planar triangles with ``(k, 2)`` targets, or a surface) is
        moved as that mesh (:class:`~meshopt_toolkit.conversions.Carried`) and comes back
        as a ``CarriedResult`` whose meshes are of the type given, with everything the
        object carries but its points (uv, colours, attributes, point and cell data, …;
        normals of the new points).
    handles : (k,) int array
        Vertex indices (any vertices; typically the boundary). Duplicates must agree.
    targets : (k, 2) float array, or callable ``t -> (k, 2)``
        Final handle positions, or the whole handle path for ``t ∈ [0, 1]`` (then
        ``targets(0)`` should be the handles' positions and no similarity is factored out).
    frames : int, optional
        Return the motion as this many meshes (≥ 2, first = input, last = result).
    steps : int
        Continuation steps (each is split further where needed; with ``frames``, at least
        ``frames − 1``). Measured on the twelve benchmark cases, 4 and 8 steps give the
        same min AR on ten; on the two most strained (annulus hole turned 180°, cylinder
        moved 1.5 along the channel) the result moves by up to 25 % either way with any
        change of the path (steps, solver tolerances), at 2.7k and 11k triangles alike.
    weight : float
        ``w`` of the metric ``M + w² JᵀJ``; larger keeps triangle shapes more rigidly.
    relax_iterations : int
        Levenberg–Marquardt iterations of each relaxation.
    quality_rounds : int, optional
        Default 6 (4 for a TetMesh). Rounds of the final quality step (handles fixed):
        least squares of the distortion from equilateral triangles, each round weighting the
        triangles that stay the worst more (towards a fit of the worst triangle); the round
        with the best minimum aspect ratio is kept.
    finish_frames : bool
        With ``frames``: give every intermediate frame the same quality step (handles
        fixed where they are at that time). The continuation's own frames are admissible
        but squeezed towards the end (90° annulus turn, 9 frames: min AR 0.19 at 45°,
        0.075 at 79° before the step); False returns them as they are, for speed.
    progress : callable ``fraction -> None``, optional
        Called with the fraction of the work done, in [0, 1].
    contact : bool
        A surface: keep it from passing through itself along the motion
        (:mod:`~meshopt_toolkit.motion.engine.contact`) where its rest is free of
        self-intersections; a TetMesh: keep the free parts of its boundary from passing
        through each other and the handles (:mod:`~meshopt_toolkit.motion.tets.contact`);
        False: the motion as without contact, the result still checked.

    Returns
    -------
    MoveResult
        Every kind of mesh is moved at unit size (divided by its own size,
        :func:`..scaling.at_unit_size`; targets alike) and scaled back, so a mesh scaled
        by any factor gives the result scaled by it (to rounding; exactly for powers of
        two), and meshes near 1e±300 move as at unit size; the result's quality numbers
        are scale-free.

    Raises
    ------
    OptionError
        ``frames < 2``, ``steps < 1``, ``weight <= 0`` or another option out of range.
    InvalidMeshError
        Bad handles or targets, targets that make the boundary cross itself, or that
        turn over a cell whose vertices are all handles (a mirror image turns every
        cell over; :mod:`.engine.pinned_cells`).
    SelfIntersectionError
        In space: a tet mesh whose boundary intersects itself, targets that make it (or a
        surface free of self-intersections) intersect itself, or a motion that does
        (:class:`~meshopt_toolkit.motion.engine.handles.SelfIntersectionGuard`).
    NoAdmissiblePathError
        No admissible interior found after a bounded effort.
    """
    if (carried := Carried.of(mesh)) is not None:  # a library object: moved as our mesh
        return carried.result(move(
            carried.mesh, handles, targets, frames=frames, steps=steps, weight=weight,
            relax_iterations=relax_iterations, quality_rounds=quality_rounds,
            finish_frames=finish_frames, max_splits=max_splits, progress=progress,
            contact=contact))
    relax_iterations = relax_iterations
    solver = _solver(mesh)
    if solver is not None:  # another kind of mesh: its own solver, the same options
        _check_options(frames, steps, relax_iterations, quality_rounds, max_splits, weight)
        rounds = {} if quality_rounds is None else {"quality_rounds": quality_rounds}
        guard = SelfIntersectionGuard(mesh, handles, targets)  # refuses crossing targets
        result = at_unit_size(
            lambda m, t: solver(m, handles, t, frames=frames, steps=steps, weight=weight,
                                relax_iterations=relax_iterations, max_splits=max_splits,
                                progress=progress, contact=contact,
                                **rounds),
            size_scale(mesh, columns=3), (mesh, targets),
            lambda r, scale: _scaled_up(r, scale, mesh, handles, targets))
        guard.check(result.frames)  # and a motion through itself
        return result
    quality_rounds = 6 if quality_rounds is None else quality_rounds
    _check_options(frames, steps, relax_iterations, quality_rounds, max_splits, weight)
    mesh = require_admissible(mesh, "move")
    _check_handles(mesh, handles, targets)  # named in the user's units
    options = dict(frames=frames, steps=steps, weight=weight, relax_iterations=relax_iterations,
                   quality_rounds=quality_rounds, finish_frames=finish_frames,
                   max_splits=max_splits, progress=progress)
    return at_unit_size(lambda m, t: _move_planar(m, handles, t, **options),
                        size_scale(mesh), (mesh, targets),
                        lambda r, scale: _scaled_up(r, scale, mesh, handles, targets))


def _scaled_up(result, scale: UnitScale, mesh, handles, targets):
    """A motion of the mesh at unit size at the user's scale: every length of the
    result, the vertices it left alone bitwise, the handles bitwise at their targets."""
    points = [scale.points_up(f.points, mesh.points) for f in result.frames[:-1]]
    frames = [mesh if np.array_equal(p, mesh.points) else mesh.with_points(p) for p in points]
    frames.append(mesh.with_points(_at_targets(scale.points_up(result.frames[-1].points,
                                                               mesh.points), handles, targets)))
    if isinstance(result, MoveResult):
        return replace(result.scaled_up(scale), mesh=frames[-1], frames=frames)
    return replace(result, mesh=frames[-1], frames=frames,
                   motion=result.motion.scaled_up(scale))


def _at_targets(points: FloatArray, handles, targets) -> FloatArray:
    """``points`` with the handles bitwise at their final targets."""
    out = np.array(points)
    out[np.asarray(handles)] = targets(1.0) if callable(targets) else targets
    return out


def _move_planar(mesh: PlanarMesh, handles, targets, *, frames, steps, weight, relax_iterations,
                 quality_rounds, finish_frames, max_splits, progress) -> MoveResult:
    """:func:`move` of an admissible planar mesh (options checked)."""
    t_start = time.perf_counter()
    P = mesh.points
    tri = mesh.triangles
    h, tg = _check_handles(mesh, handles, targets)
    be = mesh.boundary_edges
    if tg is not None:
        final_guess = P.copy()
        final_guess[h] = tg
        # loops that are all handles: fixed by the targets, checked before any work
        if problem := target_loop_problem(P, final_guess, be, h):
            raise InvalidMeshError(f"the targets {problem}")
        if problem := turned_over_problem(signed_areas(final_guess, tri) <= 0,
                                          pinned(tri, h, len(P)), "triangle"):
            raise InvalidMeshError(problem)
        # handles that stay exactly: no similarity at all (the identity stays bit for bit)
        S = Similarity(0j, 0j, 0.0, 0.0) if np.array_equal(P[h], tg) else fit_similarity(P[h], tg)
        residual_targets = S.inverse(tg)
        path = HandlePath(P[h], residual_targets, handle_groups(h, be, mesh.n_vertices))
    else:
        S = Similarity(0j, 0j, 0.0, 0.0)
        path = targets
        tg = np.asarray(targets(1.0), float)
    metric = GraphMetric(P, tri, weight)
    times, pick = frame_times(steps, frames)
    if not callable(targets) and np.allclose(residual_targets, P[h], rtol=0,
                                             atol=1e-12 * mesh.diameter):
        # the handles move by a similarity: so does the whole mesh (no strain at all)
        residual = [P.copy() for _ in times]
        details = {"continuation_splits": 0, "relax_iterations": 0}
    else:
        inner = pick[1:-1] if frames is not None and finish_frames else []
        # progress: the continuation and each quality step (about as long as the
        # continuation) share [0, 1]
        share = 1.0 / (2 + len(inner))
        report = (lambda s: progress(s * share)) if progress is not None else None
        cont = continuation_path(metric, P, h, path, times, boundary_edges=be,
                                 max_splits=max_splits, max_iterations=relax_iterations,
                                 progress=report)
        residual = cont.frames
        residual[-1], finish = _finish(metric, residual[-1], h, be, relax_iterations,
                                       quality_rounds)
        details = {"continuation_splits": cont.splits,
                   "relax_iterations": cont.relax_iterations + finish["iterations"],
                   "finish_rounds_kept": finish["kept"]}
        if report is not None:
            report(2.0)
        if len(inner):
            # independent problems; their factorizations and solves release the GIL
            # (CHOLMOD through .._cholmod, or SuperLU; a pool of its own: the frame
            # pool of .path may be in use by the steps)
            with ThreadPoolExecutor(min(len(inner), thread_budget())) as pool:
                done = pool.map(lambda i: _finish(metric, residual[i], h, be, relax_iterations,
                                                  quality_rounds), inner)
                for n, (i, (Q, more)) in enumerate(zip(inner, done), start=1):
                    residual[i] = Q
                    details["relax_iterations"] += more["iterations"]
                    if report is not None:
                        report(2.0 + n)
    moved = []
    for s, R in zip(times, residual):
        Q = S.at(float(s))(R) if not S.is_identity else R.copy()
        moved.append(Q)
    moved[-1][h] = tg  # bitwise at the targets
    # the proven bound along the frames returned: chords of the embedding (triangle inequality)
    lengths = metric.segment_lengths(np.stack([residual[i] for i in pick]))
    bound = np.concatenate([[0.0], np.cumsum(lengths)]) / weight
    q = np.array([_frame_quality(moved[i], tri) for i in pick])
    inverted = int(np.sum(metric.strain.determinants(moved[-1]) <= 0))
    problem = (area_problem(moved[-1], mesh._triangle_columns)
               or BoundaryCheck(be, mesh.boundary_vertices).test(moved[-1]))
    if inverted or problem:
        raise NoAdmissiblePathError(f"the result is not admissible: {problem or 'inverted'}")
    result_mesh = mesh.with_points(moved[-1])
    out = ([mesh.with_points(moved[i]) for i in pick] if frames is not None
           else [mesh, result_mesh])
    return MoveResult(
        mesh=result_mesh, frames=out, min_aspect_ratio=q[:, 0], mean_quality=q[:, 1],
        handle_error=float(np.abs(moved[-1][h] - tg).max()),
        seconds=time.perf_counter() - t_start, similarity=S, strain_bound=bound,
        inverted=inverted, details=details)
