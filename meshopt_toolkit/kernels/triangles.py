"""Triangle measures, vectorized over all triangles (SPEC §2, thesis §4.1 and §5.3).

Every function takes node positions ``points`` of shape ``(N, 2)`` and triangles of shape
``(T, 3)`` (counter-clockwise = positive area) and returns one value per triangle, or per
triangle and local index ``l`` (shape ``(T, 3)``, column ``l`` belongs to the edge
opposite vertex ``l`` or to the angle at vertex ``l``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .._typing import FloatArray, IntArray

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


def edges_xy(qx: FloatArray, qy: FloatArray, tri_t: IntArray) -> tuple[FloatArray, FloatArray]:
    """Edge vectors of triangles ``tri_t (3, b)`` at coordinates ``qx, qy (N,)``, component-major.

    Component-major ``(3, b)`` x and y arrays: row ``l`` is edge ``l``,
    ``e_l = q_{i(l+2)} − q_{i(l+1)}`` (opposite vertex ``l``), as in
    :func:`edge_vectors`; the layout of the hot loops (penalties, P1 assembly).
    """
    x = np.take(qx, tri_t)
    y = np.take(qy, tri_t)
    ex = np.empty_like(x)
    ey = np.empty_like(y)
    for k, (a, b) in enumerate(((2, 1), (0, 2), (1, 0))):  # 3 local edges, not triangles
        np.subtract(x[a], x[b], out=ex[k])
        np.subtract(y[a], y[b], out=ey[k])
    return ex, ey


def areas_from_edges(ex: FloatArray, ey: FloatArray) -> FloatArray:
    """Signed areas ``A = ½ det[e2, e0]`` (e2 = q1 − q0, e0 = q2 − q1), (4.2), from the edge
    components of :func:`edges_xy` ``(3, b)``. Returns ``(b,)``."""
    return 0.5 * (ex[2] * ey[0] - ey[2] * ex[0])


def signed_areas(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Signed areas ``A = ½ det[q1 − q0, q2 − q0]``, (4.2); positive iff CCW. Returns (T,).

    (``det[q1 − q0, q2 − q1]`` of SPEC §2 is the same determinant.) Coordinates are
    gathered per axis with ``np.take`` into ``(3, T)`` blocks, which is several times
    faster than gathering ``(T, 2)`` rows per vertex.
    """
    x, y = _gather_xy(points, triangles)
    ax = x[1] - x[0]
    ay = y[1] - y[0]
    bx = x[2] - x[0]
    by = y[2] - y[0]
    ax *= by
    ay *= bx
    ax -= ay
    ax *= 0.5
    return ax


def min_signed_areas_on_segment(
    start: FloatArray, end: FloatArray, triangles: IntArray
) -> FloatArray:
    """Smallest signed area of each triangle along ``(1 − s)·start + s·end``, s ∈ [0, 1].

    Along a straight segment every signed area is a quadratic ``a + b s + c s²`` in s
    (the cross product of two edge vectors linear in s), so its minimum over [0, 1] is
    exact: the smaller end value, or the vertex ``−b/(2c)`` when ``c > 0`` and it lies
    inside. All positive means that no triangle inverts or collapses between the two
    configurations. Returns (T,).
    """
    x0, y0 = _gather_xy(start, triangles)
    x1, y1 = _gather_xy(end, triangles)
    ux, uy, vx, vy = x0[1] - x0[0], y0[1] - y0[0], x0[2] - x0[0], y0[2] - y0[0]
    dux = (x1[1] - x1[0]) - ux
    duy = (y1[1] - y1[0]) - uy
    dvx = (x1[2] - x1[0]) - vx
    dvy = (y1[2] - y1[0]) - vy
    a = 0.5 * (ux * vy - uy * vx)
    b = 0.5 * (ux * dvy - uy * dvx + dux * vy - duy * vx)
    c = 0.5 * (dux * dvy - duy * dvx)
    low = np.minimum(a, a + b + c)
    positive = c > 0
    s = np.zeros_like(c)
    np.divide(-b, 2.0 * c, out=s, where=positive)
    inside = positive & (s > 0) & (s < 1)
    return np.where(inside, np.minimum(low, a + b * s + c * s * s), low)


