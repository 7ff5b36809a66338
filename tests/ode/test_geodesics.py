"""Geodesics of the complete metric: equation, invariants, integrators (SPEC §5)."""

from __future__ import annotations

import itertools
import warnings
from fractions import Fraction

import numpy as np
import pytest
from conftest import grid_mesh, square5
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from meshopt_toolkit.errors import IntegrationError, NotAdmissibleError
from meshopt_toolkit.riemannian.geodesics import (
    GeodesicWarning,
    exp_map,
    geodesic,
    geodesic_acceleration,
)
from meshopt_toolkit.kernels.triangles import signed_areas
from meshopt_toolkit.ode import DOPRI5_TABLEAU, dopri5
from meshopt_toolkit.riemannian.field import GeodesicField
from meshopt_toolkit.mesh import PlanarMesh
from meshopt_toolkit.riemannian.metrics import CompleteMetric, ElasticityMetric, EuclideanMetric
from meshopt_toolkit.penalties import HeightPenalty, QualityPenalty


def squeeze_velocity() -> np.ndarray:
    """Square5: the two bottom corners move inwards and up; straight lines make triangle
    (0, 1, 4) collinear at t = 0.8 (our reading of thesis fig. 5.1/5.25)."""
    V = np.zeros((5, 2))
    V[0] = [0.5, 1.25]
    V[1] = [-0.5, 1.25]
    return V


def min_area(points, mesh) -> float:
    return float(signed_areas(points, mesh.triangles).min())


# -- the equation ---------------------------------------------------------------------


def test_dopri5_tableau_satisfies_order_conditions():
    c, a, b, bh = (DOPRI5_TABLEAU[k] for k in ("c", "a", "b", "b_hat"))
    A = np.zeros((7, 7))
    for i, row in enumerate(a):
        A[i, : len(row)] = row
    assert np.allclose(A.sum(1), c)
    for w, order in ((b, 5), (bh, 4)):
        assert np.isclose(w.sum(), 1)
        for q in range(1, order):  # bushy trees: Σ b c^q = 1/(q+1)
            assert np.isclose(w @ c**q, 1 / (q + 1))
        assert np.isclose(w @ A @ c, 1 / 6)
        if order >= 4:
            assert np.isclose(w @ A @ c**2, 1 / 12)
            assert np.isclose(w @ (c * (A @ c)), 1 / 8)
            assert np.isclose(w @ A @ A @ c, 1 / 24)
    # the 5th-order weights are not the 4th-order ones (an error estimate exists)
    assert abs(Fraction(float(b @ c**4)) - Fraction(1, 5)) < 1e-12
    assert not np.isclose(bh @ c**4, 1 / 5)


def test_acceleration_solves_euler_lagrange_by_finite_differences(rng):
    """d/dt (g V) = ∂_Q ½ Vᵀ g(Q) V with g = I + ∇f∇fᵀ, all derivatives by central
    differences of the gradient only (independent of the closed form)."""
    mesh = square5()
    pen = HeightPenalty(mesh, alpha=(1.0, 0.0, 1.0))
    Q = mesh.points + 0.05 * rng.standard_normal((5, 2))
    V = rng.standard_normal((5, 2))
    A = geodesic_acceleration(CompleteMetric(pen), Q, V)

    def g_times(q, w):
        gr = pen.gradient(q)
        return w + gr * np.vdot(gr, w)

    h = 1e-5
    # d/dt (g(Q(t)) V(t)) = g A + (d/dε g(Q + εV)) V
    lhs = g_times(Q, A) + (g_times(Q + h * V, V) - g_times(Q - h * V, V)) / (2 * h)
    rhs = np.zeros_like(Q)
    for i in range(5):
        for d in range(2):
            E = np.zeros_like(Q)
            E[i, d] = h
            rhs[i, d] = (0.5 * np.vdot(V, g_times(Q + E, V)) - 0.5 * np.vdot(V, g_times(Q - E, V))) / (2 * h)
    assert np.allclose(lhs, rhs, rtol=1e-6, atol=1e-6 * np.abs(rhs).max())


