"""Tetrahedron measures, vectorized over all tetrahedra.

Every function takes node positions ``points (N, 3)`` and tetrahedra ``tets (M, 4)`` and
returns one value per tetrahedron or per tetrahedron and local edge (``(M, 6)``, edges in
the order of :data:`TET_EDGES`). A tetrahedron ``(q0, q1, q2, q3)`` is *positively
oriented* when ``det[q1 − q0, q2 − q0, q3 − q0] > 0`` (gmsh's and VTK's convention); its
faces :data:`TET_FACES` are then oriented outward.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .._typing import FloatArray, IntArray

#: local vertex pairs of the six edges
TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
#: local vertices of the face opposite vertex ``l``, outward for a positive tetrahedron
TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
#: for edge ``e``, the two vertices not on it (the faces meeting at ``e`` are opposite them)
_OPPOSITE = np.array([[2, 3], [1, 3], [1, 2], [0, 3], [0, 2], [0, 1]])


def _corners(points: FloatArray, tets: IntArray) -> FloatArray:
    """Vertex positions ``(4, M, 3)``: row ``l`` is local vertex ``l`` of every tet."""
    pts = np.asarray(points, dtype=np.float64)
    return pts[np.ascontiguousarray(np.asarray(tets, dtype=np.int64).T)]


def signed_volumes(points: FloatArray, tets: IntArray) -> FloatArray:
    """Signed volumes ``det[q1 − q0, q2 − q0, q3 − q0] / 6``; positive iff positively
    oriented. Returns ``(M,)``."""
    p = _corners(points, tets)
    a, b, c = p[1] - p[0], p[2] - p[0], p[3] - p[0]
    return np.einsum("mk,mk->m", a, np.cross(b, c)) / 6.0


def edge_lengths(points: FloatArray, tets: IntArray) -> FloatArray:
    """Lengths of the six edges :data:`TET_EDGES` of every tetrahedron. Returns ``(M, 6)``."""
    p = _corners(points, tets)
    e = p[TET_EDGES[:, 1]] - p[TET_EDGES[:, 0]]  # (6, M, 3)
    return np.sqrt(np.einsum("emk,emk->me", e, e))


def mean_ratios(points: FloatArray, tets: IntArray) -> FloatArray:
    """Mean ratio quality ``12 (3|V|)^(2/3) / Σ ℓ²``, signed like the volume.

    1 for the regular tetrahedron, in (0, 1] for a positive one, ≤ 0 for an inverted or
    degenerate one; invariant under rotation, translation and scaling. Returns ``(M,)``.
    """
    vol = signed_volumes(points, tets)
    sq = np.square(edge_lengths(points, tets)).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = 12.0 * np.sign(vol) * np.cbrt(np.square(3.0 * vol)) / sq
    return np.where(sq > 0, q, 0.0)


def face_normals(points: FloatArray, tets: IntArray) -> FloatArray:
    """Area-weighted normals ``(4, M, 3)`` of the faces :data:`TET_FACES` (face ``l`` is
    opposite vertex ``l``; outward for positive tetrahedra, length = twice the area)."""
    p = _corners(points, tets)
    f = TET_FACES
    return np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])


def dihedral_angles(points: FloatArray, tets: IntArray) -> FloatArray:
    """Interior dihedral angles in radians at the six edges :data:`TET_EDGES`.

    The angle at an edge is π minus the angle between the outward normals of its two
    faces, computed with ``arctan2(|n × m|, −n·m)`` (accurate near 0 and π). A mirrored
    (inverted) tetrahedron has the angles of its mirror image. Returns ``(M, 6)``.
    """
    n = face_normals(points, tets)
    a, b = n[_OPPOSITE[:, 0]], n[_OPPOSITE[:, 1]]  # (6, M, 3)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.einsum("emk,emk->em", a, b)
    return np.arctan2(cross, -dot).T


@dataclass(frozen=True)
class TetQualitySummary:
    """Mesh-level quality numbers of a tetrahedral mesh.

    Attributes
    ----------
    min_mean_ratio, mean_mean_ratio : worst and mean signed mean ratio
    min_dihedral_deg, max_dihedral_deg : extreme dihedral angles in degrees
    min_volume : smallest signed volume
    total_volume : sum of the signed volumes
    n_inverted : number of tetrahedra with signed volume <= 0
    """

    min_mean_ratio: float
    mean_mean_ratio: float
    min_dihedral_deg: float
    max_dihedral_deg: float
    min_volume: float
    total_volume: float
    n_inverted: int

    def as_dict(self) -> dict:
        """The summary as a plain JSON-serializable dict."""
        return {k: (int(v) if k == "n_inverted" else float(v)) for k, v in asdict(self).items()}


def tet_quality_summary(points: FloatArray, tets: IntArray) -> TetQualitySummary:
    """Mean ratios, dihedral angles and volumes of all tetrahedra in one summary."""
    vol = signed_volumes(points, tets)
    q = mean_ratios(points, tets)
    ang = np.degrees(dihedral_angles(points, tets))
    return TetQualitySummary(
        min_mean_ratio=float(q.min()), mean_mean_ratio=float(q.mean()),
        min_dihedral_deg=float(ang.min()), max_dihedral_deg=float(ang.max()),
        min_volume=float(vol.min()), total_volume=float(vol.sum()),
        n_inverted=int(np.count_nonzero(vol <= 0)))
