"""Exact predicates (kernels/predicates.py) against exact rational arithmetic.

Near-degenerate inputs on purpose: points on or a few ulps off a line, collinear and
overlapping segments, magnitudes from subnormal to near overflow."""

from __future__ import annotations

from fractions import Fraction as F

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.kernels.boundary import boundary_self_intersections
from meshopt_toolkit.kernels.predicates import (dot_sign_xy, exactly_scaled, orient2d,
                                                segments_intersect, triangle_orientations)


def _sgn(x) -> int:
    return (x > 0) - (x < 0)


def ref_orient(a, b, c) -> int:
    ax, ay, bx, by, cx, cy = (F(float(v)) for v in (*a, *b, *c))
    return _sgn((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))


def ref_segments(a, b, c, d) -> bool:
    """Closed segments meet: parametric solution in rationals (independent of orientations
    of the kernel's form)."""
    a, b, c, d = ([F(float(v)) for v in p] for p in (a, b, c, d))
    r = (b[0] - a[0], b[1] - a[1])
    s = (d[0] - c[0], d[1] - c[1])
    w = (c[0] - a[0], c[1] - a[1])
    den = r[0] * s[1] - r[1] * s[0]
    if den != 0:
        t = (w[0] * s[1] - w[1] * s[0]) / den
        u = (w[0] * r[1] - w[1] * r[0]) / den
        return 0 <= t <= 1 and 0 <= u <= 1
    if w[0] * r[1] - w[1] * r[0] != 0 or w[0] * s[1] - w[1] * s[0] != 0:
        return False  # parallel, on different lines

    def on(p, q, x):  # x on [p, q] for collinear p, q, x
        return min(p[0], q[0]) <= x[0] <= max(p[0], q[0]) and \
            min(p[1], q[1]) <= x[1] <= max(p[1], q[1])

    return on(a, b, c) or on(a, b, d) or on(c, d, a) or on(c, d, b)


def _ulps(x: float, k: int) -> float:
    for _ in range(abs(k)):
        x = float(np.nextafter(x, np.inf if k > 0 else -np.inf))
    return x


coord = st.floats(-4.0, 4.0, allow_nan=False, allow_infinity=False)
any_float = st.floats(allow_nan=False, allow_infinity=False)
ulp = st.integers(-3, 3)
exponent = st.sampled_from([0, 0, -1000, -600, -60, 60, 600, 1000])


@st.composite
def near_collinear(draw):
    """Three points, the third on the line of the first two (rounded) and moved by a few
    ulps, all scaled by a power of two or by a non-dyadic factor."""
    a = (draw(coord), draw(coord))
    b = (draw(coord), draw(coord))
    t = draw(st.floats(-3.0, 3.0))
    c = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
    c = (_ulps(c[0], draw(ulp)), _ulps(c[1], draw(ulp)))
    e = draw(exponent)
    factor = draw(st.sampled_from([1.0, 1.0, 3.7e-250, 1.3e250]))
    pts = np.array([a, b, c]) * factor
    with np.errstate(all="ignore"):
        pts = np.ldexp(pts, e)
    if not np.isfinite(pts).all():
        pts = np.array([a, b, c])
    return pts


@settings(max_examples=400, deadline=None)
@given(near_collinear())
def test_orient2d_near_collinear_matches_fractions(pts):
    a, b, c = pts
    want = ref_orient(a, b, c)
    # every cyclic order and the mirrored one
    assert orient2d(a, b, c)[()] == want
    assert orient2d(b, c, a)[()] == want
    assert orient2d(b, a, c)[()] == -want


@settings(max_examples=300, deadline=None)
@given(st.lists(any_float, min_size=6, max_size=6))
def test_orient2d_any_finite_floats(v):
    # the whole range: differences and products overflow or underflow
    a, b, c = np.array(v).reshape(3, 2)
    assert orient2d(a, b, c)[()] == ref_orient(a, b, c)


