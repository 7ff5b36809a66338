"""What the local polishes (:mod:`..tets.polish`, :mod:`..surface.polish`) share: the
vertices they move (:func:`cell_neighbourhood`) and the soft maximum they lower; their
L-BFGS is :func:`...descent.minimize_lbfgs`."""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray, IntArray

__all__ = ["cell_neighbourhood", "soft_maximum"]


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
