"""The thesis' steepest descent with Armijo backtracking (algorithm 2, §6.4.1), the
``method="steepest"`` iteration of :func:`meshopt_toolkit.optimize.optimize`."""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from .._linalg import dot as _dot
from .._typing import FloatArray
from ..errors import OptimizationError
from ..kernels.triangles import heights, quality_summary, signed_areas
from .result import IterationRecord, OptimizeResult, PhaseTimer

logger = logging.getLogger("meshopt_toolkit.optimize")


def max_travel_step(Q: FloatArray, triangles: np.ndarray, d: FloatArray) -> float:
    """Largest step allowed by the node-travel safeguard (6.23).

    A trial step ``s`` is refused when ``s |d_i| ≥ ½ h_l`` for a vertex ``i`` at local
    position ``l`` of any triangle, ``h_l`` that triangle's height from ``i``. Returns
    ``min ½ h_l / |d_i|`` (inf when ``d`` vanishes).
    """
    h = heights(Q, triangles)  # (T, 3), height from local vertex l onto the opposite edge
    speed = np.linalg.norm(d, axis=1)[triangles]  # (T, 3)
    with np.errstate(divide="ignore"):
        limit = np.where(speed > 0, 0.5 * h / speed, np.inf)
    return float(limit.min())


def run_steepest(mesh, problem, *, variant, retract, max_iter, tol, gtol, sigma, tau,
                 min_step, callback) -> OptimizeResult:
    """Steepest descent along ``−grad F`` with (6.22)'s first step and Armijo backtracking
    by ``tau`` (the travel guard (6.23) on straight lines); returns an OptimizeResult."""
    objective, penalty, metric = problem.objective, problem.penalty, problem.metric
    free, tri = problem.free, problem.triangles

    def penalty_value(Q):
        return 0.0 if penalty is None else float(penalty.value(Q))

    start = time.perf_counter()
    Q = np.array(mesh.points, dtype=float)
    timer = PhaseTimer()
    t0 = time.perf_counter()
    J = float(objective.value(Q))
    t0 = timer.add("state", t0)
    fpen = penalty_value(Q)
    F = J + fpen
    q = quality_summary(Q, tri)
    history = [
        IterationRecord(0, J, fpen, F, q.mean_shape_quality, q.min_aspect_ratio, 0.0, 0, math.nan,
                        dict(timer.seconds))
    ]
    s_prev = slope_prev = dnorm0 = None
    status = "max_iterations"
    message = f"reached the maximum of {max_iter} iterations without converging"
    for n in range(1, max_iter + 1):
        timer = PhaseTimer()
        t0 = time.perf_counter()
        dJ = objective.derivative(Q)
        t0 = timer.add("derivative", t0)
        P = dJ if penalty is None else dJ + penalty.gradient(Q)
        t0 = timer.add("penalty_derivative", t0)
        d = -metric.riesz(Q, P, free=free)  # restricted to the free vertices if any
        slope = _dot(P, d)  # dF(Q)[d]
        dnorm = float(metric.norm(Q, d))
        t0 = timer.add("gradient", t0)
        if dnorm0 is None:
            dnorm0 = dnorm
        if not slope < 0:
            if slope == 0 or dnorm == 0:
                status, message = "converged", "the gradient vanishes"
                break
            raise OptimizationError(
                f"iteration {n}: the search direction is not a descent direction "
                f"(dF[d] = {slope:.3e}); the derivative or the metric is wrong"
            )
        if gtol is not None and dnorm <= gtol * dnorm0:
            status = "converged"
            message = f"‖grad F‖ fell to {dnorm / dnorm0:.2e} of its first value (gtol {gtol:g})"
            break
        s = None if s_prev is None else s_prev * slope_prev / slope
        if s is None or s * dnorm < 1e-4:
            s = 1.0 / dnorm
        trial_steps = s * tau ** np.arange(max(1, math.ceil(math.log(min_step / s) / math.log(tau)) + 1))
        trial_steps = trial_steps[trial_steps >= min_step]
        # complete-complete: one retraction call gives every trial (None = not admissible)
        geo_points: list | None = None
        if retract is not None and len(trial_steps):
            t_r = time.perf_counter()
            # rescaling lemma: R_Q(s_k d) = R_Q((s_k / s) · s d) for the exponential map;
            # the second-order retraction has the same property
            geo_points = retract(Q, s * d, trial_steps / s)[0]
            timer.add("retraction", t_r)
        s_max = np.inf if retract is not None else max_travel_step(Q, tri, d)
        accepted = None
        backtracks = rejected = 0
        t_b = time.perf_counter()
        state_in_backtracking = 0.0
        for k, s_k in enumerate(trial_steps):
            if s_k >= s_max:
                backtracks += 1
                continue
            Qt = geo_points[k] if retract is not None else Q + s_k * d
            if Qt is None or np.any(signed_areas(Qt, tri) <= 0):
                backtracks += 1
                rejected += 1
                continue
            t_s = time.perf_counter()
            Ft, Jt = problem.values(Qt)  # +inf outside M+ (e.g. a boundary touching itself)
            state_in_backtracking += time.perf_counter() - t_s
            if not np.isfinite(Ft):
                backtracks += 1
                rejected += 1
                continue
            if Ft <= F + sigma * s_k * slope:
                accepted = (s_k, Qt, Jt, Ft)
                break
            backtracks += 1
        timer.seconds["backtracking"] += time.perf_counter() - t_b - state_in_backtracking
        timer.seconds["state"] += state_in_backtracking
        if accepted is None:
            status = "step_too_small"
            message = f"iteration {n}: no step ≥ {min_step:g} satisfies the Armijo condition"
            break
        s_k, Q, J, F = accepted
        s_prev, slope_prev = s_k, slope
        q = quality_summary(Q, tri)
        record = IterationRecord(
            n, J, F - J, F, q.mean_shape_quality, q.min_aspect_ratio, s_k, backtracks,
            dnorm, dict(timer.seconds), relative_gradient_norm=dnorm / dnorm0,
            rejected_trials=rejected,
        )
        history.append(record)
        logger.debug("iter %d: F=%.6g j=%.6g Λ=%.4f step=%.3g", n, F, J, q.mean_shape_quality, s_k)
        if callback is not None and callback(record, Q):
            status, message = "stopped", f"stopped by the callback at iteration {n}"
            break
        if tol is not None and n >= 5:
            past = np.array([h.objective for h in history[n - 5 : n]])
            if np.max(past - F) < tol:
                status = "converged"
                message = f"F changed less than {tol:g} over the last 5 iterations (6.26)"
                break
    final = mesh.with_points(Q)
    return OptimizeResult(
        mesh=final,
        x=Q,
        fun=F,
        j=J,
        nit=len(history) - 1,
        status=status,
        success=status in ("converged", "stopped"),
        message=message,
        history=history,
        seconds=time.perf_counter() - start,
        variant=variant,
    )
