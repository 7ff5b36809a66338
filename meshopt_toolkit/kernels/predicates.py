"""Exact geometric predicates on float64 coordinates, vectorized.

Every sign here is the sign of the exact real number the float inputs stand for (each
float is a dyadic rational), so admissibility never depends on rounding:

- a floating-point **filter** evaluates ``t1 - t2`` (orientation) or ``t1 + t2`` (dot
  product) of two products of coordinate differences and trusts its sign where
  ``|det| > (3 + 16ε)ε (|t1| + |t2|) + 2⁻¹⁰⁰⁰`` (Shewchuk's static bound ``ccwerrboundA``,
  ε = 2⁻⁵³, plus an absolute term that covers underflow of the products to subnormal
  numbers; overflow gives a non-finite value, which is never trusted);
- the **uncertain** entries (near-degenerate configurations: usually none, a few per
  straight boundary piece) are evaluated exactly with Python integers: each float is
  ``M·2^e`` with an integer ``M`` (``numpy.frexp``), so every coordinate of an entry is an
  integer multiple of the entry's smallest ``2^e``.

Inputs must be finite. Signs are invariant under scaling by a power of two, so
:func:`exactly_scaled` puts points near unit size first when that is exact (it keeps the
filtered path from overflowing or underflowing at 1e±300).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = ["ERRBOUND", "exactly_scaled", "orient2d", "orient2d_xy", "dot_sign_xy",
           "segments_intersect", "triangle_orientations", "orient3d"]

_EPS = 2.0 ** -53
#: Shewchuk's ccwerrboundA: |fl(det) - det| <= ERRBOUND (|t1| + |t2|) without underflow
ERRBOUND = (3.0 + 16.0 * _EPS) * _EPS
#: absolute slack covering products that underflowed (each error <= 2^-1075)
_TINY = 2.0 ** -1000


def _sign_products(p1, q1, p2, q2, p3, q3, p4, q4, minus: bool, positive: bool = False):
    """Float filter of ``(p1 − q1)(p2 − q2) ∓ (p3 − q3)(p4 − q4)``: ``(value, sign,
    uncertain)``; ``sign`` (int8) is exact where ``uncertain`` is False. With
    ``positive``, ``(value, None, None)`` when every value is certainly positive (the
    common case of an admissible mesh, in fewer passes).

    Besides the error bound, a term with a zero factor is exactly 0 (a float difference is
    0 only for equal inputs), and then the sign is that of the other term's factors (exact
    even where that product under- or overflows): axis-parallel degeneracies, common in
    structured meshes and rectangles, need no exact fallback.
    """
    with np.errstate(all="ignore"):
        d1 = np.subtract(p1, q1)
        d2 = np.subtract(p2, q2)
        d3 = np.subtract(p3, q3)
        d4 = np.subtract(p4, q4)
        t1 = d1 * d2
        t2 = d3 * d4
        det = np.subtract(t1, t2) if minus else np.add(t1, t2)
        np.abs(t1, out=t1)
        np.abs(t2, out=t2)
        t1 += t2
        t1 *= ERRBOUND
        t1 += _TINY
        if positive and (det > t1).all():
            return det, None, None
        np.abs(det, out=t2)
        uncertain = ~(t2 > t1)  # NaN (overflow) is uncertain too
        sign = np.greater(det, 0).view(np.int8) - np.less(det, 0).view(np.int8)
        if uncertain.any():
            k = np.flatnonzero(uncertain)
            s1 = np.sign(d1[k]) * np.sign(d2[k])
            s2 = np.sign(d3[k]) * np.sign(d4[k])
            known = (s1 == 0) | (s2 == 0)
            sign[k[known]] = np.sign(s1[known] - s2[known] if minus else s1[known] + s2[known])
            uncertain[k[known]] = False
    return det, sign, uncertain


def _integer_rows(X: FloatArray) -> Iterator[list[int]]:
    """Each row of ``X`` (K, n) as Python integers in units of the row's smallest power of
    two: its exact binary values, all scaled by one power of two.

    Raises
    ------
    ValueError
        A coordinate is not finite.
    """
    if not np.isfinite(X).all():
        raise ValueError("exact predicates need finite coordinates")
    m, e = np.frexp(X)
    M = np.ldexp(m, 53).astype(np.int64)  # exact: X = M * 2**(e - 53)
    e = e.astype(np.int64) - 53
    big = np.iinfo(np.int64).max
    e0 = np.where(M != 0, e, big).min(axis=1, keepdims=True)
    e0 = np.where(e0 == big, 0, e0)
    shift = np.where(M != 0, e - e0, 0)  # >= 0: every coordinate is an integer * 2**e0
    for mk, sk in zip(M.tolist(), shift.tolist()):
        yield [v << s for v, s in zip(mk, sk)]


def _exact_signs(coords: list[FloatArray], minus: bool) -> np.ndarray:
    """Exact sign of ``(c0 - c1)(c2 - c3) ∓ (c4 - c5)(c6 - c7)`` per entry (Python integers).

    ``coords``: eight 1-D float arrays of the same length (finite)."""
    X = np.stack([np.asarray(c, dtype=float) for c in coords], axis=1)  # (K, 8)
    if len(X) == 0:
        return np.zeros(0, np.int8)
    out = []
    for a in _integer_rows(X):
        t1 = (a[0] - a[1]) * (a[2] - a[3])
        t2 = (a[4] - a[5]) * (a[6] - a[7])
        d = t1 - t2 if minus else t1 + t2
        out.append((d > 0) - (d < 0))
    return np.array(out, dtype=np.int8)


def _signs(coords: list[FloatArray], minus: bool, positive: bool = False):
    """``(value, exact sign)`` of ``(c0 − c1)(c2 − c3) ∓ (c4 − c5)(c6 − c7)`` per entry of
    the eight 1-D arrays ``coords``: the float filter (:func:`_sign_products`), exact
    integers (:func:`_exact_signs`) where it cannot tell. With ``positive``,
    ``(value, None)`` when every value is certainly positive."""
    det, sign, uncertain = _sign_products(*coords, minus=minus, positive=positive)
    if sign is not None and uncertain.any():
        k = np.flatnonzero(uncertain)
        sign[k] = _exact_signs([c[k] for c in coords], minus=minus)
    return det, sign


def orient2d_xy(ax, ay, bx, by, cx, cy) -> np.ndarray:
    """Exact orientation sign of triangles ``(a, b, c)``: +1 counter-clockwise, −1
    clockwise, 0 collinear; ``int8`` array of the broadcast shape of the coordinates.

    The sign of ``(bx − ax)(cy − ay) − (by − ay)(cx − ax)`` for the exact input values."""
    shape, (ax, ay, bx, by, cx, cy) = _flat(ax, ay, bx, by, cx, cy)
    return _signs([bx, ax, cy, ay, by, ay, cx, ax], minus=True)[1].reshape(shape)


def _flat(*values):
    """The broadcast shape and the values as 1-D float arrays of that size."""
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in values))
    return arrays[0].shape, [a.ravel() for a in arrays]


def orient2d(a: FloatArray, b: FloatArray, c: FloatArray) -> np.ndarray:
    """:func:`orient2d_xy` of point arrays ``a, b, c`` of shape ``(..., 2)``."""
    a, b, c = (np.asarray(p, dtype=float) for p in (a, b, c))
    return orient2d_xy(a[..., 0], a[..., 1], b[..., 0], b[..., 1], c[..., 0], c[..., 1])


def dot_sign_xy(ax, ay, bx, by, cx, cy) -> np.ndarray:
    """Exact sign of ``(a − b)·(c − b)`` (the angle at ``b`` is acute: +1, right: 0)."""
    shape, (ax, ay, bx, by, cx, cy) = _flat(ax, ay, bx, by, cx, cy)
    return _signs([ax, bx, cx, bx, ay, by, cy, by], minus=False)[1].reshape(shape)


def segments_intersect(a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray
                       ) -> np.ndarray:
    """Do the closed segments ``[a, b]`` and ``[c, d]`` meet (touching included)? Exact.

    ``a, b, c, d`` are ``(K, 2)``; returns ``(K,)`` bool. The segments meet iff each one's
    endpoints are not strictly on one side of the other's line; when all four orientations
    are 0 the segments are collinear and meet iff their projections on an axis the line
    is not perpendicular to overlap (comparisons of floats are exact).
    """
    a, b, c, d = (np.asarray(p, dtype=float).reshape(-1, 2) for p in (a, b, c, d))
    d1 = orient2d(a, b, c)
    d2 = orient2d(a, b, d)
    d3 = orient2d(c, d, a)
    d4 = orient2d(c, d, b)
    hit = (d1 * d2 <= 0) & (d3 * d4 <= 0)
    col = hit & (d1 == 0) & (d2 == 0) & (d3 == 0) & (d4 == 0)
    if col.any():
        k = np.flatnonzero(col)
        # the x axis unless every x is equal (then the common line is vertical)
        P = np.stack([a[k], b[k], c[k], d[k]])  # (4, k, 2)
        vertical = (P[:, :, 0] == P[0, :, 0]).all(axis=0)
        s = P[:, np.arange(len(k)), vertical.astype(np.int64)]  # (4, k)
        lo1, hi1 = np.minimum(s[0], s[1]), np.maximum(s[0], s[1])
        lo2, hi2 = np.minimum(s[2], s[3]), np.maximum(s[2], s[3])
        hit[k] = (lo1 <= hi2) & (lo2 <= hi1)
    return hit


def triangle_orientations(qx: FloatArray, qy: FloatArray, tri_t: IntArray,
                          lazy: bool = False) -> tuple[FloatArray, np.ndarray | None]:
    """Twice the signed areas (floating point) and their exact signs.

    Parameters
    ----------
    qx, qy : (N,) coordinates (finite)
    tri_t : (3, T) triangles
    lazy : bool
        Return ``sign=None`` when every triangle is certainly positive.

    Returns
    -------
    det : (T,) float array
        ``(q1 − q0) × (q2 − q0)`` rounded (may be ±inf/NaN at extreme magnitudes).
    sign : (T,) int8 array, or None
        Its exact sign; the float value's sign wherever the filter certifies it.
    """
    x = np.take(qx, tri_t)
    y = np.take(qy, tri_t)
    return _signs([x[1], x[0], y[2], y[0], y[1], y[0], x[2], x[0]], minus=True, positive=lazy)


def exactly_scaled(points: FloatArray, extreme_only: bool = False) -> tuple[FloatArray, int]:
    """``(S, k)`` with ``points == S * 2**k`` exactly: ``S`` has its largest ``|coordinate|``
    in ``[0.5, 1)`` where that scaling is exact (no coordinate becomes subnormal); else
    ``(points, 0)``. With ``extreme_only``, points whose largest ``|coordinate|`` is in
    ``[2**-256, 2**256)`` are returned as they are (the filter neither overflows nor
    underflows there either).

    Signs of the predicates are unchanged; near unit size the filter neither overflows
    nor underflows, so the exact fallback stays rare at 1e±300 too.
    """
    P = np.asarray(points, dtype=float)
    if P.size == 0:
        return P, 0
    with np.errstate(invalid="ignore"):
        big = float(np.max(np.abs(P)))
    if not np.isfinite(big) or big == 0.0:
        return P, 0
    k = int(np.frexp(big)[1])
    if k == 0 or (extreme_only and -255 <= k <= 256):
        return P, 0
    with np.errstate(all="ignore"):
        S = np.ldexp(P, -k)
        if k < 0 or np.array_equal(np.ldexp(S, k), P):  # scaling up is always exact
            return S, k
    return P, 0


# ---------------------------------------------------------------------------------------
# orient3d: the sign of a 3x3 determinant of coordinate differences

#: Shewchuk's o3derrboundA: |fl(det) − det| <= O3D_ERRBOUND * permanent (no under/overflow)
O3D_ERRBOUND = (7.0 + 56.0 * _EPS) * _EPS
#: differences in [2^-330, 2^330] (or 0): no product of three under- or overflows
_O3D_SMALL, _O3D_LARGE = 2.0 ** -330, 2.0 ** 330


def _exact_orient3d(D: FloatArray) -> np.ndarray:
    """Exact sign of ``det [b − a; c − a; d − a]`` per row of ``D`` (K, 4, 3) (Python
    integers on the exact binary values: every coordinate of a row is an integer multiple
    of the row's smallest power of two)."""
    if len(D) == 0:
        return np.zeros(0, np.int8)
    out = np.empty(len(D), np.int8)
    for k, row in enumerate(_integer_rows(D.reshape(len(D), 12))):
        ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz = row
        bx, by, bz = bx - ax, by - ay, bz - az
        cx, cy, cz = cx - ax, cy - ay, cz - az
        dx, dy, dz = dx - ax, dy - ay, dz - az
        det = bx * (cy * dz - cz * dy) - by * (cx * dz - cz * dx) + bz * (cx * dy - cy * dx)
        out[k] = (det > 0) - (det < 0)
    return out


def orient3d(a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray) -> np.ndarray:
    """Exact orientation of the tetrahedra ``(a, b, c, d)``: the sign of
    ``det [b − a; c − a; d − a]`` (six times the signed volume; +1 where ``d`` lies on the
    side of the plane ``abc`` that ``(b − a) × (c − a)`` points to, 0 when coplanar).

    Parameters
    ----------
    a, b, c, d : (..., 3) float arrays (broadcast together; finite)

    Returns
    -------
    (...) int8 array

    Notes
    -----
    The determinant of the differences from ``d`` (of the opposite sign) is evaluated in floating point and its
    sign trusted where ``|det| > (7 + 56ε)ε · permanent + 2⁻¹⁰⁰⁰`` (Shewchuk's
    ``o3derrboundA``, plus an absolute term for a product that underflows) and every non-zero difference lies in ``[2⁻³³⁰, 2³³⁰]`` (no product under- or
    overflows); a permanent of 0 means every product has a zero factor (det is exactly 0).
    The remaining rows are evaluated exactly with Python integers.
    """
    arrays = np.broadcast_arrays(*(np.asarray(p, dtype=float) for p in (a, b, c, d)))
    shape = arrays[0].shape[:-1]
    if arrays[0].shape[-1:] != (3,):
        raise ValueError("orient3d needs points of shape (..., 3)")
    A, B, C, Dp = (p.reshape(-1, 3) for p in arrays)
    with np.errstate(all="ignore"):
        ad, bd, cd = A - Dp, B - Dp, C - Dp
        adx, ady, adz = ad.T
        bdx, bdy, bdz = bd.T
        cdx, cdy, cdz = cd.T
        p1, p2 = bdx * cdy, bdy * cdx
        p3, p4 = cdx * ady, cdy * adx
        p5, p6 = adx * bdy, ady * bdx
        det = adz * (p1 - p2) + bdz * (p3 - p4) + cdz * (p5 - p6)
        perm = (np.abs(adz) * (np.abs(p1) + np.abs(p2)) + np.abs(bdz) * (np.abs(p3) + np.abs(p4))
                + np.abs(cdz) * (np.abs(p5) + np.abs(p6)))
        diffs = np.abs(np.concatenate([ad, bd, cd], axis=1))
        ranged = ((diffs == 0) | ((diffs >= _O3D_SMALL) & (diffs <= _O3D_LARGE))).all(axis=1)
        # + _TINY: a product with a cancelled difference may still underflow (error
        # below 2^-1070 in all)
        certain = ranged & ((np.abs(det) > O3D_ERRBOUND * perm + _TINY) | (perm == 0))
    # det [a − d; b − d; c − d] = −det [b − a; c − a; d − a]
    sign = np.where(certain, -np.sign(det), 0).astype(np.int8)
    if not certain.all():
        k = np.flatnonzero(~certain)
        sign[k] = _exact_orient3d(np.stack([A[k], B[k], C[k], Dp[k]], axis=1))
    return sign.reshape(shape)
