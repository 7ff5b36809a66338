"""The last step of a surface morph that stops short of healthy (:mod:`.morph`): each
interior frame whose worst relative quality is below the worse end's is polished by the
surface motion's polish (:func:`.polish.polish_worst_triangles`, the source its rest, no
handle), every trial refused that has a degenerate triangle or a new fold or raises the
frame's membrane energy by more than 2 %.

With contact (:class:`.morph_contact.PathContact`) a trial is also refused unless the
straight segments from the previous frame to it and from it to the next are free of
contact (CCD) and no two of its triangles sharing a vertex meet (exact): from a clean
path, the path stays clean.

The neighbourhoods of ``NEIGHBOURHOODS`` are tried in turn, the smallest first, until the
frame reaches the worse end: a few worst triangles and one ring of neighbours move only
the vertices near them, where the whole surface moved towards its best shape can press a
frame against its neighbours' segments (and the next frame, polished from there, finds no
clear trial). With contact, ``SWEEPS`` passes over the frames at most: a frame left low is
polished again where the next frame, polished after it, has moved since.
"""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray
from .polish import polish_worst_triangles

__all__ = ["polish_frames"]

#: the polish's neighbourhoods (its ``worst`` triangles and ``rings`` of neighbours), tried
#: in turn on a frame until it reaches the worse end
NEIGHBOURHOODS = ((8, 1), (8, 2), (400, 5))
#: passes over the frames at most
SWEEPS = 2


def polish_frames(problem, path: list, contact=None) -> tuple[list, int]:
    """The frames of ``path`` with each interior frame below the worse end polished
    (module docstring), and how many were changed.

    Parameters
    ----------
    problem : the morph's path problem (``triangles``, ``healthy``, ``admissible``,
        ``embed``)
    path : list of (N, 3) float arrays
        The frames, the source first; admissible and, with ``contact``, clean.
    contact : :class:`.morph_contact.PathContact`, optional
        Keeps the path clean (module docstring); None: no contact.

    Returns
    -------
    path : list of (N, 3) float arrays
        A new list; the ends and the frames not polished are those given.
    polished : int
    """
    path, changed = list(path), set()
    no_handles = np.zeros(0, np.int64)
    todo = range(1, len(path) - 1)
    for _ in range(SWEEPS):
        low = [j for j in todo if not problem.healthy(path[j - 1:j + 2])]
        moved = set()
        for j in low:
            clear = None if contact is None else _clear_between(contact, path[j - 1],
                                                                path[j + 1])
            for worst, rings in NEIGHBOURHOODS:
                Q, info = polish_worst_triangles(path[0], problem.triangles, path[j],
                                                 no_handles, worst=worst, rings=rings,
                                                 clear=clear)
                if info["polish_vertices"] and problem.embed(Q) is not None and \
                        problem.admissible(Q):
                    path[j] = Q
                    moved.add(j)
                if problem.healthy(path[j - 1:j + 2]):
                    break
        changed |= moved
        if contact is None:  # no segment binds a frame to its neighbours
            break
        todo = [j for j in low if j + 1 in moved]
    return path, len(changed)


def _clear_between(contact, before: FloatArray, after: FloatArray):
    """The polish's ``clear`` of a frame between the clean frames ``before`` and ``after``:
    a trial frame is taken only where the path through it stays clean."""
    def clear(_start: FloatArray, trial: FloatArray) -> bool:
        return (contact.segment_clear(before, trial) and contact.segment_clear(trial, after)
                and contact.embedded(trial))  # the exact test, the costliest, last
    return clear
