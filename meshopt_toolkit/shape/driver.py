"""The one iteration of :func:`meshopt_toolkit.optimize.optimize`: a direction rule
(:mod:`.directions`: steepest descent, Riemannian L-BFGS, nonlinear CG) and a line search
(:mod:`.linesearch`: Armijo backtracking for steepest descent, Wolfe for L-BFGS and CG)
on ``M+``, with one set of stopping tests.

Per iteration: the derivative ``P = dF(Q)`` (already known from a Wolfe search), the
gradient ``G_Q⁻¹P`` (its norm is the stopping quantity), the direction, the line search
along the variant's retraction — ``Q + t d``, or a retraction of the complete metric
(:mod:`meshopt_toolkit.riemannian.retractions`; the Wolfe slope from the retraction
curve's velocity) — then the rule's memory (L-BFGS's curvature pair, CG's last direction)
and the stopping tests. On straight lines the Wolfe search's trials go at most
``segment_fraction`` of the way to the first degeneracy
(:meth:`.problem.ShapeProblem.step_limit`: a triangle's area, a tet's volume); the Armijo
search keeps the thesis' travel guard (6.23) (:meth:`.problem.ShapeProblem.travel_limit`).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from ..errors import OptimizationError
from .directions import DIRECTION_RULES
from .linesearch import armijo_backtracking, wolfe_line_search
from .options import OptimizeOptions
from .problem import ShapeProblem
from .result import IterationRecord, OptimizeResult, PhaseTimer

logger = logging.getLogger(__name__)

#: Wolfe curvature constant per method (Nocedal & Wright: 0.9 for quasi-Newton, 0.1 for CG)
DEFAULT_C2 = {"lbfgs": 0.9, "cg": 0.1}

#: the objective-change test looks this many iterations back (the thesis' rule (6.26))
FTOL_WINDOW = 5


def run_descent(mesh, problem: ShapeProblem, *, method: str, variant: str, retraction,
                max_iterations: int, options: OptimizeOptions, callback, h0=None):
    """Minimize ``problem`` from ``mesh.points`` by ``method`` (``"steepest"``,
    ``"lbfgs"`` or ``"cg"``) along ``retraction`` (None: straight lines); returns an
    :class:`~.result.OptimizeResult`."""
    o = options
    armijo = method == "steepest"
    rule = DIRECTION_RULES[method]() if method != "lbfgs" else DIRECTION_RULES[method](o.memory, h0)
    c2 = None if armijo else (DEFAULT_C2[method] if o.c2 is None else float(o.c2))
    start = time.perf_counter()
    Q = np.array(mesh.points, dtype=float)
    timer = PhaseTimer()
    t0 = time.perf_counter()
    F, J = problem.values(Q)
    timer.add("state", t0)
    if not math.isfinite(F):
        raise OptimizationError("the objective is not finite at the initial mesh")
    P = None
    mean_q, min_q = problem.quality(Q)
    history = [IterationRecord(0, J, F - J, F, mean_q, min_q, 0.0, 0,
                               math.nan, dict(timer.seconds), method=method)]
    t_prev = slope_prev = None
    g0 = None
    status = "max_iterations"
    message = f"reached the maximum of {max_iterations} iterations without converging"
    n = 0
    while True:
        timer = PhaseTimer()
        if P is None:
            P = problem.derivative(Q, timer)
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
        if o.gtol is not None and gnorm <= o.gtol * g0:
            status = "converged"
            message = f"‖grad F‖ fell to {gnorm / g0:.2e} of its first value (gtol {o.gtol:g})"
            break
        if n >= max_iterations:
            break
        n += 1
        d = problem.project(Q, rule.direction(Q, P, grad, problem.riesz))
        slope = problem.pair(P, d)
        restarted = False
        if rule.has_history and not slope < -1e-12 * gnorm * gnorm:
            # not a (sufficient) descent direction: restart from steepest descent
            d, slope, restarted = -grad, -gnorm * gnorm, True
            rule.restart()
        if not slope < 0:
            raise OptimizationError(
                f"iteration {n}: the search direction is not a descent direction "
                f"(dF[d] = {slope:.3e}); the derivative or the metric is wrong"
            )
        timer.add("gradient", t0)
        dnorm = float(problem.metric.norm(Q, d))
        if rule.unit_step and not restarted:
            t_init = 1.0  # a quasi-Newton step (H_0 = B⁻¹ scales the first one too)
        elif t_prev is not None:
            t_init = t_prev * slope_prev / slope  # (6.22)
            if t_init * dnorm < 1e-4:
                t_init = 1.0 / dnorm
        else:
            t_init = 1.0 / dnorm
        ls = _line_search(problem, Q, d, F, slope, t_init, retraction, o, c2, timer)
        if not ls.success and rule.has_history:
            # the quasi-Newton / CG direction failed: retry along −grad F before giving up
            rule.restart()
            d, slope = -grad, -gnorm * gnorm
            ls = _line_search(problem, Q, d, F, slope, 1.0 / gnorm, retraction, o, c2, timer)
        if not ls.success:
            status = "step_too_small"
            message = (f"iteration {n}: no step ≥ {o.min_step:g} satisfies the Armijo condition "
                       f"({ls.evaluations} trials, {ls.rejected} outside M+)")
            break
        Q_new, J_new, P_new = ls.payload
        if P_new is None and not armijo:  # steepest descent's comes at the next iteration
            P_new = problem.derivative(Q_new, timer)
        pair_rejected = rule.remember(Q_new - Q, P_new, P, d)
        t_prev, slope_prev = ls.step, slope
        Q, F, J, P = Q_new, ls.value, J_new, P_new
        mean_q, min_q = problem.quality(Q)
        record = IterationRecord(
            n, J, F - J, F, mean_q, min_q, ls.step,
            ls.evaluations - 1, gnorm, dict(timer.seconds), method=method,
            relative_gradient_norm=gnorm / g0, wolfe=None if armijo else ls.wolfe,
            pair_rejected=pair_rejected, rejected_trials=ls.rejected,
        )
        history.append(record)
        logger.debug("iter %d: F=%.6g step=%.3g |g|/|g0|=%.2e trials=%d wolfe=%s", n, F, ls.step,
                     gnorm / g0, ls.evaluations, ls.wolfe)
        if callback is not None and callback(record, Q):
            status, message = "stopped", f"stopped by the callback at iteration {n}"
            break
        if _stalled(history, o.tolerance):
            status = "converged"
            message = (f"F changed less than tolerance·max(|F|, 1) = "
                       f"{o.tolerance * max(abs(F), 1.0):.3g} over the last {FTOL_WINDOW} "
                       f"iterations (6.26)")
            break
    return OptimizeResult(
        mesh=mesh.with_points(Q), x=Q, fun=F, j=J, nit=len(history) - 1, status=status,
        success=status in ("converged", "stopped"), message=message, history=history,
        seconds=time.perf_counter() - start, variant=variant, method=method,
        rejected_pairs=rule.rejected,
    )


def _stalled(history: list[IterationRecord], tolerance: float | None) -> bool:
    """The stopping rule (6.26), relative: ``max_{m=1..5} F_{n−m} − F_n ≤ tolerance ·
    max(|F_n|, 1)`` (the thesis' absolute rule where ``|F_n| ≤ 1``); None: off."""
    n = len(history) - 1
    if tolerance is None or n < FTOL_WINDOW:
        return False
    F = history[-1].objective
    past = np.array([h.objective for h in history[n - FTOL_WINDOW: n]])
    return bool(np.max(past - F) <= tolerance * max(abs(F), 1.0))


def _line_search(problem, Q, d, F, slope, t_init, retraction, o: OptimizeOptions, c2, timer):
    """Armijo backtracking (``c2`` None) or a Wolfe search along the variant's retraction
    (None: the straight line); payload ``(Q_t, j_t, P_t)`` (``P_t`` None when not computed)."""
    armijo = c2 is None
    batch: dict[float, tuple] = {}
    # the area kept: trial points restored onto it
    curve = retraction if problem.constraint is None else problem.constraint.curve(Q, retraction)
    if retraction is None:  # straight lines: the Armijo search's travel guard, or a cap
        t0 = time.perf_counter()
        t_max = (problem.travel_limit(Q, d) if armijo
                 else o.segment_fraction * problem.step_limit(Q, d))
        timer.add("retraction", t0)
    else:
        t_max = math.inf

    def point(t):
        if curve is None:
            return Q + t * d, d
        if t in batch:
            return batch[t]
        t0 = time.perf_counter()
        points, velocities = curve(Q, d, [t])
        timer.add("retraction", t0)
        return points[0], velocities[0]

    def prepare(steps):
        # one retraction call gives every trial; by the rescaling lemma R_Q(s_k d) =
        # R_Q((s_k / s) · s d) for the exponential map (and the second-order retraction)
        if curve is None:
            return
        t0 = time.perf_counter()
        s = steps[0]
        points = curve(Q, s * d, steps / s)[0]
        timer.add("retraction", t0)
        batch.update((float(t), (X, None)) for t, X in zip(steps, points))

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
        payload[2] = problem.derivative(payload[0], timer)
        return problem.pair(payload[2], velocity[id(payload[0])])

    phases = ("state", "derivative", "penalty_derivative", "retraction")
    before = sum(timer.seconds[k] for k in phases)
    t0 = time.perf_counter()
    if armijo:
        res = armijo_backtracking(phi, F, slope, t_init, c1=o.sigma, tau=o.tau,
                                  min_step=o.min_step, t_max=t_max, prepare=prepare)
    else:
        res = wolfe_line_search(phi, dphi, F, slope, t_init, t_max=t_max, c1=o.sigma, c2=c2,
                                min_step=o.min_step)
    total = time.perf_counter() - t0
    inner = sum(timer.seconds[k] for k in phases) - before
    timer.seconds["backtracking"] += max(total - inner, 0.0)
    return res
