"""Admissible planar paths built frame by frame: each frame is the previous one with the
handles moved a little, the rest extended by the metric and relaxed (a minimizing movement
of the graph metric), stepped by the one continuation loop
(:func:`..engine.continuation.march`). Every frame is reached by accepted feasible steps,
so every frame is admissible by construction.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..._typing import FloatArray, IntArray
from ...riemannian.discrete_geodesic import discrete_geodesic
from ...riemannian.path_options import LevenbergMarquardtOptions
from ...solvers import factorize_spd
from ..engine.continuation import march
from .frame_blocks import FrameBlocks
from .metric import GraphMetric

# A frame's relaxation stops when its gradient fell by this factor: the frames only need
# to be admissible and close to the minimizing movement (the final quality step does the
# rest); on the benchmark cases a tighter factor gives the same frames.
RELAX_RTOL = 1e-2
# Their Newton steps are solved to this CG residual, and so are those of move's quality
# rounds: on the move benchmarks a tighter residual gives the same iterations and results
# with more triangular solves.
RELAX_CG_RTOL = 0.1


def _step_free(n_vertices: int, handles: IntArray) -> np.ndarray:
    """The free vertices of a one-segment path from a kept frame: none of the first, all
    but the handles of the second."""
    free = np.ones((2, n_vertices), bool)
    free[0] = False
    free[1, handles] = False
    return free


def extend(metric: GraphMetric, Q: FloatArray, handles: IntArray,
           new_positions: FloatArray, factors: FrameBlocks | None = None) -> FloatArray:
    """``Q`` with the handles at ``new_positions`` and the other vertices moved by the
    linearized metric: ``δ_f = −H_ff⁻¹ H_fh δ_h`` with ``H = M + w² JᵀJ`` at ``Q``
    (through ``factors`` when given: a kept factorization of a nearby ``H_ff``).
    ``H_ff`` is the one-segment path matrix at ``(Q, Q)`` (the same structure as the
    relaxations', assembled from per-triangle blocks); ``H_fh δ_h`` is applied triangle
    by triangle."""
    N = Q.shape[0]
    free = _step_free(N, handles)
    delta = np.zeros((N, 2))
    delta[handles] = new_positions - Q[handles]
    out = Q.copy()
    out[handles] = new_positions
    if free[1].any():
        pair = np.stack([Q, Q])
        _, _, Hff, _ = metric.path_model(pair, free).normal_equations(pair)
        rhs = -metric.apply(Q, delta)[free[1]].ravel()
        step = factorize_spd(Hff.tocsr())(rhs) if factors is None else factors.solve(Hff, rhs, 1e-8)
        out[free[1]] += step.reshape(-1, 2)
    out[handles] = new_positions  # bitwise
    return out


@dataclass
class ContinuationResult:
    frames: list[FloatArray]
    times: list[float]
    relax_iterations: int = 0
    splits: int = 0
    seconds: list[float] = field(default_factory=list)


def continuation_path(
    metric: GraphMetric,
    start: FloatArray,
    handles: IntArray,
    handle_path: Callable[[float], FloatArray],
    times: FloatArray,
    *,
    boundary_edges: IntArray | None,
    strain_target: Callable[[float], FloatArray] | None = None,
    max_splits: int = 12,
    max_iterations: int = 50,
    progress: Callable[[float], None] | None = None,
) -> ContinuationResult:
    """Frames at ``times`` (increasing, from 0) of an admissible motion of the handles:
    :func:`march` with each step predicted by :func:`extend` (admissible: no triangle
    inverted, the boundary simple) and relaxed by Levenberg–Marquardt on the one-segment
    path from the last frame.

    Parameters
    ----------
    metric : GraphMetric
    start : (N, 2) admissible positions at time ``times[0]``
    handles : (k,) int array
    handle_path : callable ``s -> (k, 2)`` handle positions
    times : (F,) float array, ``times[0]`` the start
    boundary_edges : (E, 2) int array or None
    strain_target : callable ``s -> (T, 3)``, optional
        Strain each frame is relaxed towards (default: the previous frame's, i.e. a
        minimizing movement that keeps every triangle as it was).
    max_splits : int
        How many times one step may be halved before giving up (bounded effort).
    max_iterations : int
        Levenberg–Marquardt iterations per frame.
    """
    import time as _time

    free = _step_free(start.shape[0], handles)
    # shared by every step
    factors = FrameBlocks([np.arange(2 * int(free[1].sum()))], [metric.reference[free[1]]])
    options = LevenbergMarquardtOptions(gtol=1e-6, rtol=RELAX_RTOL, max_iterations=max_iterations,
                                        cg_rtol=RELAX_CG_RTOL, newton=True, factors=factors)
    nit, secs, t0 = 0, [], _time.perf_counter()
    times = np.asarray(times, float)

    def advance(Q: FloatArray, s_now: float, s_try: float) -> FloatArray | None:
        nonlocal nit
        trial = extend(metric, Q, handles, handle_path(s_try), factors)
        if not ((metric.strain.determinants(trial) > 0).all() and _simple(trial, boundary_edges)):
            return None
        anchor = metric.strain.values(Q) if strain_target is None else strain_target(s_try)
        res = discrete_geodesic(metric, Q, trial, 1, free=free, boundary_edges=boundary_edges,
                                anchor=anchor, options=options)
        nit += res.nit
        return res.points[1]

    def frame_done(s: float) -> None:
        if progress is not None:
            progress(s)
        if np.any(times[1:] == s):
            secs.append(_time.perf_counter() - t0)

    frames, splits = march(start, times, advance, max_splits=max_splits, progress=frame_done)
    return ContinuationResult(frames, [float(t) for t in times], nit, splits, secs)


def _simple(Q: FloatArray, boundary_edges: IntArray | None) -> bool:
    if boundary_edges is None:
        return True
    from ...mesh import boundary_self_intersections

    return len(boundary_self_intersections(Q, boundary_edges)) == 0
