"""Similarities of space ``x ↦ c + b + s R (x − c)`` (``R`` a rotation): fitting
(Umeyama's closed form), interpolation along the rotation's axis, and the default handle
path of a tet mesh — the 3D counterpart of :mod:`.similarity`.

The tet distortion ``φ`` does not see rotations and sees a uniform scale only as the
same shift of every tet's volume component, so a motion that is a similarity is followed
exactly and costs no shape strain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .._typing import FloatArray, IntArray
from .similarity import HandlePath, handle_groups


@dataclass(frozen=True)
class Similarity3:
    """``x ↦ center + shift + exp(log_scale) · R (x − center)``, ``R`` = the rotation of
    ``rotvec`` (axis × angle, angle in [0, π])."""

    center: FloatArray
    shift: FloatArray
    log_scale: float
    rotvec: FloatArray

    @property
    def matrix(self) -> FloatArray:
        """``s R`` (3×3)."""
        return np.exp(self.log_scale) * Rotation.from_rotvec(self.rotvec).as_matrix()

    def __call__(self, P: FloatArray) -> FloatArray:
        return self.center + self.shift + (np.asarray(P, float) - self.center) @ self.matrix.T

    def inverse(self, P: FloatArray) -> FloatArray:
        return self.center + (np.asarray(P, float) - self.center - self.shift) @ np.linalg.inv(
            self.matrix).T

    def at(self, s: float) -> Similarity3:
        """The similarity a fraction ``s`` of the way: angle about the fixed axis,
        log-scale and shift linear in ``s``."""
        return Similarity3(self.center, s * self.shift, s * self.log_scale, s * self.rotvec)

    @property
    def is_identity(self) -> bool:
        return (not np.any(self.shift) and self.log_scale == 0.0
                and not np.any(self.rotvec))

    @property
    def angle(self) -> float:
        return float(np.linalg.norm(self.rotvec))


def fit_similarity_3d(source: FloatArray, target: FloatArray) -> Similarity3:
    """Least-squares similarity taking ``source`` to ``target`` (Umeyama 1991: the
    rotation from the SVD of the cross-covariance, a reflection excluded; the scale that
    minimizes the residual), about the centroid of ``source``."""
    X, Y = np.asarray(source, float), np.asarray(target, float)
    cx, cy = X.mean(axis=0), Y.mean(axis=0)
    Xc, Yc = X - cx, Y - cy
    var = float(np.sum(Xc**2))
    if len(X) < 3 or var == 0.0:
        return Similarity3(cx, cy - cx, 0.0, np.zeros(3))
    U, D, Vt = np.linalg.svd(Yc.T @ Xc)
    E = np.ones(3)
    E[2] = np.sign(np.linalg.det(U) * np.linalg.det(Vt)) or 1.0
    R = (U * E) @ Vt
    scale = float(D @ E) / var
    if scale <= 0.0:
        return Similarity3(cx, cy - cx, 0.0, np.zeros(3))
    return Similarity3(cx, cy - cx, float(np.log(scale)), Rotation.from_matrix(R).as_rotvec())


def tet_boundary_faces(tets: IntArray) -> IntArray:
    """Faces (F, 3) that belong to one tet only, oriented outwards for positive tets."""
    tets = np.asarray(tets)
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]],
                            tets[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def handle_groups_3d(handles: IntArray, faces: IntArray, n_vertices: int) -> list[IntArray]:
    """Positions (into ``handles``) of the handles grouped by connected boundary pieces:
    handles joined by edges of boundary faces whose ends are both handles form one group
    (:func:`.similarity.handle_groups` of the faces' edges)."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return handle_groups(handles, edges, n_vertices)


class HandlePath3(HandlePath):
    """Default path of the handles in space (:class:`.similarity.HandlePath`): each group
    (a connected piece of boundary) follows the :class:`Similarity3` that fits it best (a
    turning hole turns instead of collapsing through its centre), plus the straight-line
    remainder to its targets; bitwise the targets at ``s = 1``."""

    fit = staticmethod(fit_similarity_3d)
