"""What tets and surfaces add to :mod:`.similarity` (the one owner of similarities and
handle paths in the plane and in space): the similarity that moves a whole point set, a
tet mesh's boundary faces, and the surface motion's spelling of the handle groups and
path (a label per handle, the screw motion by default) that :mod:`..surface.move` calls.
"""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray, IntArray
from . import similarity
from .similarity import Similarity3, fit_similarity_3d, rank_3d


def global_similarity(start: FloatArray, targets: FloatArray, diameter: float,
                      rtol: float = 1e-10) -> Similarity3 | None:
    """The similarity mapping every point of ``start`` onto its target within
    ``rtol·diameter``, or None (none does, or the points span less than a plane)."""
    if rank_3d(start) < 2:
        return None
    S = fit_similarity_3d(start, targets)
    if np.abs(S(start) - targets).max() <= rtol * diameter:
        return S
    return None


def tet_boundary_faces(tets: IntArray) -> IntArray:
    """Faces (F, 3) that belong to one tet only, oriented outwards for positive tets."""
    tets = np.asarray(tets)
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]],
                            tets[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def handle_groups(triangles: IntArray, handles: IntArray, n_vertices: int) -> IntArray:
    """A label per handle (0, 1, …) of :func:`.similarity.handle_groups` through the edges
    of ``triangles`` (the surface motion's argument order and form)."""
    labels = np.empty(len(handles), int)
    for c, g in enumerate(similarity.handle_groups(handles, triangles, n_vertices)):
        labels[g] = c
    return labels


class HandlePath(similarity.HandlePath):
    """:class:`.similarity.HandlePath` of groups given as labels (:func:`handle_groups`),
    the screw motion by default: the surface motion's spelling."""

    def __init__(self, start: FloatArray, targets: FloatArray, groups: IntArray,
                 motion: str = "screw") -> None:
        labels = np.asarray(groups)
        super().__init__(start, targets, [np.flatnonzero(labels == g) for g in range(
            int(labels.max()) + 1 if len(labels) else 0)], motion)
