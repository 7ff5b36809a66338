"""Triangle measures, vectorized over all triangles (SPEC §2, thesis §4.1 and §5.3).

Every function takes node positions ``points`` of shape ``(N, 2)`` and triangles of shape
``(T, 3)`` (counter-clockwise = positive area) and returns one value per triangle, or per
triangle and local index ``l`` (shape ``(T, 3)``, column ``l`` belongs to the edge
opposite vertex ``l`` or to the angle at vertex ``l``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ._typing import FloatArray, IntArray

SQRT3 = np.sqrt(3.0)


def edge_vectors(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Edge vectors ``e_l = q_{i(l+2)} - q_{i(l+1)}`` (edge ``l`` is opposite vertex ``l``).

    Returns
    -------
    (T, 3, 2) array. The three vectors of a triangle sum to zero.
    """
    p = points[triangles]  # (T, 3, 2)
    return np.roll(p, -2, axis=1) - np.roll(p, -1, axis=1)


def edge_lengths(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Edge lengths ``E_l`` of every triangle, (4.1). Returns (T, 3)."""
    e = edge_vectors(points, triangles)
    return np.sqrt(np.einsum("tlk,tlk->tl", e, e))


def signed_areas(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Signed areas ``A = ½ det[q1 − q0, q2 − q1]``, (4.2); positive iff CCW. Returns (T,)."""
    p0 = points[triangles[:, 0]]
    p1 = points[triangles[:, 1]]
    p2 = points[triangles[:, 2]]
    a = p1 - p0
    b = p2 - p0
    return 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def heights(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Heights ``h_l = 2A / E_l`` onto edge ``l``, (5.5). Returns (T, 3)."""
    return 2.0 * signed_areas(points, triangles)[:, None] / edge_lengths(points, triangles)


def inradii(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Inradius ``r = A / s`` with semi-perimeter ``s``, (4.11). Returns (T,)."""
    return signed_areas(points, triangles) / (0.5 * edge_lengths(points, triangles).sum(axis=1))


def circumradii(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Circumradius ``R = E0 E1 E2 / (4A)``, (4.11). Returns (T,)."""
    return edge_lengths(points, triangles).prod(axis=1) / (4.0 * signed_areas(points, triangles))


def angles(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Interior angles in radians at each local vertex. Returns (T, 3), rows sum to π.

    Computed with ``arctan2(|cross|, dot)`` so that tiny and near-π angles are accurate.
    """
    p = points[triangles]
    u = np.roll(p, -1, axis=1) - p  # towards next vertex
    v = np.roll(p, -2, axis=1) - p  # towards previous vertex
    cross = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    dot = np.einsum("tlk,tlk->tl", u, v)
    return np.arctan2(np.abs(cross), dot)


def inverse_shape_quality(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Shape quality ``1/ψ = (E0² + E1² + E2²) / (4√3 A)``, (5.23). Returns (T,).

    ``1/ψ ≥ 1`` with equality iff the triangle is equilateral; it is negative for an
    inverted triangle and infinite for a degenerate one.
    """
    e = edge_vectors(points, triangles)
    sq = np.einsum("tlk,tlk->t", e, e)
    with np.errstate(divide="ignore"):
        return sq / (4.0 * SQRT3 * signed_areas(points, triangles))


def aspect_ratios(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Aspect ratio ``2r/R = 8 A² / (s E0 E1 E2)`` in (0, 1]; 1 iff equilateral. Returns (T,).

    Signed like the area (negative for an inverted triangle), zero when degenerate.
    """
    lengths = edge_lengths(points, triangles)
    area = signed_areas(points, triangles)
    s = 0.5 * lengths.sum(axis=1)
    prod = lengths.prod(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = 8.0 * area * np.abs(area) / (s * prod)
    return np.where(prod > 0, ratio, 0.0)


@dataclass(frozen=True)
class QualitySummary:
    """Mesh-level quality numbers (SPEC §2).

    Attributes
    ----------
    min_aspect_ratio : AR(Q) = min 2r/R, (5.49)
    mean_shape_quality : Λ(Q) = mean 1/ψ, (6.25)
    min_angle_deg, max_angle_deg : extreme interior angles in degrees
    min_area : smallest signed area
    total_area : sum of the signed areas
    n_inverted : number of triangles with signed area <= 0
    """

    min_aspect_ratio: float
    mean_shape_quality: float
    min_angle_deg: float
    max_angle_deg: float
    min_area: float
    total_area: float
    n_inverted: int

    def as_dict(self) -> dict:
        """The summary as a plain JSON-serializable dict."""
        return {k: (int(v) if k == "n_inverted" else float(v)) for k, v in asdict(self).items()}


def quality_summary(points: FloatArray, triangles: IntArray) -> QualitySummary:
    """Compute AR, Λ, extreme angles and areas in one vectorized pass.

    Parameters
    ----------
    points : (N, 2) float array
    triangles : (T, 3) int array

    Returns
    -------
    QualitySummary
    """
    p = points[triangles]  # (T, 3, 2)
    e = np.roll(p, -2, axis=1) - np.roll(p, -1, axis=1)  # edge l opposite vertex l
    sq = np.einsum("tlk,tlk->tl", e, e)
    lengths = np.sqrt(sq)
    # signed area from two edge vectors: e0 = q2 - q1, e1 = q0 - q2
    area = 0.5 * (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    s = 0.5 * lengths.sum(axis=1)
    prod = lengths.prod(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ar = np.where(prod > 0, 8.0 * area * np.abs(area) / (s * prod), 0.0)
        inv_psi = sq.sum(axis=1) / (4.0 * SQRT3 * area)
    # angle at vertex l is between edges l+1 and l+2 (pointing away from vertex l):
    # u = q_{l+1} - q_l = -e_{l+2}, v = q_{l+2} - q_l = e_{l+1}
    u = -np.roll(e, -2, axis=1)
    v = np.roll(e, -1, axis=1)
    cross = np.abs(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])
    dot = np.einsum("tlk,tlk->tl", u, v)
    ang = np.degrees(np.arctan2(cross, dot))
    return QualitySummary(
        min_aspect_ratio=float(ar.min()),
        mean_shape_quality=float(inv_psi.mean()),
        min_angle_deg=float(ang.min()),
        max_angle_deg=float(ang.max()),
        min_area=float(area.min()),
        total_area=float(area.sum()),
        n_inverted=int(np.count_nonzero(area <= 0)),
    )
