"""Tests of the vertex–edge distance D, its regularization D^μ and the pair search."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import grid_mesh

from meshopt_toolkit.kernels.distance import (
    DEFAULT_MU,
    boundary_pairs,
    g_mu,
    h_mu,
    iter_boundary_pairs,
    regularized_distance,
    regularized_distance_value,
    segment_distance,
    vertex_edge_distance,
)
from meshopt_toolkit.errors import NotAdmissibleError
from meshopt_toolkit.diagnostics import check_gradient, check_hvp

MU = 2.0


# ----------------------------------------------------------------- independent references


def rotation(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def brute_force_D(p, a, b, n=20001):
    """min over a dense sampling of the segment of the 1-norm in the edge frame."""
    theta = np.arctan2(*(b - a)[::-1])
    R = rotation(-theta)  # rotates the edge onto the +x axis
    s = np.linspace(0.0, 1.0, n)[:, None]
    diff = (p - (a + s * (b - a))) @ R.T
    return np.abs(diff).sum(1).min()


def g_spec(d, mu):
    """(B.4), one side, written exactly as in SPEC §2 (powers of μ, not u = μd)."""
    d = np.asarray(d, float)
    lin = d - 1 / (4 * mu)
    poly = 32 * mu**5 * d**6 - 48 * mu**4 * d**5 + 20 * mu**3 * d**4
    return np.where(d <= 0, 0.0, np.where(d >= 1 / (2 * mu), lin, poly))


def h_spec(x, mu):
    """(B.5) written exactly as in SPEC §2."""
    a = np.abs(np.asarray(x, float))
    poly = (
        40 * mu**5 * a**6 - 64 * mu**4 * a**5 + 32 * mu**3 * a**4 - 4 * mu**2 * a**3 + mu / 2 * a**2
    )
    return np.where(a >= 1 / (2 * mu), a - 1 / (4 * mu), poly)


def config(xt, yt, L=1.3, theta=0.7, shift=(0.3, -0.2)):
    """Points (3, 2) of one pair with prescribed edge-frame coordinates (x̃, ỹ)."""
    R = rotation(theta)
    a = np.array(shift, float)
    b = a + R @ [L, 0.0]
    p = a + R @ [xt, yt]
    return np.array([p, a, b])


def assemble(pairs, per_pair, n):
    out = np.zeros((n, 2))
    np.add.at(out, pairs, per_pair)
    return out


# region table: x̃ offsets (relative to an edge of length L=1.3, μ=2: zone width 0.25)
X_ZONES = {
    "inside": 0.6,
    "left-poly": -0.12,
    "left-linear": -0.6,
    "right-poly": 1.3 + 0.12,
    "right-linear": 1.3 + 0.6,
    "left-breakpoint": -0.25,
}
Y_ZONES = {
    "y-poly+": 0.1,
    "y-poly-": -0.15,
    "y-linear+": 0.7,
    "y-linear-": -0.45,
    "near-contact": 1e-4,
    "y-breakpoint": 0.25,
}


BREAKPOINT_ZONES = {"left-breakpoint", "near-contact", "y-breakpoint"}


def all_configs(breakpoints: bool = True):
    """One pair per (x-zone, y-zone) combination, each with its own three vertices.

    ``breakpoints=False`` keeps only configurations strictly inside their zones: there the
    Taylor remainders of a weighted sum are a smooth ε³ law, whereas near x̃ = 0 / ỹ = 0 the
    sign of the third derivative changes within the ε sweep and weighted sums can cancel.
    """
    xs = [v for k, v in X_ZONES.items() if breakpoints or k not in BREAKPOINT_ZONES]
    ys = [v for k, v in Y_ZONES.items() if breakpoints or k not in BREAKPOINT_ZONES]
    blocks = [
        config(x, y, theta=0.3 + 0.4 * k) for k, (x, y) in enumerate(itertools.product(xs, ys))
    ]
    points = np.concatenate(blocks)
    pairs = np.arange(points.shape[0]).reshape(-1, 3)
    return points, pairs


# ----------------------------------------------------------------- exact D


def test_D_matches_brute_force(rng):
    pts, pairs = [], []
    for k in range(60):
        a, b = rng.uniform(-1, 1, (2, 2))
        centre = 0.5 * (a + b)
        p = centre + rng.uniform(-2.5, 2.5, 2)  # left/right/above/below the edge
        pts.extend([p, a, b])
        pairs.append([3 * k, 3 * k + 1, 3 * k + 2])
    pts, pairs = np.array(pts), np.array(pairs)
    D = vertex_edge_distance(pts, pairs)
    ref = np.array([brute_force_D(*pts[row]) for row in pairs])
    L = np.linalg.norm(pts[pairs[:, 2]] - pts[pairs[:, 1]], axis=1)
    assert np.all(np.abs(D - ref) <= L / 20000 + 1e-12)
    # the 4 sides are all exercised
    x_, y_ = _frame_coords(pts, pairs)
    assert (x_ < 0).any() and (x_ > L).any() and ((x_ > 0) & (x_ < L)).any()
    assert (y_ > 0).any() and (y_ < 0).any()


def _frame_coords(pts, pairs):
    p, a, b = (pts[pairs[:, k]] for k in range(3))
    t = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    n = np.stack([-t[:, 1], t[:, 0]], 1)
    return ((p - a) * t).sum(1), ((p - a) * n).sum(1)


def test_D_closed_forms():
    pts = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 3.0], [-1.0, -2.0], [4.0, 1.0]])
    pairs = np.array([[2, 0, 1], [3, 0, 1], [4, 0, 1], [2, 1, 0]])
    np.testing.assert_allclose(vertex_edge_distance(pts, pairs), [3.0, 3.0, 3.0, 3.0])
    np.testing.assert_allclose(segment_distance(pts, pairs), [3.0, np.sqrt(5), np.sqrt(5), 3.0])


def test_segment_distance_below_D(rng):
    pts = rng.uniform(-1, 1, (40, 2))
    pairs = np.array([rng.choice(40, 3, replace=False) for _ in range(300)])
    assert np.all(segment_distance(pts, pairs) <= vertex_edge_distance(pts, pairs) + 1e-15)


# ----------------------------------------------------------------- 1D pieces


def test_pieces_match_spec_formulas(rng):
    for mu in (1.0, MU, 13.0):
        d = rng.uniform(-1, 2, 2000) / mu
        np.testing.assert_allclose(g_mu(d, mu), g_spec(d, mu), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(h_mu(d, mu), h_spec(d, mu), rtol=1e-12, atol=1e-14)


def test_thesis_right_branch_sign_is_a_typo():
    """(B.4) prints +48μ⁴(x−z)⁵ on the right branch: discontinuous at 1/(2μ), so the SPEC's
    −48 (mirror image of the left branch) is the correct one."""
    mu = MU
    d = 1 / (2 * mu)
    thesis = 32 * mu**5 * d**6 + 48 * mu**4 * d**5 + 20 * mu**3 * d**4
    assert abs(thesis - (d - 1 / (4 * mu))) > 1 / mu
    assert abs(g_spec(d - 1e-15, mu) - (d - 1 / (4 * mu))) < 1e-12


def _fd(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


@pytest.mark.parametrize("mu", [1.0, MU, 7.5])
def test_pieces_derivatives_consistent(mu, rng):
    """nderiv=k equals the central difference of nderiv=k−1 away from breakpoints."""
    x = rng.uniform(-1.5, 1.5, 400) / mu
    x = x[np.min(np.abs(np.abs(x)[:, None] - [0.0, 0.5 / mu]), 1) > 1e-3 / mu]
    h = 1e-6 / mu
    for fun in (g_mu, h_mu):
        for k in (1, 2, 3):
            fd = _fd(lambda y, fun=fun, k=k: fun(y, mu, k - 1), x, h)
            np.testing.assert_allclose(fun(x, mu, k), fd, rtol=1e-6, atol=1e-6 * mu ** (k - 1))


@pytest.mark.parametrize("mu", [1.0, MU, 7.5])
def test_pieces_continuity_at_breakpoints(mu):
    """One-sided limits of value, first and second derivative agree at every breakpoint."""
    eps = 1e-9 / mu
    for fun, bps in ((g_mu, [0.0, 0.5 / mu]), (h_mu, [-0.5 / mu, 0.0, 0.5 / mu])):
        for bp in bps:
            for k in range(3):
                lo, hi = fun(bp - eps, mu, k), fun(bp + eps, mu, k)
                scale = mu ** (k - 1)
                assert abs(hi - lo) < 1e-6 * scale, (fun.__name__, bp, k, lo, hi)
    # g_μ is even C3 at both breakpoints; h_μ at ±1/(2μ)
    for bp in (0.0, 0.5 / mu):
        assert abs(g_mu(bp + eps, mu, 3) - g_mu(bp - eps, mu, 3)) < 1e-5 * mu**2
    for bp in (-0.5 / mu, 0.5 / mu):
        assert abs(h_mu(bp + eps, mu, 3) - h_mu(bp - eps, mu, 3)) < 1e-5 * mu**2


@pytest.mark.parametrize("mu", [1.0, MU])
def test_h_third_derivative_jumps_at_zero(mu):
    """Documented: h_μ is C2, not C3, at 0 (h''' = ∓24μ² from the right/left).
    Measured by one-sided differences of h'' (independent of the nderiv=3 branch)."""
    e = 1e-6 / mu
    right = (h_mu(2 * e, mu, 2) - h_mu(e, mu, 2)) / e
    left = (h_mu(-e, mu, 2) - h_mu(-2 * e, mu, 2)) / e
    np.testing.assert_allclose([right, left], [-24 * mu**2, 24 * mu**2], rtol=1e-4)
    assert h_mu(e, mu, 3) < 0 < h_mu(-e, mu, 3)


def test_pieces_convex_and_bounded(rng):
    x = rng.uniform(-3, 3, 5000)
    for mu in (1.0, MU, 50.0):
        assert np.all(g_mu(x, mu, 2) >= 0) and np.all(h_mu(x, mu, 2) >= 0)
        g = np.maximum(x, 0)
        assert np.all((0 <= g_mu(x, mu)) & (g_mu(x, mu) <= g))
        assert np.all((0 <= h_mu(x, mu)) & (h_mu(x, mu) <= np.abs(x)))


def test_bad_mu():
    with pytest.raises(ValueError):
        g_mu(1.0, 0.0)
    with pytest.raises(ValueError):
        regularized_distance_value(np.eye(3, 2), np.array([[2, 0, 1]]), mu=-1.0)


# ----------------------------------------------------------------- D^μ values


def test_regularized_matches_spec_reference(rng):
    pts = rng.uniform(-1, 1, (50, 2))
    pairs = np.array([rng.choice(50, 3, replace=False) for _ in range(500)])
    xt, yt = _frame_coords(pts, pairs)
    L = np.linalg.norm(pts[pairs[:, 2]] - pts[pairs[:, 1]], axis=1)
    for mu in (1.0, MU, 9.0):
        ref = g_spec(-xt, mu) + g_spec(xt - L, mu) + h_spec(yt, mu)
        np.testing.assert_allclose(
            regularized_distance_value(pts, pairs, mu), ref, rtol=1e-11, atol=1e-14
        )
        np.testing.assert_allclose(
            regularized_distance(pts, pairs, mu).value, ref, rtol=1e-11, atol=1e-14
        )


def test_default_mu_is_thesis_value():
    assert DEFAULT_MU == 1.0


def test_bounds_and_convergence(rng):
    pts = rng.uniform(-1, 1, (40, 2))
    pairs = np.array([rng.choice(40, 3, replace=False) for _ in range(400)])
    D = vertex_edge_distance(pts, pairs)
    for mu in (1.0, 3.0, 30.0, 300.0):
        Dm = regularized_distance_value(pts, pairs, mu)
        assert np.all(Dm >= 0) and np.all(Dm <= D + 1e-15)
        assert np.max(D - Dm) <= 0.5 / mu + 1e-15
    # rate ~ 1/μ: fit the slope of log(D − D^μ) against log μ for a point off both axes
    pts1 = config(-0.4, 0.3)
    mus = np.geomspace(10, 1e4, 8)
    gap = [
        vertex_edge_distance(pts1, [[0, 1, 2]])[0]
        - regularized_distance_value(pts1, [[0, 1, 2]], m)[0]
        for m in mus
    ]
    slope = np.polyfit(np.log(mus), np.log(gap), 1)[0]
    assert abs(slope + 1) < 0.02


def test_rigid_motion_invariance(rng):
    pts = rng.uniform(-1, 1, (30, 2))
    pairs = np.array([rng.choice(30, 3, replace=False) for _ in range(200)])
    V = rng.standard_normal(pts.shape)
    R = rotation(1.234)
    moved = pts @ R.T + [3.0, -7.0]
    np.testing.assert_allclose(
        vertex_edge_distance(moved, pairs), vertex_edge_distance(pts, pairs), rtol=1e-12, atol=1e-13
    )
    e0 = regularized_distance(pts, pairs, MU, direction=V)
    e1 = regularized_distance(moved, pairs, MU, direction=V @ R.T)
    np.testing.assert_allclose(e1.value, e0.value, rtol=1e-11, atol=1e-13)
    # derivatives are equivariant: they rotate with the configuration
    np.testing.assert_allclose(e1.gradient, e0.gradient @ R.T, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(e1.hess_dir, e0.hess_dir @ R.T, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(e1.curvature, e0.curvature, rtol=1e-9, atol=1e-9)


# ----------------------------------------------------------------- derivatives


def _objective(pairs, n, mu, weights):
    def f(x):
        return float(weights @ regularized_distance_value(x.reshape(n, 2), pairs, mu))

    def grad(x):
        ev = regularized_distance(x.reshape(n, 2), pairs, mu)
        return assemble(pairs, weights[:, None, None] * ev.gradient, n).ravel()

    def hvp(x, v):
        ev = regularized_distance(x.reshape(n, 2), pairs, mu, direction=v.reshape(n, 2))
        return assemble(pairs, weights[:, None, None] * ev.hess_dir, n).ravel()

    return f, grad, hvp


@pytest.mark.parametrize("xzone", list(X_ZONES))
@pytest.mark.parametrize("yzone", list(Y_ZONES))
def test_taylor_every_region(xzone, yzone):
    pts = config(X_ZONES[xzone], Y_ZONES[yzone])
    pairs = np.array([[0, 1, 2]])
    f, grad, hvp = _objective(pairs, 3, MU, np.ones(1))
    x = pts.ravel()
    r1 = check_gradient(f, grad, x, rng=3, eps0=1e-2)
    assert r1.passed and r1.order > 1.7, r1
    r2 = check_hvp(f, grad, hvp, x, rng=3, eps0=1e-2)
    assert r2.passed and r2.order > 2.7, r2


@pytest.mark.parametrize("weighted", [False, True])
def test_taylor_sum_over_pairs(weighted, rng):
    pts, pairs = all_configs(breakpoints=False)
    w = rng.uniform(0.2, 3.0, len(pairs)) if weighted else np.ones(len(pairs))
    f, grad, hvp = _objective(pairs, len(pts), MU, w)
    x = pts.ravel()
    r1 = check_gradient(f, grad, x, rng=5)
    assert r1.passed and r1.order > 1.7, r1
    r2 = check_hvp(f, grad, hvp, x, rng=5)
    assert r2.passed and r2.order > 2.7, r2


def test_taylor_remainders_per_pair(rng):
    """Every pair separately (breakpoint and near-contact ones included), vectorized: the
    second-order remainder / ε³ stays bounded while ε shrinks 256-fold (a wrong Hessian
    makes it grow like 1/ε), and the first-order remainder / ε² likewise."""
    pts, pairs = all_configs()
    v = rng.standard_normal(pts.shape)
    ev = regularized_distance(pts, pairs, MU, direction=v)
    slope = (ev.gradient * v[pairs]).sum((1, 2))
    eps = 1e-2 * 0.5 ** np.arange(9)
    r1, r2 = [], []
    for e in eps:
        diff = regularized_distance_value(pts + e * v, pairs, MU) - ev.value - e * slope
        r1.append(np.abs(diff) / e**2)
        r2.append(np.abs(diff - 0.5 * e * e * ev.curvature) / e**3)
    r1, r2 = np.array(r1), np.array(r2)
    assert np.all(r1[-1] <= 4 * r1[:3].max(0) + 1e-3)
    assert np.all(r2[-1] <= 4 * r2[:3].max(0) + 1.0)
    # and the remainders really are non-trivial (the test can fail)
    assert r2[0].max() > 1.0


def test_taylor_random_mesh_pairs(rng):
    """Shared vertices between pairs (as on a real boundary), μ = 1 and a large μ."""
    m = grid_mesh(3, 0.0)
    pts = m.points + rng.uniform(-0.05, 0.05, m.points.shape)
    pairs = boundary_pairs(m.boundary_vertices, m.boundary_edges)
    for mu in (1.0, 20.0):
        f, grad, hvp = _objective(pairs, len(pts), mu, rng.uniform(0.5, 1.5, len(pairs)))
        x = pts.ravel()
        assert check_gradient(f, grad, x, rng=7).order > 1.7
        assert check_hvp(f, grad, hvp, x, rng=7).order > 2.7


def test_hessian_symmetric_and_curvature(rng):
    pts, pairs = all_configs()
    n = len(pts)
    U, V = rng.standard_normal((2, n, 2))
    eu = regularized_distance(pts, pairs, MU, direction=U)
    ev = regularized_distance(pts, pairs, MU, direction=V)
    # per pair: u_k·(H_k v_k) == v_k·(H_k u_k)
    uHv = (U[pairs] * ev.hess_dir).sum((1, 2))
    vHu = (V[pairs] * eu.hess_dir).sum((1, 2))
    np.testing.assert_allclose(uHv, vHu, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(
        ev.curvature, (V[pairs] * ev.hess_dir).sum((1, 2)), rtol=1e-10, atol=1e-10
    )
    # translation invariance: blocks of the gradient and of H·v sum to zero
    np.testing.assert_allclose(ev.gradient.sum(1), 0.0, atol=1e-12)
    np.testing.assert_allclose(ev.hess_dir.sum(1), 0.0, atol=1e-9)
    # without a direction only value and gradient are returned
    e0 = regularized_distance(pts, pairs, MU)
    assert e0.hess_dir is None and e0.curvature is None
    np.testing.assert_array_equal(e0.gradient, ev.gradient)


def test_hessian_matches_finite_difference_of_gradient(rng):
    pts, pairs = all_configs()
    V = rng.standard_normal(pts.shape)
    h = 1e-6
    gp = regularized_distance(pts + h * V, pairs, MU).gradient
    gm = regularized_distance(pts - h * V, pairs, MU).gradient
    hv = regularized_distance(pts, pairs, MU, direction=V).hess_dir
    np.testing.assert_allclose(hv, (gp - gm) / (2 * h), rtol=1e-5, atol=1e-5)


# ----------------------------------------------------------------- degenerate input


def test_degenerate_edge_raises():
    pts = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 1.0]])
    pairs = np.array([[0, 1, 2]])
    for fun in (
        vertex_edge_distance,
        segment_distance,
        regularized_distance_value,
        regularized_distance,
    ):
        with pytest.raises(NotAdmissibleError, match=r"\[1, 2\]"):
            fun(pts, pairs)


def test_coincident_point_is_finite():
    pts = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.5, 0.0]])
    pairs = np.array([[0, 1, 2], [3, 1, 2]])
    ev = regularized_distance(pts, pairs, MU, direction=np.ones((4, 2)))
    assert np.all(ev.value == 0) and np.all(vertex_edge_distance(pts, pairs) == 0)
    for arr in (ev.gradient, ev.hess_dir, ev.curvature):
        assert np.all(np.isfinite(arr))


def test_empty_pairs():
    pts = np.zeros((3, 2))
    empty = np.empty((0, 3), int)
    ev = regularized_distance(pts, empty, direction=pts)
    assert (
        ev.value.shape == (0,) and ev.gradient.shape == (0, 3, 2) and ev.hess_dir.shape == (0, 3, 2)
    )
    assert vertex_edge_distance(pts, empty).shape == (0,)


# ----------------------------------------------------------------- pair search


def _brute_segment_distance(pts, pairs):
    """Independent point–segment distance: projection parameter clamped to [0, 1]."""
    p, a, b = pts[pairs[:, 0]], pts[pairs[:, 1]], pts[pairs[:, 2]]
    s = np.clip(((p - a) * (b - a)).sum(1) / ((b - a) ** 2).sum(1), 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * (b - a)), axis=1)


def test_all_pairs_structure(grid):
    bv, be = grid.boundary_vertices, grid.boundary_edges
    P = boundary_pairs(bv, be)
    assert P.shape == (len(be) * len(bv) - 2 * len(be), 3)
    assert not np.any((P[:, 0] == P[:, 1]) | (P[:, 0] == P[:, 2]))
    assert np.isin(P[:, 0], bv).all()
    # every (edge, vertex) combination exactly once
    assert len({tuple(r) for r in P}) == len(P)
    # edge-major order
    edge_index = {tuple(e): k for k, e in enumerate(be)}
    ks = [edge_index[(r[1], r[2])] for r in P]
    assert np.all(np.diff(ks) >= 0)


@pytest.mark.parametrize("chunk", [1, 5, 17, 10**6])
def test_iter_pairs_concatenate(grid, chunk):
    bv, be = grid.boundary_vertices, grid.boundary_edges
    chunks = list(iter_boundary_pairs(bv, be, chunk=chunk))
    assert all(0 < len(c) <= chunk for c in chunks)
    np.testing.assert_array_equal(np.concatenate(chunks), boundary_pairs(bv, be))


@pytest.mark.parametrize("radius", [1e-3, 0.05, 0.2, 0.45, 5.0])
def test_radius_pairs_equal_brute_force(radius, rng):
    m = grid_mesh(7, 0.3, seed=4)
    pts = m.points + rng.uniform(-0.03, 0.03, m.points.shape)  # boundary off the axes
    bv, be = m.boundary_vertices, m.boundary_edges
    allp = boundary_pairs(bv, be)
    ref = allp[_brute_segment_distance(pts, allp) < radius]
    got = boundary_pairs(bv, be, pts, radius)
    np.testing.assert_array_equal(got, ref)
    # the radius search finds every pair with D < radius
    D = vertex_edge_distance(pts, allp)
    assert {tuple(r) for r in allp[D < radius]} <= {tuple(r) for r in got}


def test_radius_pairs_shuffled_input(rng):
    m = grid_mesh(5, 0.2, seed=1)
    bv = rng.permutation(m.boundary_vertices)
    be = m.boundary_edges[rng.permutation(len(m.boundary_edges))]
    allp = boundary_pairs(bv, be)
    ref = allp[_brute_segment_distance(m.points, allp) < 0.3]
    np.testing.assert_array_equal(boundary_pairs(bv, be, m.points, 0.3), ref)


def test_radius_edge_cases(grid):
    bv, be = grid.boundary_vertices, grid.boundary_edges
    assert boundary_pairs(bv, be, grid.points, 0.0).shape == (0, 3)
    assert boundary_pairs(bv, be, grid.points, 1e-12).shape == (0, 3)
    with pytest.raises(ValueError):
        boundary_pairs(bv, be, radius=0.1)
    assert boundary_pairs([], np.empty((0, 2), int)).shape == (0, 3)
    assert list(iter_boundary_pairs([], np.empty((0, 2), int))) == []


def test_blocking_does_not_change_results(rng, monkeypatch):
    """Results are independent of the internal block size (block edges included)."""
    import meshopt_toolkit.kernels.pairs as pairs_module

    pts = rng.uniform(-1, 1, (60, 2))
    pairs = np.array([rng.choice(60, 3, replace=False) for _ in range(1000)])
    V = rng.standard_normal(pts.shape)
    ref = regularized_distance(pts, pairs, MU, direction=V)
    ref_d = vertex_edge_distance(pts, pairs)
    monkeypatch.setattr(pairs_module, "_BLOCK", 7)
    small = regularized_distance(pts, pairs, MU, direction=V)
    for name in ("value", "gradient", "hess_dir", "curvature"):
        np.testing.assert_array_equal(getattr(small, name), getattr(ref, name))
    np.testing.assert_array_equal(vertex_edge_distance(pts, pairs), ref_d)
    np.testing.assert_array_equal(regularized_distance_value(pts, pairs, MU), ref.value)
    # a degenerate edge in a later block is still reported
    pts2 = np.vstack([pts, pts[:1]])
    bad = np.vstack([pairs, [[3, 0, 60]]])
    with pytest.raises(NotAdmissibleError):
        regularized_distance(pts2, bad, MU)


def test_radius_pairs_graded_polygon(rng):
    """A closed polygon with strongly varying edge lengths (long and tiny edges)."""
    n = 300
    theta = np.sort(rng.uniform(0, 2 * np.pi, n) ** 1.5 / (2 * np.pi) ** 0.5)
    rad = 1 + 0.1 * np.sin(7 * theta) + 0.02 * rng.standard_normal(n)
    pts = np.stack([rad * np.cos(theta), rad * np.sin(theta)], 1)
    bv = np.arange(n)
    be = np.stack([bv, np.roll(bv, -1)], 1)
    allp = boundary_pairs(bv, be)
    dist = _brute_segment_distance(pts, allp)
    for radius in (0.01, 0.1, 0.5):
        np.testing.assert_array_equal(boundary_pairs(bv, be, pts, radius), allp[dist < radius])
