"""Triangle measures (SPEC §2) against hand computations and independent formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.kernels.triangles import (
    angles,
    aspect_ratios,
    circumradii,
    edge_lengths,
    edge_vectors,
    heights,
    inradii,
    inverse_shape_quality,
    quality_summary,
    signed_areas,
)

EQUILATERAL = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, math.sqrt(3.0)]])
RIGHT_ISO = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])  # legs 1, right angle at vertex 0
ONE = np.array([[0, 1, 2]])


def random_triangles(rng, t=50):
    """Random CCW triangles as separate vertices: points (3t, 2), triangles (t, 3)."""
    pts = rng.normal(size=(3 * t, 2))
    tri = np.arange(3 * t).reshape(t, 3)
    a = signed_areas(pts, tri)
    tri[a < 0] = tri[a < 0][:, ::-1]
    return pts, tri


def heron_area(p):
    a, b, c = (
        np.linalg.norm(p[1] - p[2]),
        np.linalg.norm(p[2] - p[0]),
        np.linalg.norm(p[0] - p[1]),
    )
    s = (a + b + c) / 2
    return math.sqrt(s * (s - a) * (s - b) * (s - c))


# -- hand-computable triangles -------------------------------------------------------


def test_equilateral_triangle():
    p, t = EQUILATERAL, ONE
    np.testing.assert_allclose(edge_lengths(p, t), [[2, 2, 2]], rtol=1e-15)
    np.testing.assert_allclose(signed_areas(p, t), [math.sqrt(3)], rtol=1e-15)
    np.testing.assert_allclose(heights(p, t), [[math.sqrt(3)] * 3], rtol=1e-15)
    np.testing.assert_allclose(inradii(p, t), [1 / math.sqrt(3)], rtol=1e-15)
    np.testing.assert_allclose(circumradii(p, t), [2 / math.sqrt(3)], rtol=1e-15)
    np.testing.assert_allclose(angles(p, t), [[math.pi / 3] * 3], rtol=1e-15)
    np.testing.assert_allclose(inverse_shape_quality(p, t), [1.0], rtol=1e-15)
    np.testing.assert_allclose(aspect_ratios(p, t), [1.0], rtol=1e-15)
    q = quality_summary(p, t)
    assert q.min_aspect_ratio == pytest.approx(1.0, rel=1e-15)
    assert q.mean_shape_quality == pytest.approx(1.0, rel=1e-15)
    assert q.min_angle_deg == pytest.approx(60.0, rel=1e-14)
    assert q.max_angle_deg == pytest.approx(60.0, rel=1e-14)
    assert q.n_inverted == 0


def test_right_isosceles_triangle_closed_forms():
    p, t = RIGHT_ISO, ONE
    s2 = math.sqrt(2.0)
    # edge l opposite vertex l: E0 = |q1 q2| = √2, E1 = |q2 q0| = 1, E2 = |q0 q1| = 1
    np.testing.assert_allclose(edge_lengths(p, t), [[s2, 1, 1]], rtol=1e-15)
    np.testing.assert_array_equal(edge_vectors(p, t), [[[-1, 1], [0, -1], [1, 0]]])
    assert signed_areas(p, t)[0] == 0.5
    np.testing.assert_allclose(heights(p, t), [[1 / s2, 1, 1]], rtol=1e-15)
    r = 0.5 / ((2 + s2) / 2)  # A / s = 1 / (2 + √2) = 1 - 1/√2
    np.testing.assert_allclose(inradii(p, t), [1 - 1 / s2], rtol=1e-14)
    assert r == pytest.approx(1 - 1 / s2, rel=1e-14)
    np.testing.assert_allclose(circumradii(p, t), [s2 / 2], rtol=1e-15)  # half hypotenuse
    np.testing.assert_allclose(angles(p, t), [[math.pi / 2, math.pi / 4, math.pi / 4]], rtol=1e-15)
    np.testing.assert_allclose(inverse_shape_quality(p, t), [4 / (2 * math.sqrt(3))], rtol=1e-15)
    np.testing.assert_allclose(aspect_ratios(p, t), [2 * (s2 - 1)], rtol=1e-14)
    q = quality_summary(p, t)
    assert q.min_aspect_ratio == pytest.approx(2 * (s2 - 1), rel=1e-14)
    assert q.mean_shape_quality == pytest.approx(2 / math.sqrt(3), rel=1e-15)
    assert q.min_angle_deg == pytest.approx(45.0, rel=1e-14)
    assert q.max_angle_deg == pytest.approx(90.0, rel=1e-14)
    assert q.min_area == q.total_area == 0.5


# -- identities and independent formulas ---------------------------------------------


def test_edge_vectors_sum_to_zero_and_match_lengths(rng):
    p, t = random_triangles(rng)
    e = edge_vectors(p, t)
    np.testing.assert_allclose(e.sum(axis=1), 0, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(e, axis=2), edge_lengths(p, t), rtol=1e-15)
    # edge l joins the two vertices other than l
    for l in range(3):
        d = p[t[:, (l + 2) % 3]] - p[t[:, (l + 1) % 3]]
        np.testing.assert_array_equal(e[:, l], d)


def test_area_matches_heron_and_shoelace(rng):
    p, t = random_triangles(rng)
    a = signed_areas(p, t)
    heron = [heron_area(p[k]) for k in t]
    np.testing.assert_allclose(a, heron, rtol=1e-9)
    x, y = p[t, 0], p[t, 1]
    shoelace = 0.5 * (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1)
    np.testing.assert_allclose(a, shoelace, rtol=1e-12, atol=1e-15)


def test_heights_times_edges_is_twice_the_area(rng):
    p, t = random_triangles(rng)
    np.testing.assert_allclose(
        heights(p, t) * edge_lengths(p, t),
        np.repeat(2 * signed_areas(p, t)[:, None], 3, axis=1),
        rtol=1e-13,
    )


def test_height_is_distance_to_the_opposite_line(rng):
    p, t = random_triangles(rng, 20)
    h = heights(p, t)
    for l in range(3):
        a, b, v = p[t[:, (l + 1) % 3]], p[t[:, (l + 2) % 3]], p[t[:, l]]
        d = b - a
        n = np.stack([-d[:, 1], d[:, 0]], 1) / np.linalg.norm(d, axis=1)[:, None]
        np.testing.assert_allclose(h[:, l], np.abs(np.einsum("kd,kd->k", v - a, n)), rtol=1e-12)


def test_angles_sum_to_pi_and_match_law_of_cosines(rng):
    p, t = random_triangles(rng)
    ang = angles(p, t)
    np.testing.assert_allclose(ang.sum(axis=1), math.pi, rtol=1e-14)
    E = edge_lengths(p, t)
    for l in range(3):
        a, b, c = E[:, l], E[:, (l + 1) % 3], E[:, (l + 2) % 3]
        np.testing.assert_allclose(
            np.cos(ang[:, l]), (b**2 + c**2 - a**2) / (2 * b * c), rtol=1e-9, atol=1e-12
        )


def test_radii_against_law_of_sines_and_tangent_lengths(rng):
    p, t = random_triangles(rng)
    E, ang = edge_lengths(p, t), angles(p, t)
    # law of sines: E_l / sin θ_l = 2R for every l
    for l in range(3):
        np.testing.assert_allclose(circumradii(p, t), E[:, l] / (2 * np.sin(ang[:, l])), rtol=1e-9)
    # inradius: r = (s - E_l) tan(θ_l / 2)
    s = E.sum(axis=1) / 2
    for l in range(3):
        np.testing.assert_allclose(inradii(p, t), (s - E[:, l]) * np.tan(ang[:, l] / 2), rtol=1e-9)


def test_circumcentre_is_equidistant(rng):
    p, t = random_triangles(rng, 20)
    R = circumradii(p, t)
    for k, tri in enumerate(t):
        a, b, c = p[tri]
        # solve |x - a|² = |x - b|² = |x - c|² as a 2×2 linear system
        M = 2 * np.array([b - a, c - a])
        rhs = np.array([b @ b - a @ a, c @ c - a @ a])
        x = np.linalg.solve(M, rhs)
        np.testing.assert_allclose(np.linalg.norm(p[tri] - x, axis=1), R[k], rtol=1e-8)


def test_shape_quality_and_aspect_ratio_bounds(rng):
    p, t = random_triangles(rng, 200)
    ipsi = inverse_shape_quality(p, t)
    ar = aspect_ratios(p, t)
    assert np.all(ipsi >= 1 - 1e-12)
    assert np.all((ar > 0) & (ar <= 1 + 1e-12))
    np.testing.assert_allclose(ar, 2 * inradii(p, t) / circumradii(p, t), rtol=1e-12)
    E = edge_lengths(p, t)
    np.testing.assert_allclose(
        ipsi, (E**2).sum(axis=1) / (4 * math.sqrt(3) * signed_areas(p, t)), rtol=1e-13
    )


# -- sign conventions ----------------------------------------------------------------


def test_clockwise_triangle_has_negative_area_and_signed_measures():
    p, t = RIGHT_ISO, ONE[:, ::-1]
    assert signed_areas(p, t)[0] == -0.5
    assert np.all(heights(p, t) < 0)
    assert inradii(p, t)[0] < 0 and circumradii(p, t)[0] < 0
    assert inverse_shape_quality(p, t)[0] == pytest.approx(-2 / math.sqrt(3))
    assert aspect_ratios(p, t)[0] == pytest.approx(-2 * (math.sqrt(2) - 1))
    # angles are unsigned
    np.testing.assert_allclose(np.sort(angles(p, t)[0]), [math.pi / 4, math.pi / 4, math.pi / 2])
    q = quality_summary(p, t)
    assert q.n_inverted == 1 and q.min_area == -0.5 and q.total_area == -0.5


def test_degenerate_triangles():
    p = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0], [0.0, 0.0]])
    collinear, coincident = [0, 1, 2], [0, 3, 2]
    t = np.array([collinear, coincident])
    assert np.all(signed_areas(p, t) == 0)
    np.testing.assert_array_equal(aspect_ratios(p, t), [0, 0])
    ang = angles(p, t)
    np.testing.assert_allclose(ang[0], [0, math.pi, 0])
    q = quality_summary(p, t)
    assert q.min_aspect_ratio == 0 and q.n_inverted == 2
    assert q.min_angle_deg == 0 and q.max_angle_deg == pytest.approx(180.0)
    assert not np.isfinite(q.mean_shape_quality)


# -- quality_summary against the per-triangle kernels --------------------------------


@pytest.mark.parametrize("flip", [0, 3])
def test_quality_summary_matches_kernels(rng, flip):
    from conftest import grid_mesh

    m = grid_mesh(6, jitter=0.4, seed=3)
    p, t = m.points, m.triangles.copy()
    t[:flip] = t[:flip, ::-1]  # some inverted triangles
    q = quality_summary(p, t)
    area, ang = signed_areas(p, t), np.degrees(angles(p, t))
    assert q.min_aspect_ratio == pytest.approx(aspect_ratios(p, t).min(), rel=1e-13)
    assert q.mean_shape_quality == pytest.approx(inverse_shape_quality(p, t).mean(), rel=1e-13)
    assert q.min_angle_deg == pytest.approx(ang.min(), rel=1e-12)
    assert q.max_angle_deg == pytest.approx(ang.max(), rel=1e-12)
    assert q.min_area == area.min()
    assert q.total_area == area.sum()
    assert q.n_inverted == flip == np.count_nonzero(area <= 0)
    d = q.as_dict()
    assert set(d) == {
        "min_aspect_ratio",
        "mean_shape_quality",
        "min_angle_deg",
        "max_angle_deg",
        "min_area",
        "total_area",
        "n_inverted",
    }
    assert isinstance(d["n_inverted"], int) and isinstance(d["min_area"], float)


def test_quality_summary_on_thin_triangles_is_accurate():
    # tiny and near-π angles: the summary must agree with the arctan2 kernel
    eps = 1e-7
    p = np.array([[0, 0], [1, 0], [0.5, eps], [2, 0], [3, 0], [2.5, -eps]], float)
    t = np.array([[0, 1, 2], [3, 5, 4]])
    q = quality_summary(p, t)
    ang = np.degrees(angles(p, t))
    assert q.min_angle_deg == pytest.approx(ang.min(), rel=1e-8)
    assert q.max_angle_deg == pytest.approx(ang.max(), rel=1e-14)
    assert q.min_angle_deg == pytest.approx(np.degrees(np.arctan(2 * eps)), rel=1e-8)


def test_quality_summary_accepts_plain_lists():
    q = quality_summary(EQUILATERAL.tolist(), [[0, 1, 2]])
    assert q.min_aspect_ratio == pytest.approx(1.0)


# -- invariances (property tests) ------------------------------------------------------

coord = st.floats(-10, 10, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(
    pts=st.lists(st.tuples(coord, coord), min_size=3, max_size=3),
    angle=st.floats(0, 2 * math.pi),
    scale=st.floats(1e-3, 1e3),
    shift=st.tuples(coord, coord),
)
def test_quality_invariant_under_rigid_motion_and_scaling(pts, angle, scale, shift):
    p = np.array(pts, dtype=float)
    a = signed_areas(p, ONE)[0]
    E = edge_lengths(p, ONE)[0]
    # only reasonably shaped triangles: the measures are ill-conditioned near degeneracy
    if not abs(a) > 1e-3 * max(E.max(), 1e-300) ** 2:
        return
    # and triangles not tiny against their coordinates: rounding the moved coordinates
    # perturbs the shape by ε·(scale·|p| + |shift|)/(scale·E) (found by hypothesis: an
    # 8e-14-wide triangle shifted by 1)
    if not scale * E.max() > 1e-5 * (scale * np.abs(p).max() + max(abs(shift[0]), abs(shift[1]))):
        return
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    q = scale * p @ rot.T + np.array(shift)
    for f in (inverse_shape_quality, aspect_ratios):
        assert f(q, ONE)[0] == pytest.approx(f(p, ONE)[0], rel=1e-7)
    np.testing.assert_allclose(angles(q, ONE), angles(p, ONE), rtol=1e-7, atol=1e-9)
    assert signed_areas(q, ONE)[0] == pytest.approx(scale**2 * a, rel=1e-7)
    # a reflection flips the sign of the area and keeps |1/ψ|
    r = p * np.array([-1.0, 1.0])
    assert inverse_shape_quality(r, ONE)[0] == pytest.approx(-inverse_shape_quality(p, ONE)[0])


@settings(max_examples=40, deadline=None)
@given(perm=st.permutations([0, 1, 2]))
def test_measures_follow_vertex_permutation(perm):
    p = np.array([[0.1, 0.2], [1.3, -0.4], [0.7, 1.1]])
    t = np.array([perm])
    even = perm in ([0, 1, 2], [1, 2, 0], [2, 0, 1])
    sign = 1 if even else -1
    assert signed_areas(p, t)[0] == pytest.approx(sign * signed_areas(p, ONE)[0])
    # angle at local vertex l is the angle at point perm[l]
    np.testing.assert_allclose(angles(p, t)[0], angles(p, ONE)[0][perm], rtol=1e-14)
    np.testing.assert_allclose(edge_lengths(p, t)[0], edge_lengths(p, ONE)[0][perm], rtol=1e-14)


def test_min_signed_areas_on_segment_is_exact(rng):
    from meshopt_toolkit.kernels.triangles import min_signed_areas_on_segment

    tri = np.array([[0, 1, 2]])
    P0 = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    # a half turn about the centroid: positive at both ends, zero area halfway
    c = P0.mean(axis=0)
    P1 = 2 * c - P0
    assert signed_areas(P1, tri)[0] == pytest.approx(0.5)
    assert min_signed_areas_on_segment(P0, P1, tri)[0] == pytest.approx(0.0, abs=1e-15)
    # random segments against dense sampling (which can only see a larger minimum)
    pts0 = rng.normal(size=(40, 2))
    pts1 = rng.normal(size=(40, 2))
    tris = rng.integers(0, 40, size=(200, 3))
    exact = min_signed_areas_on_segment(pts0, pts1, tris)
    s = np.linspace(0, 1, 4001)[:, None, None]
    sampled = np.min([signed_areas(p, tris) for p in (1 - s) * pts0 + s * pts1], axis=0)
    assert np.all(exact <= sampled + 1e-12)
    assert np.allclose(exact, sampled, atol=1e-6)


def test_doubled_areas_of_frames_equal_signed_areas_frame_by_frame():
    from conftest import grid_mesh
    from meshopt_toolkit.kernels.triangles import doubled_areas_of_frames

    rng = np.random.default_rng(7)
    mesh = grid_mesh(6, jitter=0.3, seed=2)
    frames = mesh.points + 0.05 * rng.standard_normal((4, *mesh.points.shape))
    got = doubled_areas_of_frames(frames, np.ascontiguousarray(mesh.triangles.T))
    want = np.stack([2 * signed_areas(f, mesh.triangles) for f in frames])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


_LEADING = st.one_of(st.just(0.0), st.floats(0.01, 10), st.floats(-10, -0.01))


@settings(deadline=None, max_examples=200)
@given(st.lists(st.tuples(_LEADING, st.floats(-10, 10).filter(lambda v: abs(v) > 1e-6 or v == 0),
                          st.floats(0.01, 10)),
                min_size=1, max_size=20))
def test_first_positive_roots_agree_with_the_textbook_formula(coefficients):
    from meshopt_toolkit.kernels.triangles import first_positive_roots

    a, b, c = (np.array(v) for v in zip(*coefficients))
    got = first_positive_roots(a, b, c)
    for ak, bk, ck, g in zip(a, b, c, got):
        if ak == 0:
            roots = [-ck / bk] if bk != 0 else []
        else:
            disc = bk * bk - 4 * ak * ck
            roots = [] if disc < 0 else [(-bk + s * math.sqrt(disc)) / (2 * ak) for s in (1, -1)]
        positive = [r for r in roots if r > 0]
        expected = min(positive) if positive else math.inf
        assert g == pytest.approx(expected, rel=1e-9), (ak, bk, ck)
