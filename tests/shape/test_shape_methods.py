"""Riemannian L-BFGS and CG (meshopt_toolkit.shape): closed-form checks of the line search,
the curvature pairs and the segment guard, L-BFGS on quadratics against the exact
minimizer, and admissibility of every iterate (including an annulus where a
trial step used to be fatal)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import grid_mesh, square5
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.errors import OptionError
from meshopt_toolkit.kernels.triangles import signed_areas
from meshopt_toolkit.mesh import boundary_self_intersections
from meshopt_toolkit.optimize import METHODS, VARIANTS, optimize
from meshopt_toolkit.kernels.triangles import segment_limit
from meshopt_toolkit.shape import LBFGSMemory, wolfe_line_search


class QuadraticObjective:
    """j(Q) = ½ (q − c)ᵀ A (q − c) over the interior vertices' coordinates (q = vec Q_I)."""

    def __init__(self, mesh, A, c):
        self.interior = np.setdiff1d(np.arange(mesh.n_vertices), mesh.boundary_vertices)
        self.A, self.c = A, c

    def value(self, Q):
        r = Q[self.interior].ravel() - self.c
        return 0.5 * float(r @ self.A @ r)

    def derivative(self, Q):
        g = np.zeros_like(Q)
        g[self.interior] = (self.A @ (Q[self.interior].ravel() - self.c)).reshape(-1, 2)
        return g


def _quadratic(mesh, seed, cond=10.0, shift=0.03):
    rng = np.random.default_rng(seed)
    interior = np.setdiff1d(np.arange(mesh.n_vertices), mesh.boundary_vertices)
    n = 2 * len(interior)
    U, _ = np.linalg.qr(rng.normal(size=(n, n)))
    A = U @ np.diag(np.geomspace(1.0, cond, n)) @ U.T
    c = mesh.points[interior].ravel() + shift * rng.uniform(-1, 1, n)  # admissible minimizer
    return QuadraticObjective(mesh, A, c), c, n


# -- the line search ------------------------------------------------------------------------

def _phi_of(f, df, domain=math.inf):
    def phi(t):
        return (f(t) if t < domain else math.inf), t

    return phi, (lambda t, payload: df(t))


@pytest.mark.parametrize("t0", [1e-3, 0.5, 2.0, 40.0])
def test_line_search_returns_a_wolfe_step_and_rejects_steps_outside_the_domain(t0):
    # φ(t) = (t − 3)² on t < 3.5, +∞ beyond: the Wolfe steps lie around t = 3
    phi, dphi = _phi_of(lambda t: (t - 3.0) ** 2, lambda t: 2 * (t - 3.0), domain=3.5)
    f0, g0, c1, c2 = 9.0, -6.0, 1e-4, 0.9
    res = wolfe_line_search(phi, dphi, f0, g0, t0, c1=c1, c2=c2)
    t = res.step
    assert res.wolfe and 0 < t < 3.5
    assert res.value <= f0 + c1 * t * g0  # sufficient decrease
    assert abs(res.slope) <= c2 * abs(g0)  # strong curvature condition
    if t0 > 3.5:
        assert res.rejected >= 1  # the first trial was outside: rejected, not fatal


@settings(max_examples=60, deadline=None)
@given(a=st.floats(0.1, 10), b=st.floats(-2, 2), dom=st.floats(0.05, 10), t0=st.floats(1e-3, 50),
       c2=st.sampled_from([0.1, 0.5, 0.9]))
def test_line_search_wolfe_conditions_hold_whenever_reported(a, b, dom, t0, c2):
    """φ(t) = a (t − 1)² + |b| (t − 1)⁴ on [0, dom): Armijo always holds at an accepted
    step, both (strong) Wolfe conditions whenever ``wolfe`` is reported, and no accepted
    step lies outside the domain."""
    def f(t):
        return a * (t - 1) ** 2 + abs(b) * (t - 1) ** 4

    def df(t):
        return 2 * a * (t - 1) + 4 * abs(b) * (t - 1) ** 3

    phi, dphi = _phi_of(f, df, domain=dom)
    f0, g0 = f(0.0), df(0.0)
    res = wolfe_line_search(phi, dphi, f0, g0, t0, c1=1e-4, c2=c2)
    assert res.success
    assert 0 < res.step < dom
    assert res.value <= f0 + 1e-4 * res.step * g0
    if res.wolfe:
        assert abs(res.slope) <= c2 * abs(g0)
    if dom > 1.5:  # a Wolfe step exists inside the domain: the search must find it
        assert res.wolfe


