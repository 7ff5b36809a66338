"""What the local polishes (:mod:`..tets.polish`, :mod:`..surface.polish`) share: the
vertices they move (:func:`cell_neighbourhood`) and the soft maximum they lower; their
L-BFGS is :func:`...descent.minimize_lbfgs`. The reweighted quality rounds of the planar
and tet finishes (:func:`quality_rounds`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..._typing import FloatArray, IntArray

__all__ = ["cell_neighbourhood", "quality_rounds", "soft_maximum"]


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


def quality_rounds(Q: FloatArray, rounds: int, relax: Callable, quality: Callable,
                   sizes: Callable, ceiling: float = np.inf) -> tuple[FloatArray, int, int]:
    """The finishes' reweighted rounds: ``relax(Q, weights) -> (Q, iterations)`` one
    proximal least-squares round with per-cell weights (None the first: all 1), each
    round's weights those of the last times ``max(1, size/rms size)^½`` of the cells'
    distortion ``sizes(Q)`` (the cells that stay the worst weigh more and more). The
    iterate with the best ``quality(Q)`` (the worst cell's) is kept, the start included;
    the rounds stop once it reaches ``ceiling``.

    Returns
    -------
    best : the kept iterate
    iterations : int, the rounds' iterations together
    kept : int, the round of ``best`` (0: the start)
    """
    best, best_q = Q, quality(Q)
    kept, nit, weights = 0, 0, None
    for k in range(1, rounds + 1):
        if best_q >= ceiling:
            break
        Q, it = relax(Q, weights)
        nit += it
        q = quality(Q)
        if q > best_q:
            best, best_q, kept = Q, q, k
        size = sizes(Q)
        pressed = np.sqrt(np.maximum(1.0, size / np.sqrt(np.mean(size**2))))
        weights = pressed if weights is None else weights * pressed
    return best, nit, kept
