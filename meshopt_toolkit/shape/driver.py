"""The iteration of ``optimize(method="lbfgs" | "cg")``: Riemannian L-BFGS and nonlinear
conjugate gradients (Hestenes–Stiefel+) on ``M+`` with a Wolfe line search.

Per iteration: the derivative ``P = dF(Q)`` (already known from the line search), the
gradient ``G_Q⁻¹P`` (its norm is the stopping quantity), the direction
(:mod:`.directions`), the line search (:mod:`.linesearch`) along the variant's
retraction — ``Q + t d`` with trials capped at ``segment_fraction`` of the first
degeneracy along the line (:func:`.problem.segment_limit`), or a retraction of the
complete metric (:mod:`meshopt_toolkit.riemannian.retractions`; the Wolfe slope from the
retraction curve's velocity) — then the curvature pair (L-BFGS) and the stopping tests.
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from ..errors import OptimizationError
from ..kernels.triangles import quality_summary
from .directions import LBFGSMemory, hestenes_stiefel_plus
from .linesearch import wolfe_line_search
from .problem import ShapeProblem, segment_limit
from .result import IterationRecord, OptimizeResult, PhaseTimer

logger = logging.getLogger(__name__)

#: Wolfe curvature constant per method (Nocedal & Wright: 0.9 for quasi-Newton, 0.1 for CG)
DEFAULT_C2 = {"lbfgs": 0.9, "cg": 0.1}

#: the relative objective-change test looks this many iterations back: the relative
#: version of the thesis' rule (6.26), robust to a single short step
FTOL_WINDOW = 5


def run_descent(
    mesh,
    problem: ShapeProblem,
    *,
    method: str,
    variant: str,
    retraction,
    max_iter: int,
    gtol: float | None,
    ftol: float | None,
    memory: int,
    c1: float,
    c2: float | None,
    segment_fraction: float,
    min_step: float,
    callback,
    h0=None,
):
    """Run L-BFGS (``method="lbfgs"``) or HS+ CG (``"cg"``); returns an OptimizeResult."""
    c2 = DEFAULT_C2[method] if c2 is None else float(c2)
    tri = problem.triangles
    start = time.perf_counter()
    Q = np.array(mesh.points, dtype=float)
    timer = PhaseTimer()
    F, J = problem.values(Q)
    if not math.isfinite(F):
        raise OptimizationError("the objective is not finite at the initial mesh")
    P = problem.derivative(Q)
    q = quality_summary(Q, tri)
    history = [IterationRecord(0, J, F - J, F, q.mean_shape_quality, q.min_aspect_ratio, 0.0, 0,
                               math.nan, dict(timer.seconds), method=method)]
    lbfgs = LBFGSMemory(memory) if method == "lbfgs" else None
    d_prev = P_prev = None
    t_prev = slope_prev = None
    g0 = None
    status, message = "max_iterations", f"reached the maximum of {max_iter} iterations without converging"
    n = 0
    while True:
        timer = PhaseTimer()
        t0 = time.perf_counter()
        grad = problem.riesz(Q, P)
        gg = problem.pair(P, grad)
        if gg < 0 or not math.isfinite(gg):
            raise OptimizationError(
                f"iteration {n + 1}: dF[grad F] = {gg:.3e} is not positive: "
                f"the derivative or the metric is wrong"
            )
        gnorm = math.sqrt(gg)
        if g0 is None:
            g0 = gnorm
        if gnorm == 0.0:
            status, message = "converged", "the gradient vanishes"
            break
        if gtol is not None and gnorm <= gtol * g0:
            status = "converged"
            message = f"‖grad F‖ fell to {gnorm / g0:.2e} of its first value (gtol {gtol:g})"
            break
        if n >= max_iter:
            break
        n += 1
        restarted = False
        if lbfgs is not None:
            d = lbfgs.direction(P, lambda X: problem.riesz(Q, X),
                                None if h0 is None else (lambda X: h0(Q, X)))
        elif d_prev is None:
            d = -grad
        else:
            beta = hestenes_stiefel_plus(grad, P - P_prev, d_prev)
            d = beta * d_prev - grad
        d = problem.project(Q, d)
        slope = problem.pair(P, d)
        if not slope < -1e-12 * gnorm * gnorm and (lbfgs is not None and lbfgs.pairs or d_prev is not None):
            # not a (sufficient) descent direction: restart from steepest descent
            d, slope, restarted = -grad, -gnorm * gnorm, True
            if lbfgs is not None:
                lbfgs.clear()
        if not slope < 0:
            raise OptimizationError(
                f"iteration {n}: the search direction is not a descent direction "
                f"(dF[d] = {slope:.3e}); the derivative or the metric is wrong"
            )
        timer.add("gradient", t0)
        dnorm = float(problem.metric.norm(Q, d))
        if lbfgs is not None and (lbfgs.pairs or h0 is not None) and not restarted:
            t_init = 1.0  # a quasi-Newton step (H_0 = B⁻¹ scales the first one too)
        elif t_prev is not None and slope_prev is not None:
            t_init = t_prev * slope_prev / slope  # (6.22)
            if t_init * dnorm < 1e-4:
                t_init = 1.0 / dnorm
        else:
            t_init = 1.0 / dnorm
        ls = _line_search(problem, Q, d, F, slope, t_init, retraction=retraction, c1=c1, c2=c2,
                          segment_fraction=segment_fraction, min_step=min_step, timer=timer)
        if not ls.success and not (d_prev is None and lbfgs is not None and not lbfgs.pairs):
            # the quasi-Newton / CG direction failed: retry along −grad F before giving up
            if lbfgs is not None:
                lbfgs.clear()
            d, slope = -grad, -gnorm * gnorm
            ls = _line_search(problem, Q, d, F, slope, 1.0 / gnorm, retraction=retraction,
                              c1=c1, c2=c2,
                              segment_fraction=segment_fraction, min_step=min_step, timer=timer)
        if not ls.success:
            status = "step_too_small"
            message = (f"iteration {n}: no step ≥ {min_step:g} satisfies the Armijo condition "
                       f"({ls.evaluations} trials, {ls.rejected} outside M+)")
            break
        Q_new, J_new, P_new = ls.payload
        if P_new is None:
            t1 = time.perf_counter()
            P_new = problem.derivative(Q_new)
            timer.add("derivative", t1)
        s = Q_new - Q
        pair_rejected = False
        if lbfgs is not None:
            pair_rejected = not lbfgs.update(s, P_new - P, problem.pair(P, s))
        d_prev, P_prev, t_prev, slope_prev = d, P, ls.step, slope
        Q, F, J, P = Q_new, ls.value, J_new, P_new
        q = quality_summary(Q, tri)
        record = IterationRecord(
            n, J, F - J, F, q.mean_shape_quality, q.min_aspect_ratio, ls.step,
            ls.evaluations - 1, gnorm, dict(timer.seconds), method=method,
            relative_gradient_norm=gnorm / g0, wolfe=ls.wolfe, pair_rejected=pair_rejected,
            rejected_trials=ls.rejected,
        )
        history.append(record)
        logger.debug("iter %d: F=%.6g step=%.3g |g|/|g0|=%.2e evals=%d wolfe=%s", n, F, ls.step,
                     gnorm / g0, ls.evaluations, ls.wolfe)
        if callback is not None and callback(record, Q):
            status, message = "stopped", f"stopped by the callback at iteration {n}"
            break
        if ftol is not None and n >= FTOL_WINDOW:
            past = np.array([h.objective for h in history[n - FTOL_WINDOW : n]])
            if np.max(past - F) <= ftol * max(abs(F), 1.0):
                status = "converged"
                message = (f"F changed less than ftol·max(|F|, 1) = {ftol * max(abs(F), 1.0):.3g} "
                           f"over the last {FTOL_WINDOW} iterations")
                break
    return OptimizeResult(
        mesh=mesh.with_points(Q), x=Q, fun=F, j=J, nit=len(history) - 1, status=status,
        success=status in ("converged", "stopped"), message=message, history=history,
        seconds=time.perf_counter() - start, variant=variant, method=method,
        rejected_pairs=0 if lbfgs is None else lbfgs.rejected,
    )


def _line_search(problem, Q, d, F, slope, t_init, *, retraction, c1, c2, segment_fraction,
                 min_step, timer):
    """Weak-Wolfe search along the variant's retraction (None: the straight line, capped
    by :func:`segment_limit`); payload ``(Q_t, j_t, P_t)``."""
    if problem.constraint is not None:  # the area kept: trial points restored onto it
        curve = problem.constraint.curve(Q, retraction)
        if retraction is None:
            t0 = time.perf_counter()
            t_max = segment_fraction * segment_limit(Q, problem.triangles, d)
            timer.add("retraction", t0)
        else:
            t_max = math.inf

        def point(t):
            t0 = time.perf_counter()
            points, velocities = curve(Q, d, [t])
            timer.add("retraction", t0)
            return points[0], velocities[0]
    elif retraction is not None:
        def point(t):
            t0 = time.perf_counter()
            points, velocities = retraction(Q, d, [t])
            timer.add("retraction", t0)
            return points[0], velocities[0]

        t_max = math.inf
    else:
        def point(t):
            return Q + t * d, d

        t0 = time.perf_counter()
        t_max = segment_fraction * segment_limit(Q, problem.triangles, d)
        timer.add("retraction", t0)

    velocity = {}

    def phi(t):
        Qt, Vt = point(t)
        if Qt is None:
            problem.n_rejected += 1
            return math.inf, None
        t0 = time.perf_counter()
        Ft, Jt = problem.values(Qt)
        timer.add("state", t0)
        velocity[id(Qt)] = Vt
        return Ft, [Qt, Jt, None]

    def dphi(t, payload):
        t0 = time.perf_counter()
        payload[2] = problem.derivative(payload[0])
        timer.add("derivative", t0)
        return problem.pair(payload[2], velocity[id(payload[0])])

    phases = ("state", "derivative", "retraction")
    before = sum(timer.seconds[k] for k in phases)
    t0 = time.perf_counter()
    res = wolfe_line_search(phi, dphi, F, slope, t_init, t_max=t_max, c1=c1, c2=c2,
                            min_step=min_step)
    total = time.perf_counter() - t0
    inner = sum(timer.seconds[k] for k in phases) - before
    timer.seconds["backtracking"] += max(total - inner, 0.0)
    return res