def test_line_search_without_any_admissible_decrease_fails_cleanly():
    phi, dphi = _phi_of(lambda t: 1.0, lambda t: 0.0, domain=0.0)  # +∞ everywhere but t = 0
    res = wolfe_line_search(phi, dphi, 1.0, -1.0, 1.0, min_step=1e-8)
    assert not res.success and res.step == 0 and res.rejected == res.evaluations


# -- curvature pairs and the segment guard ---------------------------------------------------

def test_lbfgs_rejects_and_counts_pairs_without_positive_curvature():
    mem = LBFGSMemory(size=3)
    s = np.array([[1.0, 0.0]])
    assert not mem.update(s, np.array([[-1.0, 0.0]]), slope=-1.0)  # s·ŷ < 0
    assert not mem.update(s, np.array([[0.0, 5.0]]), slope=-1.0)  # s·ŷ = 0
    assert mem.rejected == 2 and not mem.pairs
    assert mem.update(s, np.array([[2.0, 0.0]]), slope=-1.0)
    # with one pair, H0 = γ I and γ = s·y / y·y: a 1-D quadratic's Newton step exactly
    d = mem.direction(np.array([[4.0, 0.0]]), riesz=lambda X: X)
    np.testing.assert_allclose(d, [[-2.0, 0.0]])
    for _ in range(5):
        mem.update(s, np.array([[2.0, 0.0]]), slope=-1.0)
    assert len(mem.pairs) == 3  # the memory size bounds the pairs kept


def test_segment_limit_is_the_first_degeneracy_along_the_line():
    mesh = square5()  # centre vertex 4 at height 1 over each outer edge
    d = np.zeros((5, 2))
    d[4] = [2.0, 0.0]
    t = segment_limit(mesh.points, mesh.triangles, d)
    assert t == pytest.approx(0.5)  # the centre reaches the edge x = 1 at t = 1/2
    assert signed_areas(mesh.points + t * (1 - 1e-9) * d, mesh.triangles).min() > 0
    assert signed_areas(mesh.points + t * (1 + 1e-9) * d, mesh.triangles).min() < 0
    assert segment_limit(mesh.points, mesh.triangles, np.ones((5, 2))) == math.inf  # translation


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_segment_limit_keeps_every_area_positive_before_it(seed):
    mesh = grid_mesh(3, jitter=0.2, seed=seed % 7)
    d = np.random.default_rng(seed).normal(size=mesh.points.shape)
    t = segment_limit(mesh.points, mesh.triangles, d)
    ts = np.linspace(0, 1, 50) * (min(t, 100.0) * (1 - 1e-7))
    assert all(signed_areas(mesh.points + s * d, mesh.triangles).min() > 0 for s in ts)
    if math.isfinite(t):
        A = signed_areas(mesh.points + t * d, mesh.triangles)
        assert A.min() <= 1e-9 * np.abs(signed_areas(mesh.points, mesh.triangles)).max()


# -- L-BFGS and CG on quadratics --------------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_lbfgs_with_exact_line_searches_terminates_on_a_quadratic_in_n_plus_1_iterations(seed):
    """Strong Wolfe with a small c2 is an (almost) exact line search on a quadratic; BFGS with
    exact line searches and memory ≥ n then terminates in n steps (the first direction is
    the same whatever the scaling γ of H0)."""
    mesh = grid_mesh(3, jitter=0.1, seed=seed)  # 4 interior vertices: n = 8 unknowns
    obj, c, n = _quadratic(mesh, seed)
    res = optimize(mesh, obj, variant="euclidean-euclidean", method="lbfgs", max_iterations=50,
                   options=dict(memory=n, c2=1e-4, sigma=1e-5, gtol=1e-9, tolerance=None),
                   fixed=mesh.boundary_vertices, penalty=None)
    assert res.status == "converged" and res.success
    assert res.nit <= n + 1
    interior = obj.interior
    np.testing.assert_allclose(res.x[interior].ravel(), c, atol=1e-7)


