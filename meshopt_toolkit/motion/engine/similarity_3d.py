"""What tets and surfaces add to :mod:`.similarity` (the one owner of similarities and
handle paths in the plane and in space): the similarity that moves a whole point set and a
tet mesh's boundary faces.
"""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray, IntArray
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