def test_translation_is_exact_when_alpha3_is_zero():
    """Prop. 5.2.12: f1 with α3 = 0 is translation invariant, so translations are geodesics."""
    from meshopt_toolkit import data_path, load

    mesh = load(data_path("square_crossed.msh")).as_planar()
    pen = HeightPenalty(mesh, alpha=(1.0, 0.0, 0.0))
    V = np.tile([0.7, -0.3], (mesh.n_vertices, 1))
    res = geodesic(pen, mesh.points, V, 3.0, times=[1.0, 3.0])
    assert np.allclose(res.points[1], mesh.points + 3 * V, atol=1e-12)
    assert np.allclose(res.velocities[1], V, atol=1e-12)


# -- invariants and admissibility ------------------------------------------------------


@pytest.mark.parametrize("penalty", ["f1", "f2"])
def test_energy_conserved_and_f_growth_bounded(penalty, rng):
    from meshopt_toolkit import data_path, load

    mesh = load(data_path("disc_25.msh")).as_planar()
    if penalty == "f1":
        pen = HeightPenalty(mesh, alpha=(0.5, 0.0, 0.5))
    else:
        pen = QualityPenalty(mesh, beta=(10, 1, 0, 0.001 * mesh.n_vertices))
    V = 0.5 * rng.standard_normal(mesh.points.shape)
    times = np.linspace(0, 2, 9)
    with warnings.catch_warnings():
        warnings.simplefilter("error", GeodesicWarning)
        res = geodesic(pen, mesh.points, V, 2.0, times=times, dense=False)
    e0 = res.energy[0]
    assert np.allclose(res.energy, e0, rtol=1e-3)
    assert res.max_energy_drift < 1e-3
    tight = geodesic(pen, mesh.points, V, 2.0, times=times, rtol=1e-9, atol=1e-9, dense=False)
    assert np.allclose(tight.energy, e0, rtol=1e-6)

    f = np.array([pen.value(p) for p in res.points])
    assert np.allclose(f, res.penalty)
    assert np.all(np.abs(f - f[0]) <= np.sqrt(e0) * times * (1 + 1e-3) + 1e-12)
    assert all(min_area(p, mesh) > 0 for p in res.points)
    # dense output: interpolated positions agree with landed ones, f-bound holds there too
    dense = geodesic(pen, mesh.points, V, 2.0, times=times)
    assert dense.n_steps < res.n_steps
    assert np.abs(dense.points - res.points).max() < 1e-5 * np.abs(V).max()
    assert np.all(np.abs(dense.penalty - f[0]) <= np.sqrt(e0) * times * (1 + 1e-3) + 1e-12)


def test_complete_metric_stays_admissible_for_long_times():
    mesh = square5()
    V = squeeze_velocity()
    euclid = geodesic(EuclideanMetric(), mesh.points, V, 1.0, times=[0.7, 0.8, 0.9])
    assert min_area(euclid.points[0], mesh) > 0
    assert min_area(euclid.points[1], mesh) == pytest.approx(0, abs=1e-12)
    assert min_area(euclid.points[2], mesh) < 0
    pen = HeightPenalty(mesh, alpha=(1.0, 0.0, 1.0))
    times = np.linspace(0, 50, 51)
    res = geodesic(CompleteMetric(pen), mesh.points, V, 50.0, times=times, on_violation="raise")
    areas = np.array([min_area(p, mesh) for p in res.points])
    assert res.admissible.all() and np.all(areas > 0)
    e0 = res.energy[0]
    assert np.all(np.abs(res.penalty - res.penalty[0]) <= np.sqrt(e0) * times * (1 + 1e-4) + 1e-10)


