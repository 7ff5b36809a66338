"""The descent steps every minimizer of the package shares: backtracking along a direction
(:func:`backtrack` over the trial steps of :func:`halvings`, or any decreasing steps) and
L-BFGS with that backtracking (:func:`minimize_lbfgs`).

A trial is judged by the caller (sufficient decrease, admissibility, a residual that
falls): ``try_step(t)`` returns what the accepted trial computed, or None to refuse it.
The motions' polishes, the tet least squares, the Riemannian log map and discrete
geodesics search with these; plain functions of arrays, numpy only.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import TypeVar

import numpy as np

from ._typing import FloatArray

Payload = TypeVar("Payload")

#: Armijo's sufficient-decrease constant of the searches here
ARMIJO = 1e-4


def halvings(first: float = 1.0, *, count: int | None = None, above: float = 0.0
             ) -> Iterator[float]:
    """``first, first/2, first/4, …``: at most ``count`` steps (all without), each above
    ``above``."""
    step, k = first, 0
    while step > above and (count is None or k < count):
        yield step
        step *= 0.5
        k += 1


def backtrack(try_step: Callable[[float], Payload | None], steps: Iterable[float]
              ) -> tuple[float, Payload] | None:
    """The first of the trial ``steps`` that ``try_step`` accepts (returns not None), with
    what it returned; None when every one is refused."""
    for step in steps:
        out = try_step(step)
        if out is not None:
            return step, out
    return None


def sufficient_decrease(value: float, start: float, step: float, slope: float,
                        c1: float = ARMIJO) -> bool:
    """Armijo's test ``f(t) ≤ f(0) + c1 · t · f'(0)`` (False for ``f(t) = inf`` or NaN)."""
    return value <= start + c1 * step * slope


def minimize_lbfgs(objective: Callable, u: FloatArray, iterations: int, *, first_step: float,
                   admissible: Callable | None = None, memory: int = 10,
                   min_step: float = 1e-10, curvature: float = 1e-300) -> FloatArray:
    """L-BFGS from the admissible ``u``; a trial with ``F = inf``, too little decrease
    (:func:`sufficient_decrease`) or not ``admissible`` halves the step.

    Parameters
    ----------
    objective : callable
        ``u ↦ (F, G)``; ``(inf, None)`` where ``u`` is not admissible.
    u : (n,) float array
    iterations : int
    first_step : float
        The largest entry of the first (steepest-descent) step.
    admissible : callable, optional
        ``u ↦ bool``, checked on trials that decrease ``F`` enough.
    memory : int
        Pairs kept.
    min_step : float
        The step fraction below which the search gives up.
    curvature : float
        Pairs with ``sᵀy`` at most this are not kept.

    Returns
    -------
    (n,) float array
        The last accepted iterate (``u`` where none was).
    """
    F, G = objective(u)
    if G is None:  # not admissible at the start: nothing to descend
        return u
    S: list = []
    Y: list = []
    for _ in range(iterations):
        d = -G
        alphas = []
        for s_, y_ in reversed(list(zip(S, Y))):
            a = s_ @ d / (y_ @ s_)
            alphas.append(a)
            d = d - a * y_
        d = d * ((S[-1] @ Y[-1]) / (Y[-1] @ Y[-1]) if S
                 else first_step / max(np.abs(d).max(), 1e-300))
        for (s_, y_), a in zip(zip(S, Y), reversed(alphas)):
            d = d + (a - (y_ @ d) / (y_ @ s_)) * s_
        slope = G @ d
        if slope >= 0:  # not a descent direction: start again from steepest descent
            if not S:
                break
            S, Y = [], []
            continue

        def try_step(step: float, u=u, d=d, F=F, slope=slope):
            trial = u + step * d
            F1, G1 = objective(trial)
            if sufficient_decrease(F1, F, step, slope) and (admissible is None
                                                            or admissible(trial)):
                return trial, F1, G1
            return None

        found = backtrack(try_step, halvings(above=min_step))
        if found is None:
            break
        trial, F1, G1 = found[1]
        s_, y_ = trial - u, G1 - G
        u, F, G = trial, F1, G1
        if s_ @ y_ > curvature:
            S.append(s_)
            Y.append(y_)
            if len(S) > memory:
                S.pop(0)
                Y.pop(0)
    return u
