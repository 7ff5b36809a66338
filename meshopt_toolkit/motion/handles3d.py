"""Handles and targets of a mesh in space as the 3D solvers take them: the checks, each
handle once, and the vertices a solver sees (those in some cell; a file may hold others)."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError


def check_handles(handles, targets, n_vertices: int) -> tuple[np.ndarray, FloatArray]:
    """``(handles, targets)`` as arrays after the shape checks: a non-empty 1-D integer
    array of vertex indices in range, and targets ``(k, 3)``.

    Raises
    ------
    InvalidMeshError
        One line naming what is wrong.
    """
    h = np.asarray(handles)
    tg = np.asarray(targets, dtype=float)
    if h.ndim != 1 or h.size == 0 or not np.issubdtype(h.dtype, np.integer):
        raise InvalidMeshError("handles must be a non-empty 1-D array of vertex indices")
    if h.min() < 0 or h.max() >= n_vertices:
        raise InvalidMeshError(
            f"a handle index is out of range (the mesh has {n_vertices} vertices)")
    if tg.shape != (h.size, 3):
        raise InvalidMeshError(f"targets must have shape ({h.size}, 3), got {tg.shape}")
    return h.astype(np.int64), tg


def distinct_handles(handles: IntArray, targets: FloatArray) -> tuple[IntArray, FloatArray]:
    """Each handle once, in increasing order, with its (first) target.

    Raises
    ------
    InvalidMeshError
        A vertex is a handle twice with different targets.
    """
    order = np.argsort(handles, kind="stable")
    hs, ts = handles[order], targets[order]
    same = hs[1:] == hs[:-1]
    if (same & np.any(ts[1:] != ts[:-1], axis=1)).any():
        raise InvalidMeshError("a vertex is a handle twice with different targets")
    keep = np.concatenate([[True], ~same])
    return hs[keep], ts[keep]


class SolvedVertices:
    """The vertices that lie in some cell, renumbered for a solver, which sees only them;
    the others stay where they are, or go to their targets where they are handles.

    Attributes
    ----------
    points : (n, 3) the solved vertices' points
    cells : (M, k) the cells in the solved numbering
    handles, targets : the handles among the solved vertices (solved numbering), targets
    """

    def __init__(self, points: FloatArray, cells: IntArray, handles: IntArray,
                 targets: FloatArray) -> None:
        self._all = np.asarray(points, dtype=float)
        self._used = np.unique(cells)
        local = np.full(len(self._all), -1, np.int64)
        local[self._used] = np.arange(len(self._used))
        keep = local[handles] >= 0
        self.points = self._all[self._used]
        self.cells = local[cells]
        self.handles, self.targets = local[handles[keep]], targets[keep]
        self._loose = handles[~keep], targets[~keep]

    def full(self, Q: FloatArray) -> FloatArray:
        """All the mesh's points: ``Q`` at the solved vertices, the rest as described."""
        out = np.array(self._all)
        out[self._used] = Q
        out[self._loose[0]] = self._loose[1]
        return out