@pytest.mark.parametrize("method", ["lbfgs", "cg"])
@pytest.mark.parametrize("variant", ["euclidean-euclidean", "elasticity-euclidean"])
def test_methods_reach_the_reference_minimizer_of_a_quadratic(method, variant):
    mesh = grid_mesh(4, jitter=0.1, seed=5)
    obj, c, n = _quadratic(mesh, 5, cond=50.0, shift=0.02)
    res = optimize(mesh, obj, variant=variant, method=method, max_iterations=400,
                   options=dict(gtol=1e-8, tolerance=None), fixed=mesh.boundary_vertices,
                   penalty=None)
    assert res.status == "converged"
    np.testing.assert_allclose(res.x[obj.interior].ravel(), c, atol=1e-6)
    steepest = optimize(mesh, obj, variant=variant, method="steepest", max_iterations=res.nit,
                        options=dict(tolerance=None, gtol=1e-8), fixed=mesh.boundary_vertices,
                        penalty=None)
    assert steepest.fun > res.fun  # same iteration budget: steepest descent is behind
    if method == "lbfgs":
        assert all(h.wolfe for h in res.history[1:])


# -- admissibility, failures, history --------------------------------------------------------

@pytest.fixture(scope="module")
def annulus_mesh():
    from meshopt_toolkit.generate import annulus

    return annulus(size=0.2)


@pytest.mark.parametrize("method", METHODS)
def test_annulus_trials_across_the_boundary_are_rejected_not_fatal(method, annulus_mesh):
    """On an annulus with β3 = 0 a trial step crossed the boundary (areas still
    positive) and the run stopped with 'boundary self-intersects'."""
    from meshopt_toolkit.optimize import thesis_penalty_beta
    from meshopt_toolkit.fem.poisson import PoissonObjective

    mesh = annulus_mesh
    edges = mesh.boundary_edges
    iterates = []
    res = optimize(mesh, PoissonObjective(mesh), variant="euclidean-euclidean", method=method,
                   penalty=thesis_penalty_beta(2, mesh.n_vertices), max_iterations=100,
                   callback=lambda rec: iterates.append(rec.points.copy()))
    # β3 = 0: nothing in F keeps the inner boundary off the outer one, the infimum lies on
    # the edge of M+; the run may end there (step_too_small) but never raises
    assert res.status in ("converged", "step_too_small", "max_iterations")
    assert res.nit >= 5 and len(iterates) == res.nit
    for Q in iterates:
        assert signed_areas(Q, mesh.triangles).min() > 0
        assert len(boundary_self_intersections(Q, edges)) == 0
    assert sum(h.rejected_trials for h in res.history) >= 1  # some trials were outside M+


@pytest.mark.parametrize("variant", VARIANTS)
def test_lbfgs_history_records_method_steps_and_curvature_pairs(variant):
    from test_optimize import PullObjective

    mesh = grid_mesh(4, jitter=0.2, seed=3)
    res = optimize(mesh, PullObjective(mesh, mesh.points + 0.05), variant=variant, method="lbfgs",
                   penalty=(0.01, 0.01, 0, 0.01), max_iterations=6,
                   options=dict(tolerance=None, gtol=None))
    rows = [h.as_row() for h in res.history]
    assert {"method", "step", "wolfe", "pair_rejected", "rejected_trials",
            "relative_gradient_norm"} <= set(rows[0])
    assert all(r["method"] == "lbfgs" for r in rows)
    assert all(r["step"] > 0 for r in rows[1:])
    assert res.summary()["rejected_curvature_pairs"] == sum(r["pair_rejected"] for r in rows)
    assert res.summary()["method"] == "lbfgs"


@pytest.mark.parametrize("method", METHODS)
def test_reaching_max_iterations_is_not_success(method):
    mesh = grid_mesh(4, jitter=0.1, seed=5)
    obj, c, n = _quadratic(mesh, 5, cond=50.0, shift=0.02)
    res = optimize(mesh, obj, method=method, variant="euclidean-euclidean", max_iterations=2,
                   penalty=None)
    assert res.status == "max_iterations" and not res.success
    assert "without converging" in res.message


