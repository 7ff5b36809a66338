"""Tetrahedron measures, vectorized over all tetrahedra.

Every function takes node positions ``points (N, 3)`` and tetrahedra ``tets (M, 4)`` and
returns one value per tetrahedron or per tetrahedron and local edge (``(M, 6)``, edges in
the order of :data:`TET_EDGES`). A tetrahedron ``(q0, q1, q2, q3)`` is *positively
oriented* when ``det[q1 − q0, q2 − q0, q3 − q0] > 0`` (gmsh's and VTK's convention); its
faces :data:`TET_FACES` are then oriented outward.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray
from ..scaling import unit_cells
from .triangles import SummaryRecord

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


def _unit_edges(points: FloatArray, tets: IntArray, count: int = 6
                ) -> tuple[FloatArray, IntArray]:
    """The first ``count`` edge vectors ``(count, M, 3)`` of :data:`TET_EDGES` (3: those
    from ``q0``), each tet's divided by a power of two of its size
    (:func:`~meshopt_toolkit.scaling.unit_cells`), and the exponents ``(M,)``. The
    measures below are formed from these, so none overflows or underflows at 1e±300 and
    the ratios are the same numbers at every scale."""
    p = _corners(points, tets)
    if count == 3:
        return unit_cells(p[1:] - p[0], axis=1)
    return unit_cells(p[TET_EDGES[:, 1]] - p[TET_EDGES[:, 0]], axis=1)


def _volumes6(d: FloatArray) -> FloatArray:
    """``det[q1 − q0, q2 − q0, q3 − q0]`` of edge vectors ``d`` (:func:`_unit_edges`)."""
    return np.einsum("mk,mk->m", d[0], np.cross(d[1], d[2]))


def signed_volumes(points: FloatArray, tets: IntArray) -> FloatArray:
    """Signed volumes ``det[q1 − q0, q2 − q0, q3 − q0] / 6``; positive iff positively
    oriented (0 where the volume is below the floating-point range: see
    :func:`orientations`). Returns ``(M,)``."""
    d, e = _unit_edges(points, tets, 3)
    with np.errstate(over="ignore", under="ignore"):
        return np.ldexp(_volumes6(d) / 6.0, 3 * e)


def orientations(points: FloatArray, tets: IntArray) -> FloatArray:
    """The sign of each tet's volume (+1 positively oriented, 0 flat, −1 inverted), the
    same at every scale (a volume of 1e-900 is positive). Returns ``(M,)``."""
    return np.sign(_volumes6(_unit_edges(points, tets, 3)[0]))


def edge_lengths(points: FloatArray, tets: IntArray) -> FloatArray:
    """Lengths of the six edges :data:`TET_EDGES` of every tetrahedron. Returns ``(M, 6)``."""
    d, e = _unit_edges(points, tets)
    with np.errstate(over="ignore", under="ignore"):
        return np.ldexp(np.sqrt(np.einsum("emk,emk->me", d, d)), e[:, None])


def _mean_ratios(d: FloatArray) -> FloatArray:
    vol = _volumes6(d) / 6.0
    sq = np.einsum("emk,emk->m", d, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = 12.0 * np.sign(vol) * np.cbrt(np.square(3.0 * vol)) / sq
    return np.where(sq > 0, q, 0.0)


def mean_ratios(points: FloatArray, tets: IntArray) -> FloatArray:
    """Mean ratio quality ``12 (3|V|)^(2/3) / Σ ℓ²``, signed like the volume.

    1 for the regular tetrahedron, in (0, 1] for a positive one, ≤ 0 for an inverted or
    degenerate one; invariant under rotation, translation and scaling (each tet is
    measured at a power of two of its own size: the same number at 1e±300). Returns
    ``(M,)``.
    """
    return _mean_ratios(_unit_edges(points, tets)[0])


#: the faces :data:`TET_FACES` as pairs of edges (indices into :data:`TET_EDGES`) whose
#: cross product is the face's normal: (q2 − q1) × (q3 − q1), (q3 − q0) × (q2 − q0), …
_FACE_EDGES = np.array([[3, 4], [2, 1], [0, 2], [1, 0]])


def _face_normals(d: FloatArray) -> FloatArray:
    return np.cross(d[_FACE_EDGES[:, 0]], d[_FACE_EDGES[:, 1]])


def face_normals(points: FloatArray, tets: IntArray) -> FloatArray:
    """Area-weighted normals ``(4, M, 3)`` of the faces :data:`TET_FACES` (face ``l`` is
    opposite vertex ``l``; outward for positive tetrahedra, length = twice the area)."""
    d, e = _unit_edges(points, tets)
    with np.errstate(over="ignore", under="ignore"):
        return np.ldexp(_face_normals(d), 2 * e[:, None])


def _dihedral_angles(d: FloatArray) -> FloatArray:
    n = _face_normals(d)
    a, b = n[_OPPOSITE[:, 0]], n[_OPPOSITE[:, 1]]  # (6, M, 3)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.einsum("emk,emk->em", a, b)
    return np.arctan2(cross, -dot).T


def dihedral_angles(points: FloatArray, tets: IntArray) -> FloatArray:
    """Interior dihedral angles in radians at the six edges :data:`TET_EDGES`.

    The angle at an edge is π minus the angle between the outward normals of its two
    faces, computed with ``arctan2(|n × m|, −n·m)`` (accurate near 0 and π). A mirrored
    (inverted) tetrahedron has the angles of its mirror image. Returns ``(M, 6)``.
    """
    return _dihedral_angles(_unit_edges(points, tets)[0])


@dataclass(frozen=True)
class TetQualitySummary(SummaryRecord):
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


def tet_quality_summary(points: FloatArray, tets: IntArray) -> TetQualitySummary:
    """Mean ratios, dihedral angles and volumes of all tetrahedra in one summary."""
    d, e = _unit_edges(points, tets)
    with np.errstate(over="ignore", under="ignore"):
        vol = np.ldexp(_volumes6(d) / 6.0, 3 * e)
    q = _mean_ratios(d)
    ang = np.degrees(_dihedral_angles(d))
    return TetQualitySummary(
        min_mean_ratio=float(q.min()), mean_mean_ratio=float(q.mean()),
        min_dihedral_deg=float(ang.min()), max_dihedral_deg=float(ang.max()),
        min_volume=float(vol.min()), total_volume=float(vol.sum()),
        n_inverted=int(np.count_nonzero(_volumes6(d) <= 0)))
