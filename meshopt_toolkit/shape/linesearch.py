"""The line searches of the descent methods, for functions that are ``+∞`` outside their
domain: a Wolfe search (:func:`wolfe_line_search`, L-BFGS and CG) and Armijo
backtracking (:func:`armijo_backtracking`, the thesis' steepest descent).

``φ(t) = F(R_Q(t d))`` along a retraction ``R``; a trial whose configuration leaves ``M+``
has ``φ(t) = +∞`` and is *rejected* (the bracket shrinks), never fatal. The search
brackets a step satisfying

* sufficient decrease (Armijo): ``φ(t) ≤ φ(0) + c1 t φ'(0)``, and
* the curvature condition: ``φ'(t) ≥ c2 φ'(0)`` (weak), and with ``strong=True`` also
  ``φ'(t) ≤ c2 |φ'(0)|`` (strong Wolfe: a step past the 1-D minimizer closes the bracket)

by expansion (factor ``expand``) and safeguarded interpolation inside the bracket
(quadratic from ``φ(lo), φ'(lo), φ(hi)`` when ``φ(hi)`` is finite, bisection when it is
not) — the bisection scheme of Lewis & Overton for weak Wolfe steps, which terminates for
any ``0 < c1 < c2 < 1`` when ``φ`` is bounded below and continuously differentiable on
``[0, t_max)``. ``φ'(t)`` is computed only at trials that pass the Armijo test.

When the evaluation budget runs out, or the bracket reaches ``t_max`` without a curvature
point, the best Armijo step found is returned with ``wolfe=False``; with no Armijo step the
result has ``step = 0``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class LineSearchResult:
    """Outcome of :func:`wolfe_line_search`.

    Attributes
    ----------
    step : accepted step ``t`` (0 when no trial satisfied the Armijo condition)
    value : ``φ(step)``
    slope : ``φ'(step)`` (None when not computed)
    payload : what ``phi`` returned with the accepted value (e.g. the configuration)
    evaluations : number of trial steps (``φ`` evaluations; for the Armijo search also
        the trials at or beyond ``t_max``, refused without one)
    rejected : trials with ``φ = +∞`` (outside the domain)
    wolfe : True when both Wolfe conditions hold at ``step``
    """

    step: float
    value: float
    slope: float | None
    payload: Any
    evaluations: int
    rejected: int
    wolfe: bool

    @property
    def success(self) -> bool:
        return self.step > 0


def wolfe_line_search(
    phi: Callable[[float], tuple[float, Any]],
    dphi: Callable[[float, Any], float] | None,
    f0: float,
    g0: float,
    t0: float,
    *,
    t_max: float = math.inf,
    c1: float = 1e-4,
    c2: float = 0.9,
    expand: float = 4.0,
    max_evals: int = 30,
    min_step: float = 0.0,
    strong: bool = True,
) -> LineSearchResult:
    """Find a weak-Wolfe step of ``φ`` (Armijo only when ``dphi`` is None).

    Parameters
    ----------
    phi : ``t -> (φ(t), payload)``; ``φ(t) = +inf`` marks a trial outside the domain
    dphi : ``(t, payload) -> φ'(t)``, or None for a backtracking (Armijo-only) search
    f0, g0 : ``φ(0)`` and ``φ'(0)`` (must be < 0: a descent direction)
    t0 : first trial step (> 0)
    t_max : largest trial step (e.g. a fraction of the first degeneracy)
    c1, c2 : Wolfe constants, ``0 < c1 < c2 < 1``
    expand : growth factor of the step while the curvature condition fails
    max_evals : evaluation budget
    min_step : give up when the bracket's upper end drops below it
    strong : strong Wolfe conditions (``|φ'(t)| ≤ c2 |φ'(0)|``) instead of weak ones

    Returns
    -------
    LineSearchResult
    """
    if not g0 < 0:
        raise ValueError(f"φ'(0) = {g0!r} is not negative: not a descent direction")
    if not 0 < c1 < c2 < 1:
        raise ValueError(f"need 0 < c1 < c2 < 1, got c1={c1}, c2={c2}")
    lo, f_lo, g_lo = 0.0, f0, g0
    hi, f_hi = math.inf, math.inf
    best: tuple[float, float, float | None, Any] | None = None
    evals = rejected = 0
    t = min(t0, t_max)
    while evals < max_evals:
        f, payload = phi(t)
        evals += 1
        if not math.isfinite(f):
            rejected += 1
        if not f <= f0 + c1 * t * g0 or f >= f_lo and lo > 0:  # no sufficient decrease
            hi, f_hi = t, f
        else:
            if dphi is None:
                return LineSearchResult(t, f, None, payload, evals, rejected, False)
            g = float(dphi(t, payload))
            if best is None or f < best[1]:
                best = (t, f, g, payload)
            if c2 * g0 <= g and not (strong and g > -c2 * g0):
                return LineSearchResult(t, f, g, payload, evals, rejected, True)
            if g > 0:  # past the 1-D minimizer (strong Wolfe): it lies in [lo, t]
                hi, f_hi = t, f
            else:
                lo, f_lo, g_lo = t, f, g
        # next trial
        if math.isinf(hi):
            if lo >= t_max:
                break  # cannot grow further: keep the Armijo point
            t = min(expand * lo, t_max)
            continue
        if hi < min_step or hi - lo <= 1e-12 * hi:
            break
        width = hi - lo
        if math.isfinite(f_hi) and math.isfinite(f_lo):
            denom = 2.0 * (f_hi - f_lo - g_lo * width)
            tq = lo - g_lo * width * width / denom if denom > 0 else lo + 0.5 * width
            t = min(max(tq, lo + 0.1 * width), hi - 0.1 * width)
        else:
            t = lo + 0.5 * width
    if best is None:
        return LineSearchResult(0.0, f0, None, None, evals, rejected, False)
    t, f, g, payload = best
    return LineSearchResult(t, f, g, payload, evals, rejected, False)


def armijo_backtracking(
    phi: Callable[[float], tuple[float, Any]],
    f0: float,
    g0: float,
    t0: float,
    *,
    c1: float = 1e-4,
    tau: float = 0.5,
    min_step: float = 1e-6,
    t_max: float = math.inf,
    prepare: Callable[[np.ndarray], None] | None = None,
) -> LineSearchResult:
    """The first of the steps ``t0, tau·t0, tau²·t0, … ≥ min_step`` with sufficient decrease
    ``φ(t) ≤ φ(0) + c1 t φ'(0)`` (the thesis' Armijo rule (6.21)).

    Parameters
    ----------
    phi : ``t -> (φ(t), payload)``; ``φ(t) = +inf`` marks a trial outside the domain
    f0, g0 : ``φ(0)`` and ``φ'(0)`` (must be < 0: a descent direction)
    t0 : first trial step (> 0)
    c1 : Armijo constant
    tau : backtracking factor in (0, 1)
    min_step : the smallest trial step
    t_max : trials at or beyond it are refused unevaluated (steepest descent's travel
        guard (6.23))
    prepare : called once with every trial step before the first ``phi`` (e.g. one
        retraction call that gives all trial points)

    Returns
    -------
    LineSearchResult
        ``wolfe`` is always False and ``slope`` None; ``step = 0`` when no trial passed.
    """
    if not g0 < 0:
        raise ValueError(f"φ'(0) = {g0!r} is not negative: not a descent direction")
    count = max(1, math.ceil(math.log(min_step / t0) / math.log(tau)) + 1)
    steps = t0 * tau ** np.arange(count)
    steps = steps[steps >= min_step]
    if prepare is not None and len(steps):
        prepare(steps)
    trials = rejected = 0
    for t in steps:
        trials += 1
        if t >= t_max:
            continue
        f, payload = phi(float(t))
        if not math.isfinite(f):
            rejected += 1
            continue
        if f <= f0 + c1 * t * g0:
            return LineSearchResult(float(t), f, None, payload, trials, rejected, False)
    return LineSearchResult(0.0, f0, None, None, trials, rejected, False)
