"""Retractions of the complete metric (riemannian/retractions.py): the second-order
retraction agrees with the exponential map to third order, follows its own velocity,
refuses what leaves M+, keeps fixed vertices, and drives complete-complete optimization
to the same optimum as the exponential map."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh

from meshopt_toolkit.errors import OptimizationError, OptionError
from meshopt_toolkit.fem.poisson import PoissonObjective
from meshopt_toolkit.kernels.triangles import signed_areas
from meshopt_toolkit.optimize import default_metric_beta, optimize, thesis_penalty_beta
from meshopt_toolkit.penalties import QualityPenalty
from meshopt_toolkit.riemannian.geodesic_options import GeodesicOptions
from meshopt_toolkit.riemannian.geodesics import exp_map
from meshopt_toolkit.riemannian.metrics import CompleteMetric
from meshopt_toolkit.riemannian.retractions import ExponentialRetraction, SecondOrderRetraction


@pytest.fixture
def setting():
    mesh = grid_mesh(5, jitter=0.3, seed=4)
    metric = CompleteMetric(QualityPenalty(mesh, beta=(1.0, 1.0, 0.0, 1.0)))
    rng = np.random.default_rng(11)
    V = rng.standard_normal(mesh.points.shape)
    V /= np.abs(V).max()
    return mesh, metric, V


def test_second_order_retraction_agrees_with_the_exponential_map_to_third_order(setting):
    mesh, metric, V = setting
    Q = mesh.points
    retract = SecondOrderRetraction(metric)
    ts = 0.02 * 2.0 ** -np.arange(5)
    points, _ = retract(Q, V, ts)
    errors = np.array([np.abs(p - exp_map(metric, Q, V, t, method="dop853", rtol=1e-12)).max()
                       for p, t in zip(points, ts)])
    straight = np.array([np.abs(Q + t * V - exp_map(metric, Q, V, t, method="dop853",
                                                    rtol=1e-12)).max() for t in ts])
    ratios = errors[:-1] / errors[1:]
    assert np.all(ratios > 6.5), ratios  # O(t³): 8 per halving
    assert np.all(straight[:-1] / straight[1:] < 4.5)  # the straight line only O(t²)
    assert np.all(errors < straight)


def test_second_order_retraction_velocity_is_the_curve_derivative(setting):
    mesh, metric, V = setting
    retract = SecondOrderRetraction(metric)
    t, h = 0.05, 1e-6
    (p_minus, p, p_plus), (_, v, _) = retract(mesh.points, V, [t - h, t, t + h])
    np.testing.assert_allclose((p_plus - p_minus) / (2 * h), v, atol=1e-7)
    # at t = 0 it is V itself and the point is Q
    (p0,), (v0,) = retract(mesh.points, V, [0.0])
    np.testing.assert_array_equal(p0, mesh.points)
    np.testing.assert_array_equal(v0, V)


def test_second_order_retraction_refuses_points_outside_m_plus(setting):
    mesh, metric, V = setting
    points, velocities = SecondOrderRetraction(metric)(mesh.points, V, [0.01, 50.0])
    assert points[0] is not None and signed_areas(points[0], mesh.triangles).min() > 0
    assert points[1] is None and velocities[1] is None


def test_retractions_keep_fixed_vertices(setting):
    mesh, metric, V = setting
    fixed = mesh.boundary_vertices
    free = np.ones(mesh.n_vertices, bool)
    free[fixed] = False
    V = V.copy()
    V[fixed] = 0.0
    for retract in (SecondOrderRetraction(metric, free),
                    ExponentialRetraction(metric, GeodesicOptions(), free)):
        (p,), (v,) = retract(mesh.points, V, [0.05])
        np.testing.assert_array_equal(p[fixed], mesh.points[fixed])
        np.testing.assert_array_equal(v[fixed], 0.0)


def test_exponential_retraction_returns_the_requested_order(setting):
    mesh, metric, V = setting
    retract = ExponentialRetraction(metric, GeodesicOptions(method="dop853", rtol=1e-10))
    points, _ = retract(mesh.points, V, [0.04, 0.01, 0.02])
    for p, t in zip(points, (0.04, 0.01, 0.02)):
        np.testing.assert_allclose(p, exp_map(metric, mesh.points, V, t, method="dop853",
                                              rtol=1e-10), atol=1e-9)


@pytest.mark.parametrize("method", ["steepest", "lbfgs"])
def test_complete_complete_reaches_the_exponential_maps_optimum(method):
    """The thesis' problem (table 6.4 set 2) on a small disc: the second-order retraction
    (the default) and the exponential map end at the same objective within 2e-4 (the
    tolerance of the thesis-table comparison), every iterate admissible."""
    import meshopt_toolkit as mt

    mesh = mt.load(mt.data_path("disc_146.msh")).as_planar()
    kw = dict(variant="complete-complete", method=method,
              penalty=thesis_penalty_beta(2, mesh.n_vertices),
              metric_beta=default_metric_beta(mesh.n_vertices))
    second = optimize(mesh, PoissonObjective(mesh), **kw)
    exp = optimize(mesh, PoissonObjective(mesh), options=dict(retraction="exp"), **kw)
    assert second.success and exp.success
    assert abs(second.fun - exp.fun) <= 2e-4
    assert signed_areas(second.x, mesh.triangles).min() > 0


def test_retraction_options_are_checked():
    mesh = grid_mesh(3)
    obj = PoissonObjective(mesh)
    with pytest.raises(OptionError, match="straight lines"):
        optimize(mesh, obj, variant="complete-euclidean", options=dict(retraction="exp"),
                 penalty=None)
    with pytest.raises(OptionError, match="straight lines"):
        optimize(mesh, obj, variant="elasticity-euclidean",
                 options=dict(exp_options={"method": "auto"}), penalty=None)
    with pytest.raises(OptionError, match="unknown retraction"):
        optimize(mesh, obj, variant="complete-complete", options=dict(retraction="cayley"),
                 penalty=None)
    for retraction in ("second-order", "exp"):  # exp_options go with "exp" only
        kw = dict(variant="complete-complete", max_iterations=1, penalty=None,
                  options=dict(retraction=retraction, exp_options={"method": "auto"}))
        if retraction == "exp":
            assert optimize(mesh, obj, **kw).nit == 1
        else:
            with pytest.raises(OptionError, match="retraction='exp' only"):
                optimize(mesh, obj, **kw)
