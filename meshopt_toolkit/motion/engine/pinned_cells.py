"""Cells whose vertices are all handles: the targets alone place them, so no motion of
the other vertices mends what the targets do to them. ``mt.move`` refuses, before any
work, targets that turn such cells over or flatten them (a mirror image of a mesh turns
every cell over; a closed surface all of whose vertices are handles may not be turned
inside out)."""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray, IntArray
from ...kernels.surface import DEGENERATE_ASPECT, area_vectors, aspect_ratios

__all__ = ["pinned", "turned_over_problem", "surface_targets_problem"]


def pinned(cells: IntArray, handles: IntArray, n_vertices: int) -> np.ndarray:
    """``(M,)`` bool: the cells all of whose vertices are handles."""
    is_handle = np.zeros(n_vertices, bool)
    is_handle[np.asarray(handles, dtype=np.int64)] = True
    return is_handle[np.asarray(cells)].all(axis=1)


def turned_over_problem(turned: np.ndarray, fixed: np.ndarray, cell: str) -> str | None:
    """The line naming the ``fixed`` cells (bool ``(M,)``) that the targets turn over or
    flatten (``turned``, bool ``(M,)``), or None; ``cell`` names a cell ("triangle")."""
    bad = np.flatnonzero(turned & fixed)
    if not len(bad):
        return None
    if len(bad) == len(turned):
        return (f"the targets turn every {cell} over (a mirror image of the mesh), which no "
                f"motion reaches without flattening a {cell}")
    return (f"the targets turn {len(bad)} {cell}{'s' * (len(bad) > 1)} over or flatten "
            f"{'them' if len(bad) > 1 else 'it'} ({cell} {int(bad[0])} first), and all "
            f"their vertices are handles: no motion of the other vertices mends that")


def _enclosed(points: FloatArray, triangles: IntArray) -> float:
    """``6 ×`` the signed volume a closed surface encloses."""
    return float(np.einsum("tk,tk->", points[triangles[:, 0]],
                           area_vectors(points, triangles)))


def surface_targets_problem(points: FloatArray, triangles: IntArray, handles: IntArray,
                            targets: FloatArray, closed_and_oriented: bool) -> str | None:
    """Targets of a surface's handles that no motion reaches, or None: triangles all of
    whose corners are handles made degenerate, or a closed oriented surface all of whose
    vertices are handles turned inside out (its enclosed volume changes sign).

    ``points`` at unit size (the enclosed volume is formed from them)."""
    final = np.array(points, dtype=float)
    final[handles] = targets
    fixed = pinned(triangles, handles, len(points))
    flat = aspect_ratios(final, triangles) <= DEGENERATE_ASPECT
    if (flat & fixed).any():
        first = int(np.flatnonzero(flat & fixed)[0])
        return (f"the targets make {int(np.sum(flat & fixed))} triangles degenerate whose "
                f"corners are all handles (triangle {first} first)")
    if closed_and_oriented and fixed.all() and (
            np.sign(_enclosed(final, triangles)) != np.sign(_enclosed(points, triangles))):
        return ("the targets turn the closed surface inside out (a mirror image), which no "
                "motion reaches without flattening it")
    return None