def test_unknown_method_is_refused():
    from test_optimize import PullObjective

    mesh = grid_mesh(3)
    with pytest.raises(OptionError, match="method"):
        optimize(mesh, PullObjective(mesh, mesh.points), method="newton", penalty=None)


def _armijo_reference(t0, tau, c1, min_step, f):
    """The first trial ``t0·tau^k ≥ min_step`` with ``f(t) ≤ f(0) + c1 t f'(0)``, decided
    in exact rational arithmetic on the same float trials (f a polynomial in Fractions)."""
    from fractions import Fraction

    steps = t0 * tau ** np.arange(200)
    for t in steps[steps >= min_step]:
        T = Fraction(float(t))
        if f(T) <= f(Fraction(0)) + Fraction(c1) * T * Fraction(-2):
            return float(t)
    return 0.0


@settings(max_examples=60, deadline=None)
@given(t0=st.floats(0.01, 100.0), tau=st.floats(0.1, 0.9), c1=st.floats(0.01, 0.9))
def test_armijo_backtracking_takes_the_first_trial_with_sufficient_decrease(t0, tau, c1):
    """φ(t) = (t − 1)² − 1, φ'(0) = −2: the accepted step is the first of t0, τ t0, …
    with sufficient decrease (exact check), and only trials up to it are evaluated."""
    from meshopt_toolkit.shape import armijo_backtracking

    seen = []

    def phi(t):
        seen.append(t)
        return (t - 1.0) ** 2 - 1.0, t

    res = armijo_backtracking(phi, 0.0, -2.0, t0, c1=c1, tau=tau, min_step=1e-6)
    expected = _armijo_reference(t0, tau, c1, 1e-6, lambda T: (T - 1) ** 2 - 1)
    assert res.step == expected and res.payload == expected
    assert res.wolfe is False and res.slope is None
    assert seen == (t0 * tau ** np.arange(len(seen))).tolist() and seen[-1] == expected
    assert res.evaluations == len(seen)


def test_armijo_backtracking_guard_rejections_and_failure():
    from meshopt_toolkit.shape import armijo_backtracking

    seen, prepared = [], []

    def phi(t):  # +inf (outside the domain) above 0.3
        seen.append(t)
        return (math.inf if t > 0.3 else (t - 1.0) ** 2 - 1.0), None

    res = armijo_backtracking(phi, 0.0, -2.0, 4.0, tau=0.5, t_max=1.0,
                              prepare=prepared.append)
    # 4, 2, 1 are refused by the guard unevaluated; 0.5 is outside; 0.25 is taken
    assert seen == [0.5, 0.25] and res.step == 0.25
    assert res.evaluations == 5 and res.rejected == 1
    assert len(prepared) == 1 and prepared[0][:5].tolist() == [4.0, 2.0, 1.0, 0.5, 0.25]
    assert prepared[0].min() >= 1e-6
    uphill = armijo_backtracking(lambda t: (1.0, None), 0.0, -2.0, 1.0, min_step=0.1)
    assert not uphill.success and uphill.step == 0.0 and uphill.evaluations == 4  # 1 … 0.125
    with pytest.raises(ValueError, match="descent"):
        armijo_backtracking(lambda t: (0.0, None), 0.0, 1.0, 1.0)


@pytest.mark.parametrize("method, search", [("steepest", None), ("lbfgs", True), ("cg", True)])
def test_one_driver_each_method_its_line_search(method, search):
    """Every method runs through shape.driver.run_descent: steepest descent's records carry
    no Wolfe flag (Armijo backtracking), L-BFGS's and CG's do."""
    from test_optimize import PullObjective

    mesh = grid_mesh(4, jitter=0.2, seed=3)
    res = optimize(mesh, PullObjective(mesh, mesh.points + 0.05), method=method,
                   variant="euclidean-euclidean", penalty=(0.01, 0.01, 0, 0.01),
                   max_iterations=4, options=dict(tolerance=None, gtol=None))
    assert res.method == method and res.nit == 4
    flags = {r.wolfe is None for r in res.history[1:]}
    assert flags == {search is None}
