"""Similarities of space ``x ↦ c + b + s R (x − c)`` (``R`` a rotation), the one owner of
the concept for tets and surfaces: fitting (Umeyama's closed form), the inverse, two paths
from the identity — :meth:`Similarity3.at` (the centre along the chord) and
:meth:`Similarity3.screw` (about the similarity's own axis line) — and the default paths of
groups of handles; the 3D counterpart of :mod:`.similarity`.

The tet and surface distortions do not see rotations and see a uniform scale only as the
same shift of every cell's volume or area component, so a motion that is a similarity is
followed exactly and costs no shape strain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .._typing import FloatArray, IntArray
from ..errors import OptionError
from . import similarity

#: the paths of :class:`HandlePath`: a group's similarity along its chord or screw motion
HANDLE_MOTIONS = ("chord", "screw")


@dataclass(frozen=True)
class Similarity3:
    """``x ↦ centre + shift + exp(log_scale) · R (x − centre)``, ``R`` = the rotation of
    ``rotvec`` (axis × angle, angle in [0, π]); the coordinates in which :meth:`at` is
    linear, as :class:`.similarity.Similarity` in the plane."""

    centre: FloatArray
    shift: FloatArray
    log_scale: float
    rotvec: FloatArray

    @classmethod
    def identity(cls) -> Similarity3:
        return cls(np.zeros(3), np.zeros(3), 0.0, np.zeros(3))

    @property
    def scale(self) -> float:
        return float(np.exp(self.log_scale))

    @property
    def rotation(self) -> FloatArray:
        """``R`` (3×3, det +1)."""
        return Rotation.from_rotvec(self.rotvec).as_matrix()

    @property
    def matrix(self) -> FloatArray:
        """``s R`` (3×3)."""
        return np.exp(self.log_scale) * self.rotation

    @property
    def image(self) -> FloatArray:
        """Where the centre goes, ``centre + shift``."""
        return self.centre + self.shift

    @property
    def angle(self) -> float:
        return float(np.linalg.norm(self.rotvec))

    @property
    def is_identity(self) -> bool:
        return (not np.any(self.shift) and self.log_scale == 0.0
                and not np.any(self.rotvec))

    def __call__(self, P: FloatArray) -> FloatArray:
        return self.centre + self.shift + (np.asarray(P, float) - self.centre) @ self.matrix.T

    def inverse(self, P: FloatArray) -> FloatArray:
        """The inverse map applied to ``P``."""
        return self.centre + (np.asarray(P, float) - self.centre - self.shift) @ np.linalg.inv(
            self.matrix).T

    def at(self, t: float) -> Similarity3:
        """The similarity a fraction ``t`` of the way along its path of least mass-weighted
        motion from the identity: the centre along the chord, the angle about the fixed
        axis and the log-scale linear in ``t`` (t = 1: the same similarity, bitwise)."""
        return Similarity3(self.centre, t * self.shift, t * self.log_scale, t * self.rotvec)

    def screw(self, t: float) -> Similarity3:
        """The similarity a fraction ``t`` of its screw (spiral) motion
        ``p + s^t R^t (x − p)`` plus the shift along the axis, about the axis line through
        ``p`` it turns about: a turn about a hinge moves along the arc, not the chord
        (t = 1: itself; ``screw(a)`` after ``screw(b)`` is ``screw(a + b)``)."""
        if t == 1.0:
            return self
        q, u, v_u = self._axis()
        log_st = t * self.log_scale
        # the shift along the axis under the scale: v_u (s^t − 1)/(s − 1), → t v_u at s = 1
        along = t if abs(self.log_scale) < 1e-12 else np.expm1(log_st) / np.expm1(
            self.log_scale)
        Rt = Rotation.from_rotvec(t * self.rotvec).as_matrix()
        return Similarity3(self.centre, q - np.exp(log_st) * (Rt @ q) + along * v_u * u,
                           log_st, t * self.rotvec)

    def _axis(self) -> tuple[FloatArray, FloatArray, float]:
        """``(p − c, u, b·u)``: the point of the axis line nearest the centre ``c``
        (relative to it), the unit axis ``u`` (0 without a turn) and the shift ``b``
        along it; ``(0, b/|b|, |b|)``, the chord, where the similarity is within 1e-6 of a
        translation."""
        v, angle = self.shift, self.angle
        if abs(1.0 - np.exp(self.log_scale + 1j * angle)) < 1e-6:
            size = float(np.linalg.norm(v))
            return np.zeros(3), (v / size if size > 0 else np.zeros(3)), size
        u = self.rotvec / angle if angle > 0 else np.zeros(3)
        v_u = float(v @ u)
        # (I − sR) maps the plane normal to u onto itself, invertibly: |1 − s e^{iθ}| > 0
        uu = np.outer(u, u)
        K = (np.eye(3) - self.matrix) @ (np.eye(3) - uu) + uu
        return np.linalg.solve(K, v - v_u * u), u, v_u


def fit_similarity_3d(source: FloatArray, target: FloatArray, scaling: bool = True
                      ) -> Similarity3:
    """Least-squares similarity taking ``source`` to ``target`` (Umeyama 1991: the
    rotation from the SVD of the cross-covariance, a reflection excluded; the scale that
    minimizes the residual, or 1 without ``scaling`` or where that scale is not positive),
    about the centroid of ``source``; a translation for fewer than 3 points or coincident
    ones."""
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
    scale = float(D @ E) / var if scaling else 1.0
    log_scale = float(np.log(scale)) if scale > 0.0 else 0.0
    return Similarity3(cx, cy - cx, log_scale, Rotation.from_matrix(R).as_rotvec())


def rank_3d(points: FloatArray) -> int:
    """The dimension of the affine span of ``points`` (singular values above 1e-9 of the
    largest)."""
    if len(points) < 2:
        return 0
    x = points - points.mean(axis=0)
    s = np.linalg.svd(x, compute_uv=False)
    return int(np.sum(s > 1e-9 * max(s[0], 1e-300)))


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
    """A label per handle (0, 1, …): its connected piece through edges of ``triangles``
    (a surface's, or a tet mesh's boundary faces) whose ends are both handles
    (:func:`.similarity.handle_labels`)."""
    F = np.asarray(triangles)
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return similarity.handle_labels(handles, edges, n_vertices)


class HandlePath(similarity.HandlePath):
    """Positions of the handles at fraction ``t`` of their motion from ``start`` to
    ``targets`` (:class:`.similarity.HandlePath` in space): each group (labels from
    :func:`handle_groups`) follows the similarity that fits it best — along its ``motion``,
    "chord" (:meth:`Similarity3.at`) or "screw" (:meth:`Similarity3.screw`), so a turning
    piece turns instead of collapsing through its centre — plus ``t`` times what the
    similarity leaves; a group spanning less than a plane moves linearly. Bitwise
    ``targets`` at ``t = 1``."""

    fit = staticmethod(fit_similarity_3d)

    def __init__(self, start: FloatArray, targets: FloatArray, groups: IntArray,
                 motion: str = "screw") -> None:
        if motion not in HANDLE_MOTIONS:
            raise OptionError(f"motion must be one of {HANDLE_MOTIONS}, not {motion!r}")
        self.motion = motion
        labels = np.asarray(groups)
        super().__init__(start, targets, [np.flatnonzero(labels == g) for g in range(
            int(labels.max()) + 1 if len(labels) else 0)])

    @staticmethod
    def turns(points: FloatArray) -> bool:
        """A single vertex or a collinear piece has no rotation of its own."""
        return rank_3d(points) >= 2

    def along(self, S: Similarity3, t: float) -> Similarity3:
        return S.screw(t) if self.motion == "screw" else S.at(t)