def segment_limit(points: FloatArray, triangles: IntArray, direction: FloatArray) -> float:
    """First ``t > 0`` at which a signed area of ``points + t·direction`` vanishes (``inf``
    if none): the largest step before a triangle inverts.

    The doubled area of each triangle along the line is the quadratic ``c + b t + a t²``
    (``c`` > 0 at an admissible configuration); every area stays positive on ``[0, t)``
    for ``t`` below the returned value, so a straight-line step cannot pass through an
    inverted configuration and come out on the other side.
    """
    q = points[triangles]  # (T, 3, 2)
    w = direction[triangles]
    e1, e2 = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    w1, w2 = w[:, 1] - w[:, 0], w[:, 2] - w[:, 0]

    def cross(u, v):
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]

    roots = first_positive_roots(cross(w1, w2), cross(e1, w2) + cross(w1, e2), cross(e1, e2))
    return float(roots.min()) if roots.size else np.inf


def first_positive_roots(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """Per entry, the first ``t > 0`` at which ``a t² + b t + c`` (``c > 0``: positive at
    ``t = 0``) vanishes, ``inf`` where it does not; from the stable pair of roots ``q/a``,
    ``c/q``, and where ``a = 0`` the root ``−c/b`` of the linear part (``b < 0``).
    """
    with np.errstate(all="ignore"):
        disc = b * b - 4.0 * a * c
        sq = np.sqrt(np.maximum(disc, 0.0))
        qq = -0.5 * (b + np.where(b >= 0, sq, -sq))
        r1 = np.where(a != 0, qq / a, np.inf)
        r2 = np.where(qq != 0, c / qq, np.inf)
        lin = np.where(b < 0, -c / b, np.inf)
    r1 = np.where((r1 > 0) & np.isfinite(r1), r1, np.inf)
    r2 = np.where((r2 > 0) & np.isfinite(r2), r2, np.inf)
    return np.where(a == 0, lin, np.where(disc < 0, np.inf, np.minimum(r1, r2)))


def doubled_areas_of_frames(frames: FloatArray, tri_t: IntArray) -> FloatArray:
    """Twice the signed areas, ``2A = (q1 − q0) × (q2 − q0)``, of every triangle of many
    configurations at once: ``frames`` ``(m, N, 2)``, ``tri_t`` ``(3, T)``; returns
    ``(m, T)``.

    Points are viewed as complex numbers ``z = x + iy`` (no copy of C-contiguous input),
    so ``2A = Im(conj(z1 − z0)(z2 − z0))`` costs one gather per corner for all frames.
    """
    z = np.ascontiguousarray(frames, dtype=np.float64).view(np.complex128)[..., 0][:, tri_t]
    return ((z[:, 1] - z[:, 0]).conj() * (z[:, 2] - z[:, 0])).imag


def _gather_xy(points: FloatArray, triangles: IntArray) -> tuple[FloatArray, FloatArray]:
    """Vertex coordinates of every triangle as two ``(3, T)`` arrays ``x``, ``y``.

    Row ``l`` holds local vertex ``l`` of every triangle, contiguous in memory.
    """
    pts = np.asarray(points, dtype=np.float64)
    tri = np.ascontiguousarray(np.asarray(triangles).T)  # contiguous index rows: fast take
    return np.take(pts[:, 0], tri), np.take(pts[:, 1], tri)


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


class SummaryRecord:
    """Base of the quality summaries: dataclasses of floats and the count ``n_inverted``."""

    def as_dict(self) -> dict:
        """The summary as a plain JSON-serializable dict."""
        return {k: (int(v) if k == "n_inverted" else float(v)) for k, v in asdict(self).items()}


@dataclass(frozen=True)
class QualitySummary(SummaryRecord):
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


def quality_summary(points: FloatArray, triangles: IntArray) -> QualitySummary:
    """Compute AR (5.49), Λ (6.25), extreme angles and areas in one vectorized pass.

    Works on 1-D per-triangle arrays with in-place arithmetic, and never evaluates an
    angle per triangle: with squared edge lengths ``E_l²``, their sum ``S`` and the
    doubled area ``2A``, the angle opposite edge ``l`` has

        cot θ_l = (S − 2 E_l²) / (4 |A|)        (law of cosines over 2A = b c sin θ)

    so the smallest angle of a triangle is opposite its shortest edge and the largest
    opposite its longest. Since cot is decreasing on (0, π), the mesh's extreme angles
    are ``arccot`` of the extreme cotangents: one ``arctan2`` per summary, not per
    triangle. The values equal those of :func:`angles` up to rounding.

    Parameters
    ----------
    points : (N, 2) float array
    triangles : (T, 3) int array

    Returns
    -------
    QualitySummary
        Degenerate triangles give ``min_aspect_ratio`` 0 and an infinite (or NaN)
        ``mean_shape_quality``, as the per-triangle kernels do.
    """
    x, y = _gather_xy(points, triangles)
    x0, x1, x2 = x  # contiguous rows, overwritten in place below
    y0, y1, y2 = y
    # edge vectors e0 = q2 - q1, e1 = q0 - q2, e2 = q1 - q0 (edge l opposite vertex l),
    # computed in place in the gathered buffers
    np.subtract(x1, x0, out=x1)  # x1 := e2x
    np.subtract(y1, y0, out=y1)  # y1 := e2y
    np.subtract(x0, x2, out=x0)  # x0 := e1x
    np.subtract(y0, y2, out=y0)  # y0 := e1y
    np.add(x0, x1, out=x2)  # e1 + e2 = -e0: its square is E0² and the sign is irrelevant
    np.add(y0, y1, out=y2)
    e0x, e0y, e1x, e1y, e2x, e2y = x2, y2, x0, y0, x1, y1
    # twice the signed area, (q1 - q0) × (q2 - q0) = e2 × (-e1), rounded exactly as in
    # signed_areas so that min_area and total_area agree with it bit for bit
    area2 = e1x * e2y
    area2 -= e2x * e1y
    # squared edge lengths
    s0 = np.square(e0x)
    s0 += np.square(e0y)
    s1 = np.square(e1x)
    s1 += np.square(e1y)
    s2 = np.square(e2x, out=e2x)
    s2 += np.square(e2y, out=e2y)
    ssum = s0 + s1
    ssum += s2
    with np.errstate(divide="ignore", invalid="ignore"):
        # Λ = mean (E0² + E1² + E2²) / (4√3 A)
        mean_inv_psi = float(np.mean(ssum / area2) / (2.0 * SQRT3))
        # extreme angles from the cotangents of each triangle's extreme angles
        smin = np.minimum(s0, s1)
        np.minimum(smin, s2, out=smin)
        smax = np.maximum(s0, s1)
        np.maximum(smax, s2, out=smax)
        abs2 = np.abs(area2)
        abs2 *= 2.0  # 4|A|
        cot_small = ssum - 2.0 * smin
        cot_small /= abs2
        cot_large = ssum - 2.0 * smax
        cot_large /= abs2
        # AR = 2r/R = 8 A|A| / (s E0 E1 E2) = 16 A|A| / ((E0 + E1 + E2) E0 E1 E2)
        l0, l1, l2 = np.sqrt(s0, out=s0), np.sqrt(s1, out=s1), np.sqrt(s2, out=s2)
        lsum = l0 + l1
        lsum += l2
        np.multiply(l0, l1, out=l0)
        np.multiply(l0, l2, out=l0)  # l0 := E0 E1 E2
        lsum *= l0
        ar = area2 * abs2  # (2A) · 4|A| = 8 A|A|; doubled: 8 A|A| / s with s = sum / 2
        ar += ar
        ar /= lsum
    n_inverted = int(np.count_nonzero(area2 <= 0))
    if n_inverted and not np.all(l0 > 0):
        ar[l0 == 0] = 0.0  # a triangle with a zero-length edge has AR 0 (like aspect_ratios)
    if n_inverted:
        # zero-area triangles give ±inf cotangents (angles 0 or π) and NaN when two
        # vertices coincide; the angle kernel gives 0 there (arctan2(0, 0))
        np.nan_to_num(cot_small, copy=False, nan=np.inf, posinf=np.inf, neginf=-np.inf)
        np.nan_to_num(cot_large, copy=False, nan=np.inf, posinf=np.inf, neginf=-np.inf)
    min_angle = np.arctan2(1.0, cot_small.max())
    max_angle = np.arctan2(1.0, cot_large.min())
    return QualitySummary(
        min_aspect_ratio=float(ar.min()),
        mean_shape_quality=mean_inv_psi,
        min_angle_deg=float(np.degrees(min_angle)),
        max_angle_deg=float(np.degrees(max_angle)),
        min_area=0.5 * float(area2.min()),
        total_area=0.5 * float(area2.sum()),
        n_inverted=n_inverted,
    )
