"""The descent of the local polishes (:mod:`.tet_polish`, :mod:`.surface_polish`): the
vertices they move (:func:`cell_neighbourhood`), the soft maximum they lower and L-BFGS
with a backtracking line search that refuses inadmissible trials."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._typing import FloatArray, IntArray


def cell_neighbourhood(cells: IntArray, seeds: IntArray, rings: int, n_vertices: int
                       ) -> np.ndarray:
    """The vertices (a bool mask (n_vertices,)) of the ``seeds`` cells and ``rings`` rings of
    neighbours around them: each ring adds the corners of every cell touching the last."""
    near = np.zeros(n_vertices, bool)
    near[cells[seeds]] = True
    for _ in range(rings):
        near[cells[near[cells].any(axis=1)]] = True
    return near


def soft_maximum(values: FloatArray, gradients: FloatArray, sharpness: float
                 ) -> tuple[float, FloatArray]:
    """``max v + log Σ exp(s (v − max v)) / s`` of per-cell ``values`` (C,) and its
    per-cell gradients: ``gradients`` (C, ...) weighted by the softmax of ``s·values``."""
    top = values.max()
    w = np.exp(sharpness * (values - top))
    total = w.sum()
    weighted = (w / total).reshape((-1,) + (1,) * (gradients.ndim - 1)) * gradients
    return top + np.log(total) / sharpness, weighted


def minimize_lbfgs(objective: Callable, u: FloatArray, iterations: int, *, first_step: float,
                   admissible: Callable | None = None, memory: int = 10,
                   min_step: float = 1e-10, curvature: float = 1e-300) -> FloatArray:
    """L-BFGS from the admissible ``u``; a trial with ``F = inf``, too little decrease
    (Armijo, 1e-4) or not ``admissible`` halves the step.

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
        step = 1.0
        while step > min_step:
            trial = u + step * d
            F1, G1 = objective(trial)
            if F1 <= F + 1e-4 * step * slope and (admissible is None or admissible(trial)):
                break
            step *= 0.5
        else:
            break
        s_, y_ = trial - u, G1 - G
        u, F, G = trial, F1, G1
        if s_ @ y_ > curvature:
            S.append(s_)
            Y.append(y_)
            if len(S) > memory:
                S.pop(0)
                Y.pop(0)
    return u