@settings(max_examples=8, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(
    jitter=st.floats(0.0, 0.6),
    seed=st.integers(0, 10_000),
    speed=st.floats(0.5, 2.0),
    use_f2=st.booleans(),
)
def test_random_geodesics_never_invert(jitter, seed, speed, use_f2):
    """Random small meshes and velocities: a result is always admissible. Without the
    boundary-pair term the metric cannot stop the boundary from touching itself; then
    (and only then) an IntegrationError saying so is the correct outcome."""
    mesh = grid_mesh(2, jitter=jitter, seed=seed)
    r = np.random.default_rng(seed)
    V = speed * r.standard_normal(mesh.points.shape)
    if use_f2:
        pen = QualityPenalty(mesh, beta=(1.0, 0.1, 0.0, 0.1 * mesh.n_vertices))
    else:
        pen = HeightPenalty(mesh, alpha=(0.1, 0.0, 0.5))
    try:
        res = geodesic(pen, mesh.points, V, 2.0, times=[0.5, 1.0, 2.0], rtol=1e-5, atol=1e-5,
                       on_violation="ignore")
    except IntegrationError as exc:
        assert "boundary self-intersects" in str(exc)
        return
    for p in res.points:
        assert min_area(p, mesh) > 0
    assert res.max_energy_drift < 1e-2


def test_rejects_steps_that_leave_the_manifold():
    """A huge first step inverts a triangle: it is rejected and retried, never returned."""
    mesh = square5()
    pen = HeightPenalty(mesh, alpha=(1.0, 0.0, 1.0))
    fld = GeodesicField(pen, mesh.triangles)
    out = dopri5(fld, mesh.points, squeeze_velocity(), np.array([2.0]), rtol=1e-6, atol=1e-6, h0=2.0)
    assert out.n_left_manifold >= 1
    assert min_area(out.points[-1], mesh) > 0


# -- integrators agree; orders; rescaling ----------------------------------------------


def _mild_case():
    mesh = square5()
    pen = HeightPenalty(mesh, alpha=(0.5, 0.0, 0.5))
    V = np.zeros((5, 2))
    V[4] = [0.4, 0.3]
    V[0] = [0.2, 0.3]
    return mesh, pen, V


def test_fast_integrator_agrees_with_scipy_dop853_and_stormer_verlet():
    mesh, pen, V = _mild_case()
    fast = geodesic(pen, mesh.points, V, 1.0)
    tight = geodesic(pen, mesh.points, V, 1.0, method="scipy", rtol=1e-12, atol=1e-12)
    sv = geodesic(pen, mesh.points, V, 1.0, method="stormer-verlet", steps=128)
    dp5 = geodesic(pen, mesh.points, V, 1.0, method="dopri5")
    assert fast.method == "dop853" and sv.method == "stormer-verlet"
    assert np.abs(fast.final - tight.final).max() < 1e-6
    assert np.abs(dp5.final - tight.final).max() < 1e-6
    assert np.abs(sv.final - tight.final).max() < 1e-4
    assert fast.n_evaluations < sv.n_evaluations / 10


def test_stormer_verlet_is_second_order():
    mesh, pen, V = _mild_case()
    ref = geodesic(pen, mesh.points, V, 1.0, rtol=1e-12, atol=1e-12).final
    steps = np.array([8, 16, 32, 64])
    errs = [np.abs(geodesic(pen, mesh.points, V, 1.0, method="stormer-verlet", steps=int(n)).final
                   - ref).max() for n in steps]
    slope = -np.polyfit(np.log(steps), np.log(errs), 1)[0]
    assert abs(slope - 2) < 0.15, (errs, slope)


@pytest.mark.parametrize("method", ["dopri5", "dop853"])
def test_global_error_decreases_with_tolerance(method):
    mesh, pen, V = _mild_case()
    ref = geodesic(pen, mesh.points, V, 1.0, method="scipy", rtol=1e-13, atol=1e-13).final
    errs = [np.abs(geodesic(pen, mesh.points, V, 1.0, method=method, rtol=tol, atol=tol).final
                   - ref).max() for tol in (1e-4, 1e-6, 1e-8, 1e-10)]
    assert all(e1 > e2 for e1, e2 in itertools.pairwise(errs)), errs
    assert errs[-1] < 1e-9


def test_stormer_verlet_asks_for_more_steps():
    mesh = square5()
    pen = HeightPenalty(mesh, alpha=(1.0, 0.0, 1.0))
    with pytest.raises(IntegrationError, match="use more steps"):
        geodesic(pen, mesh.points, 3 * squeeze_velocity(), 2.0, method="stormer-verlet", steps=4)


def test_rescaling_lemma(rng):
    from meshopt_toolkit import data_path, load

    mesh = load(data_path("disc_25.msh")).as_planar()
    metric = CompleteMetric(HeightPenalty(mesh, alpha=(0.5, 0.0, 0.5)))
    V = 0.5 * rng.standard_normal(mesh.points.shape)
    taus = [1.0, 0.5, 0.25, 0.125]
    one = geodesic(metric, mesh.points, V, 1.0, times=taus)
    for tau, p in zip(taus, one.points):
        assert np.abs(metric.exp(mesh.points, tau * V) - p).max() < 1e-6
        assert np.abs(exp_map(metric, mesh.points, V, time=tau) - p).max() < 1e-6


# -- API details ------------------------------------------------------------------------


def test_euclidean_exp_and_output_order_and_negative_time():
    mesh, pen, V = _mild_case()
    Q = mesh.points
    assert np.array_equal(exp_map(EuclideanMetric(), Q, V, 2.0), Q + 2 * V)
    assert np.array_equal(exp_map(None, Q, V, 2.0), Q + 2 * V)
    res = geodesic(pen, Q, V, 1.0, times=[1.0, 0.0, 0.5])
    assert np.array_equal(res.points[1], Q) and np.array_equal(res.velocities[1], V)
    mid = geodesic(pen, Q, V, 0.5).final
    assert np.abs(res.points[2] - mid).max() < 2e-6  # both within rtol = 1e-6 of γ(0.5)
    assert np.array_equal(res.at(0.5), res.points[2])
    back = geodesic(pen, Q, V, -0.5)
    assert np.abs(back.final - geodesic(pen, Q, -V, 0.5).final).max() < 1e-12
    still = geodesic(pen, Q, np.zeros_like(V), 3.0)
    assert np.array_equal(still.final, Q) and still.n_steps == 0


def test_refusals():
    mesh, pen, V = _mild_case()
    with pytest.raises(IntegrationError, match="not implemented"):
        exp_map(ElasticityMetric(mesh), mesh.points, V)
    with pytest.raises(IntegrationError, match="method"):
        geodesic(pen, mesh.points, V, method="euler")
    with pytest.raises(IntegrationError, match="shape"):
        geodesic(pen, mesh.points, V[:3])
    with pytest.raises(IntegrationError, match="times"):
        geodesic(pen, mesh.points, V, 1.0, times=[2.0])
    bad = mesh.points.copy()
    bad[4] = [5.0, 5.0]
    with pytest.raises(IntegrationError, match="not admissible"):
        geodesic(pen, bad, V)


def test_invariant_violation_warns_or_raises():
    mesh, pen, V = _mild_case()
    with pytest.warns(GeodesicWarning, match="energy"):
        res = geodesic(pen, mesh.points, V, 1.0, rtol=1e-3, atol=1e-3, energy_tol=1e-15)
    assert res.warnings
    with pytest.raises(IntegrationError, match="energy"):
        geodesic(pen, mesh.points, V, 1.0, rtol=1e-3, atol=1e-3, energy_tol=1e-15,
                 on_violation="raise")


def test_hermite_interpolant_is_exact_for_quintics(rng):
    from meshopt_toolkit.ode import _hermite

    c = rng.standard_normal((6, 3, 2))  # q(t) = Σ c_k t^k, per coordinate

    def q(t):
        return sum(c[k] * t**k for k in range(6))

    def dq(t):
        return sum(k * c[k] * t ** (k - 1) for k in range(1, 6))

    def ddq(t):
        return sum(k * (k - 1) * c[k] * t ** (k - 2) for k in range(2, 6))

    t0, t1 = 0.3, 1.1
    for t in (0.3, 0.5, 0.77, 1.1):
        qi, vi = _hermite(q(t0), dq(t0), ddq(t0), q(t1), dq(t1), ddq(t1), t0, t1, t)
        assert np.allclose(qi, q(t), atol=1e-12) and np.allclose(vi, dq(t), atol=1e-11)


def test_options_object_equals_keyword_settings_and_names_unknown_ones():
    """``geodesic(options=GeodesicOptions(...))`` = the same settings as keywords (and as a
    mapping); keywords override the object; an unknown setting is a TypeError naming it;
    the signature stays short (no 18-argument functions)."""
    import inspect

    from meshopt_toolkit.riemannian.geodesics import GeodesicOptions

    mesh = square5()
    pen = HeightPenalty(mesh, alpha=(1.0, 1.0, 1.0))
    V, times = squeeze_velocity(), [0.3, 1.0]
    by_kw = geodesic(pen, mesh.points, V, 1.0, times=times, method="dopri5", rtol=1e-8)
    opts = GeodesicOptions(method="dopri5", rtol=1e-8)
    by_obj = geodesic(pen, mesh.points, V, 1.0, times=times, options=opts)
    by_map = geodesic(pen, mesh.points, V, 1.0, times=times, options={"method": "dopri5", "rtol": 1e-8})
    over = geodesic(pen, mesh.points, V, 1.0, times=times, options=GeodesicOptions(method="bs3"),
                    method="dopri5", rtol=1e-8)
    for res in (by_obj, by_map, over):
        assert res.method == "dopri5" and np.array_equal(res.points, by_kw.points)
    with pytest.raises(TypeError, match="rtoll"):
        geodesic(pen, mesh.points, V, 1.0, rtoll=1e-3)
    with pytest.raises(IntegrationError, match="unknown geodesic method"):
        GeodesicOptions(method="euler")
    for bad in ({"rtol": 0.0}, {"rtol": float("nan")}, {"max_steps": 0}, {"atol": -1.0}):
        with pytest.raises(IntegrationError, match=next(iter(bad))):
            GeodesicOptions(**bad)
    with pytest.raises(TypeError, match="GeodesicOptions or a mapping"):
        geodesic(pen, mesh.points, V, 1.0, options="bs3")
    assert len(inspect.signature(geodesic).parameters) <= 10
    # exp_map and the metric's exp honour an options object (no defaults on top of it)
    from meshopt_toolkit.riemannian.geodesics import exp_map

    end = exp_map(pen, mesh.points, V, 1.0, options=opts)
    assert np.array_equal(end, by_kw.points[-1])
    assert np.array_equal(CompleteMetric(pen).exp(mesh.points, V, 1.0, options=opts), end)


def test_dop853_continuous_extension_has_order_seven():
    """One DOP853 step of the harmonic oscillator y' = (y₂, −y₁) (closed form: a rotation):
    the continuous extension inside the step has local error O(h⁸); halving h divides it
    by ≈ 2⁸ (asserted ≥ 2⁷)."""
    from meshopt_toolkit.ode.tableaus import dense_evaluate, dense_polynomial, rk_pair

    pair = rk_pair("dop853")
    S = len(pair.b)

    def f(y):
        return np.array([y[1], -y[0]])

    def error(h):
        y0 = np.array([1.0, 0.0])
        a = np.zeros((S, S))
        a[:, :] = pair.a
        k = np.zeros((S + 4, 2))
        k[0] = f(y0)
        for s in range(1, S):
            k[s] = f(y0 + h * a[s, :s] @ k[:s])
        y1 = y0 + h * pair.b @ k[:S]
        k[S] = f(y1)
        for i, row in enumerate(pair.dense_a):
            k[S + 1 + i] = f(y0 + h * row[:S + 1 + i] @ k[:S + 1 + i])
        theta = np.array([0.2, 0.5, 0.9])
        y = dense_evaluate(dense_polynomial(pair, k, y0, y1, h), y0, theta)
        exact = np.stack([np.cos(theta * h), -np.sin(theta * h)], axis=1)
        return np.abs(y - exact).max()

    e1, e2 = error(0.4), error(0.2)
    assert e2 < 1e-9 and e1 / e2 >= 2.0**7


def test_energy_at_interpolated_outputs_holds_at_the_default_tolerance():
    """The energy (V, V)_g at output times inside steps (dense output)
    stays within 1e-4 of e(0) at the default tolerance on the 5-second squeeze with the
    boundary-pair term (h_μ) on; the quintic Hermite velocities gave 1.9e-3."""
    mesh = square5()
    pen = HeightPenalty(mesh, alpha=(1.0, 1.0, 1.0))
    res = geodesic(CompleteMetric(pen), mesh.points, squeeze_velocity(), 5.0,
                   times=np.linspace(0, 5, 51), on_violation="raise")
    assert res.n_steps < 50  # outputs inside steps: the interpolant is what is tested
    assert np.max(np.abs(res.energy - res.energy[0])) <= 1e-4 * res.energy[0]


# -- line-search mode, boundary guard, partial results, fixed vertices --------------------


def u_mesh() -> PlanarMesh:
    """grid_mesh(4) with the top-middle 2×2 cells removed: a U whose two walls face each
    other across a gap of 0.5 (boundary edges that can be brought into contact)."""
    g = grid_mesh(4)
    tri = g.triangles.reshape(2, 4, 4, 3)  # (kind, row, col, corner)
    keep = np.ones((2, 4, 4), dtype=bool)
    keep[:, 2:, 1:3] = False
    tri = tri[keep]
    used = np.unique(tri)
    remap = np.full(g.n_vertices, -1)
    remap[used] = np.arange(used.size)
    return PlanarMesh(g.points[used], remap[tri])


def test_bs3_tableau_satisfies_order_conditions():
    from meshopt_toolkit.ode import BS3_TABLEAU

    c, a, b, bh = (BS3_TABLEAU[k] for k in ("c", "a", "b", "b_hat"))
    A = np.zeros((4, 4))
    for i, row in enumerate(a):
        A[i, : len(row)] = row
    assert np.allclose(A.sum(1), c)
    for w, order in ((b, 3), (bh, 2)):
        assert np.isclose(w.sum(), 1)
        assert np.isclose(w @ c, 1 / 2)
        if order >= 3:
            assert np.isclose(w @ c**2, 1 / 3) and np.isclose(w @ A @ c, 1 / 6)
    assert not np.isclose(bh @ c**2, 1 / 3)  # the embedded weights are only 2nd order
    assert np.allclose(A[3, :3], b[:3])  # first same as last


def test_bs3_is_third_order():
    mesh, pen, V = _mild_case()
    ref = geodesic(pen, mesh.points, V, 1.0, rtol=1e-12, atol=1e-12).final
    steps = np.array([8, 16, 32, 64])
    errs = []
    for n in steps:  # fixed steps: huge tolerances, h0 = 1/n, outputs on the grid
        res = geodesic(pen, mesh.points, V, 1.0, times=np.arange(1, n + 1) / n, method="bs3",
                       rtol=1e9, atol=1e9, h0=1.0 / n, dense=False, on_violation="ignore")
        errs.append(np.abs(res.final - ref).max())
    slope = -np.polyfit(np.log(steps), np.log(errs), 1)[0]
    assert abs(slope - 3) < 0.3, (errs, slope)


def test_line_search_mode_is_cheap_admissible_and_a_retraction(rng):
    from meshopt_toolkit import data_path, load

    mesh = load(data_path("disc_85.msh")).as_planar()
    pen = QualityPenalty(mesh, beta=(10, 1, 0, 0.01 * mesh.n_vertices))
    V = 0.3 * rng.standard_normal(mesh.points.shape)
    times = 0.5 ** np.arange(20)[::-1]
    ref = geodesic(pen, mesh.points, V, 1.0, times=times, rtol=1e-10, on_violation="ignore")
    fast = geodesic(pen, mesh.points, V, 1.0, times=times, method="line-search")
    exact = geodesic(pen, mesh.points, V, 1.0, times=times, on_violation="ignore")
    assert fast.method == "line-search" and fast.n_evaluations < exact.n_evaluations / 3
    assert fast.admissible.all() and all(pen.is_admissible(p) for p in fast.points)
    assert np.isnan(fast.penalty).all()  # positions only: no f at the outputs
    # energy projection: every output landed on a step end has the initial energy
    landed = ~np.isnan(fast.energy)
    assert landed.any() and np.allclose(fast.energy[landed], ref.energy[0], rtol=1e-12)
    # a retraction that agrees with exp to second order: error O(t³) for small t (the
    # BS3 step's local error); loose only where the path bounces (large t)
    err = np.abs(fast.points - ref.points).max(axis=(1, 2))
    small = slice(0, 8)  # t = 2^-19 … 2^-12, inside the first step
    slope = np.polyfit(np.log(times[small]), np.log(err[small]), 1)[0]
    assert slope > 2.7, (slope, err[small])
    assert err[small].max() < 1e-6 * np.abs(V).max()
    assert np.abs(fast.final - ref.final).max() < 0.5 * np.abs(V).max()


def test_energy_projection_keeps_the_energy_at_loose_tolerance(rng):
    from meshopt_toolkit import data_path, load
    from meshopt_toolkit.ode import energy, runge_kutta

    mesh = load(data_path("disc_25.msh")).as_planar()
    pen = QualityPenalty(mesh, beta=(10, 1, 0, 0.01 * mesh.n_vertices))
    V = 0.5 * rng.standard_normal(mesh.points.shape)
    t = np.linspace(0.25, 2.0, 8)
    outs = {}
    for project in (False, True):
        fld = GeodesicField(pen)
        outs[project] = runge_kutta(fld, mesh.points, V, t, rtol=5e-2, atol=5e-2, pair="bs3",
                                    dense=False,
                                    control={"energy_rtol": np.inf, "project_energy": project})
    e0 = energy(pen.gradient(mesh.points), V)
    e_free = np.array([energy(pen.gradient(q), v) for q, v in zip(outs[False].points,
                                                                  outs[False].velocities)])
    e_proj = np.array([energy(pen.gradient(q), v) for q, v in zip(outs[True].points,
                                                                  outs[True].velocities)])
    assert np.allclose(e_proj, e0, rtol=1e-12)
    assert np.abs(e_free / e0 - 1).max() > 1e-6  # without it the energy does drift


@pytest.mark.parametrize("dense", [True, False])
def test_boundary_guard_agrees_with_the_exact_test(rng, monkeypatch, dense):
    """Random walks of the U-mesh boundary, from harmless to crossing: the guard (dense
    test + displacement certificate; or, as for large boundaries, the penalty's test and
    the k-d tree certificate) answers exactly what penalty.boundary_problem does, and most
    answers along a slow walk come from the certificate."""
    from meshopt_toolkit.riemannian.field import BoundaryGuard

    if not dense:
        monkeypatch.setattr(BoundaryGuard, "DENSE_PAIRS", 0)
    for mesh in (u_mesh(), grid_mesh(3)):  # (the square: collinear boundary edges)
        pen = QualityPenalty(mesh, beta=(1, 0, 0, 0))
        bv = mesh.boundary_vertices
        for scale, steps in ((0.004, 60), (0.03, 60), (0.2, 30)):
            guard = BoundaryGuard(pen)
            assert guard.dense == dense
            Q = mesh.points.copy()
            disagree = 0
            for _ in range(steps):
                Q[bv] += scale * rng.standard_normal((len(bv), 2))
                disagree += (guard.problem(Q) is None) != (pen.boundary_problem(Q) is None)
            assert disagree == 0
            if scale == 0.004:
                assert guard.n_exact < steps / 3
    # touching and crossing walls are found
    mesh = u_mesh()
    pen = QualityPenalty(mesh, beta=(1, 0, 0, 0))
    right = np.flatnonzero(np.isclose(mesh.points[:, 0], 0.75) & (mesh.points[:, 1] > 0.6))
    for shift, ok in ((0.3, True), (0.5, False), (0.6, False)):
        Q = mesh.points.copy()
        Q[right, 0] -= shift
        Q[right, 1] += 0.01
        assert (BoundaryGuard(pen).problem(Q) is None) == ok == (pen.boundary_problem(Q) is None)


def test_failed_geodesic_carries_the_part_it_integrated():
    """β3 = 0: nothing stops the U's walls from meeting; the outputs before the contact
    come with the error."""
    mesh = u_mesh()
    pen = QualityPenalty(mesh, beta=(0.1, 0, 0, 0.1))
    arm = np.flatnonzero((mesh.points[:, 0] > 0.7) & (mesh.points[:, 1] > 0.6))
    V = np.zeros_like(mesh.points)
    V[arm, 0] = -1.0  # the right arm shears left: the gap of 0.5 closes near t = 0.5
    times = np.linspace(0.1, 1.0, 10)
    with pytest.raises(IntegrationError, match="boundary self-intersects") as info:
        geodesic(pen, mesh.points, V, 1.0, times=times, method="line-search")
    part = info.value.partial
    assert part is not None and 1 <= len(part.times) <= 5
    np.testing.assert_allclose(part.times, times[: len(part.times)])
    assert all(pen.is_admissible(p) for p in part.points)


def test_fixed_vertices_stay_and_the_restricted_energy_is_conserved(rng):
    from meshopt_toolkit import data_path, load
    from meshopt_toolkit.ode import energy

    mesh = load(data_path("disc_25.msh")).as_planar()
    pen = QualityPenalty(mesh, beta=(10, 1, 0, 0.01 * mesh.n_vertices))
    free = np.ones(mesh.n_vertices, dtype=bool)
    free[mesh.boundary_vertices] = False
    V = 0.3 * rng.standard_normal(mesh.points.shape) * free[:, None]
    res = geodesic(pen, mesh.points, V, 1.0, times=[0.5, 1.0], free=free, rtol=1e-9,
                   dense=False, on_violation="raise")
    for p in res.points:
        np.testing.assert_array_equal(p[~free], mesh.points[~free])
    g0 = pen.gradient(mesh.points) * free[:, None]
    e0 = energy(g0, V)
    for p, v in zip(res.points, res.velocities):
        assert energy(pen.gradient(p) * free[:, None], v) == pytest.approx(e0, rel=1e-6)
    with pytest.raises(IntegrationError, match="vanish"):
        geodesic(pen, mesh.points, V + 0.1, 1.0, free=free)


def test_curvature_without_the_boundary_check():
    mesh = u_mesh()
    pen = QualityPenalty(mesh, beta=(1, 0.5, 0, 1))
    arm = np.flatnonzero((mesh.points[:, 0] > 0.7) & (mesh.points[:, 1] > 0.6))
    Q = mesh.points.copy()
    Q[arm, 0] -= 0.6  # the right arm sheared over the left one: triangles stay positive
    assert min_area(Q, mesh) > 0 and pen.boundary_problem(Q) is not None
    with pytest.raises(NotAdmissibleError, match="boundary"):
        pen.gradient_and_curvature(Q, Q)
    g, c = pen.gradient_and_curvature(Q, Q, check_boundary=False)
    assert np.isfinite(g).all() and np.isfinite(c)
    # where the boundary is fine, skipping its check changes nothing
    checked = pen.gradient_and_curvature(mesh.points, Q)
    unchecked = pen.gradient_and_curvature(mesh.points, Q, check_boundary=False)
    np.testing.assert_array_equal(checked[0], unchecked[0])
    assert checked[1] == unchecked[1]


def test_step_control_is_given_as_an_object_or_a_mapping_of_its_fields():
    from meshopt_toolkit import data_path, load
    from meshopt_toolkit.ode import StepControl, runge_kutta

    mesh = load(data_path("disc_25.msh")).as_planar()
    fld = GeodesicField(QualityPenalty(mesh, beta=(10, 1, 0, 0.25)))
    V = 0.1 * np.ones_like(mesh.points)
    V[mesh.boundary_vertices] = 0.0
    t = np.array([0.5, 1.0])
    a = runge_kutta(fld, mesh.points, V, t, rtol=1e-4, atol=1e-4,
                    control=StepControl(max_steps=500, exit_shrink=0.5))
    b = runge_kutta(fld, mesh.points, V, t, rtol=1e-4, atol=1e-4,
                    control={"max_steps": 500, "exit_shrink": 0.5})
    assert np.array_equal(a.points, b.points)
    with pytest.raises(TypeError, match="max_step"):
        runge_kutta(fld, mesh.points, V, t, rtol=1e-4, atol=1e-4, control={"max_step": 5})