@settings(max_examples=200, deadline=None)
@given(near_collinear())
def test_dot_sign_matches_fractions(pts):
    a, b, c = (tuple(F(float(x)) for x in p) for p in pts)
    want = _sgn((a[0] - b[0]) * (c[0] - b[0]) + (a[1] - b[1]) * (c[1] - b[1]))
    assert dot_sign_xy(*pts[0], *pts[1], *pts[2])[()] == want


def test_orient2d_vectorized_mixes_filtered_and_exact(rng):
    # mostly clear cases, some exact zeros of the float formula with nonzero true values
    pts = rng.uniform(-1, 1, (500, 3, 2))
    t = rng.uniform(-2, 2, 200)
    pts[:200, 2] = pts[:200, 0] + t[:, None] * (pts[:200, 1] - pts[:200, 0])
    # exactly collinear: dyadic points and midpoints
    pts[200:250, :2] = rng.integers(-64, 64, (50, 2, 2)) / 8
    pts[200:250, 2] = 0.5 * (pts[200:250, 0] + pts[200:250, 1])
    got = orient2d(pts[:, 0], pts[:, 1], pts[:, 2])
    want = [ref_orient(*p) for p in pts]
    assert got.tolist() == want
    assert set(want[:200]) == {-1, 1} and set(want[200:250]) == {0}
    a, b, c = pts[:200, 0], pts[:200, 1], pts[:200, 2]
    rounded = np.sign((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                      - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    assert (rounded != want[:200]).sum() > 10  # rounding gets many of them wrong


@st.composite
def segment_pairs(draw):
    """Two segments on (or a few ulps off) one line, overlapping, touching or apart; or
    through one point; scaled far from unit size."""
    a = np.array([draw(coord), draw(coord)])
    d = np.array([draw(coord), draw(coord)])
    kind = draw(st.sampled_from(["line", "line", "point", "free"]))
    if kind == "free":
        pts = [a, d, np.array([draw(coord), draw(coord)]), np.array([draw(coord), draw(coord)])]
    elif kind == "point":  # c on segment ab (rounded), d anywhere
        t = draw(st.sampled_from([0.0, 0.5, 1.0, 0.3]))
        b = np.array([draw(coord), draw(coord)])
        pts = [a, b, a + t * (b - a), d]
    else:  # four points along a line: params decide overlap / touching / gap
        ts = [draw(st.sampled_from([0.0, 0.25, 0.5, 0.75, 1.0, 1.5, -0.5])) for _ in range(4)]
        pts = [a + t * (d - a) for t in ts]
    pts = [np.array([_ulps(p[0], draw(ulp)), _ulps(p[1], draw(ulp))]) for p in pts]
    e = draw(exponent)
    with np.errstate(all="ignore"):
        out = [np.ldexp(p, e) for p in pts]
    return out if all(np.isfinite(p).all() for p in out) else pts


@settings(max_examples=400, deadline=None)
@given(segment_pairs())
def test_segments_intersect_matches_fractions(seg):
    a, b, c, d = seg
    want = ref_segments(a, b, c, d)
    assert segments_intersect(a, b, c, d)[0] == want
    assert segments_intersect(c, d, b, a)[0] == want


def test_collinear_overlap_cases():
    # exactly collinear (dyadic slope): overlap, touch at an end, gap; vertical and
    # horizontal; a segment reduced to a point
    a, b = np.array([[0.0, 0.0]]), np.array([[4.0, 2.0]])
    cases = {((2.0, 1.0), (6.0, 3.0)): True, ((4.0, 2.0), (6.0, 3.0)): True,
             ((4.5, 2.25), (6.0, 3.0)): False, ((-2.0, -1.0), (-0.5, -0.25)): False,
             ((1.0, 0.5), (1.0, 0.5)): True, ((5.0, 2.5), (5.0, 2.5)): False}
    for (c, d), want in cases.items():
        assert segments_intersect(a, b, np.array([c]), np.array([d]))[0] == want, (c, d)
        assert ref_segments(a[0], b[0], c, d) == want
    v = np.array([[0.0, 0.0]]), np.array([[0.0, 1.0]])
    assert segments_intersect(*v, np.array([[0.0, 1.0]]), np.array([[0.0, 2.0]]))[0]
    assert not segments_intersect(*v, np.array([[0.0, 1.5]]), np.array([[0.0, 2.0]]))[0]


# Four consecutive boundary vertices of a straight slanted side: the edges (p0, p1) and
# (p2, p3) are 0.12 apart, yet the float orientation of p0 against (p2, p3) is exactly 0
# while that of p1 is not. The rounded test took the pair for touching.
SLANTED_SIDE = np.array([[-1.64710966981131, 0.8126513770315601],
                         [-1.6268885133766084, 0.7958679555592545],
                         [-1.5055615747684004, 0.6951674267254214],
                         [-1.485340418333699, 0.6783840052531158]])


def test_slanted_side_is_not_touching():
    p = SLANTED_SIDE

    def rounded(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

    d = [rounded(p[0], p[1], p[2]), rounded(p[0], p[1], p[3]),
         rounded(p[2], p[3], p[0]), rounded(p[2], p[3], p[1])]
    # the trap: rounding says "touching" (products <= 0, not all four zero)
    assert d[0] * d[1] <= 0 and d[2] * d[3] <= 0 and not all(x == 0 for x in d)
    assert not ref_segments(*p)
    assert not segments_intersect(p[0], p[1], p[2], p[3])[0]
    # as boundary edges with a long edge elsewhere (so the pair passes the broad phase)
    pts = np.concatenate([p, [[50.0, 50.0], [60.0, 60.0]]])
    edges = np.array([[0, 1], [1, 2], [2, 3], [4, 5]])
    assert len(boundary_self_intersections(pts, edges)) == 0


@settings(max_examples=150, deadline=None)
@given(st.lists(near_collinear(), min_size=1, max_size=8))
def test_triangle_orientations_match_fractions(tris):
    P = np.concatenate(tris)
    tri_t = np.arange(len(P)).reshape(-1, 3).T
    det, sign = triangle_orientations(P[:, 0], P[:, 1], tri_t)
    want = [ref_orient(*t) for t in tris]
    assert sign.tolist() == want
    # the lazy form: None only when every triangle is positive
    _, lazy = triangle_orientations(P[:, 0], P[:, 1], tri_t, lazy=True)
    assert (lazy is None and set(want) == {1}) or lazy.tolist() == want
    # counter-clockwise copies: all positive, certified by the filter or exactly
    ccw = np.where(np.array(want)[None] < 0, tri_t[[0, 2, 1]], tri_t)
    keep = np.array(want) != 0
    if keep.any():
        s = triangle_orientations(P[:, 0], P[:, 1], ccw[:, keep], lazy=True)[1]
        assert s is None or (s == 1).all()


@settings(max_examples=200, deadline=None)
@given(st.lists(any_float, min_size=2, max_size=12))
def test_exactly_scaled_is_exact(v):
    P = np.array(v[: len(v) // 2 * 2]).reshape(-1, 2)
    S, k = exactly_scaled(P)
    assert np.array_equal(np.ldexp(S, k), P)
    if k:
        assert 0.5 <= np.abs(S).max() < 1


def test_non_finite_coordinates_are_refused():
    with pytest.raises(ValueError):
        orient2d(np.array([0.0, np.nan]), np.array([1.0, 0.0]), np.array([2.0, 0.0]))


def test_boundary_near_overflow_that_cannot_be_scaled():
    # ±8e307 with a subnormal coordinate: no exact power-of-two scaling exists, the
    # differences overflow; the exact fallback decides
    big, tiny = 8e307, 5e-324
    square = np.array([[-big, -big], [tiny, -big], [big, -big], [big, big], [-big, big]])
    edges = np.stack([np.arange(5), np.roll(np.arange(5), -1)], 1)
    assert exactly_scaled(square)[1] == 0
    assert len(boundary_self_intersections(square, edges)) == 0
    bowtie = square[[0, 1, 2, 4, 3]]  # the last two swapped: two edges cross
    assert boundary_self_intersections(bowtie, edges).tolist() == [[2, 4]]
    assert ref_segments(*bowtie[[2, 3]], *bowtie[[4, 0]])
