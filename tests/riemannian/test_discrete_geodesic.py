"""The one discrete-geodesic entry (riemannian.discrete_geodesic): its methods, chosen by
what the metric provides, its settings and its one result type."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from conftest import grid_mesh

from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.penalties import QualityPenalty
from meshopt_toolkit.riemannian.discrete_geodesic import discrete_geodesic
from meshopt_toolkit.riemannian.geodesic_result import DiscreteGeodesic
from meshopt_toolkit.riemannian.metrics import (CompleteMetric, EuclideanMetric,
                                                MetricNotImplementedError)
from meshopt_toolkit.riemannian.path_options import LevenbergMarquardtOptions, NewtonCGOptions


@pytest.fixture(scope="module")
def mesh():
    return grid_mesh(4, jitter=0.3)


def _bent(mesh, amount=0.12):
    P = mesh.points
    bump = np.sin(np.pi * P[:, 0]) * np.sin(np.pi * P[:, 1])
    return P + amount * bump[:, None] * np.array([1.0, -0.5])


def test_one_entry_with_few_parameters():
    assert len(inspect.signature(discrete_geodesic).parameters) <= 12


def test_auto_is_levenberg_marquardt_for_a_path_model_and_newton_cg_otherwise(mesh):
    P, Q1 = mesh.points, _bent(mesh)
    graph = GraphMetric(P, mesh.triangles)
    auto = discrete_geodesic(graph, P, Q1, 3)
    lm = discrete_geodesic(graph, P, Q1, 3, method="levenberg-marquardt")
    assert isinstance(auto, DiscreteGeodesic) and auto.converged
    assert np.array_equal(auto.points, lm.points) and auto.nit == lm.nit
    complete = CompleteMetric(QualityPenalty(mesh, beta=(1, 1, 0, 1)))
    auto = discrete_geodesic(complete, P, Q1, 4)
    ncg = discrete_geodesic(complete, P, Q1, 4, method="newton-cg")
    assert auto.converged and np.array_equal(auto.points, ncg.points)


def test_levenberg_marquardt_result(mesh):
    """Ends exact, the length that of the polygon through the embedded frames (computed
    here from ``embed``), no penalty, converged iff its status says so."""
    P, Q1 = mesh.points, _bent(mesh)
    metric = GraphMetric(P, mesh.triangles, 1.3)
    res = discrete_geodesic(metric, P, Q1, 4)
    assert np.array_equal(res.points[0], P) and np.array_equal(res.points[-1], Q1)
    assert res.segments == 4 and np.isnan(res.penalty).all() and res.penalty.shape == (5,)
    assert res.length == pytest.approx(metric.segment_lengths(res.points).sum(), rel=1e-12)
    assert res.converged == (res.status == "converged")
    assert res.energy == pytest.approx(4 * np.sum(metric.segment_lengths(res.points) ** 2),
                                       rel=1e-12)
    assert len(res.history) >= res.nit


def test_levenberg_marquardt_without_unknowns(mesh):
    P, Q1 = mesh.points, _bent(mesh)
    metric = GraphMetric(P, mesh.triangles)
    free = np.zeros((3, mesh.n_vertices), bool)
    res = discrete_geodesic(metric, P, Q1, 2, free=free)
    assert res.nit == 0 and res.status == "converged"
    assert np.array_equal(res.points[1], 0.5 * P + 0.5 * Q1)
    assert res.energy == pytest.approx(2 * np.sum(metric.segment_lengths(res.points) ** 2),
                                       rel=1e-12)


def test_settings_as_objects_or_mappings(mesh):
    P, Q1 = mesh.points, _bent(mesh)
    metric = GraphMetric(P, mesh.triangles)
    a = discrete_geodesic(metric, P, Q1, 2, options=LevenbergMarquardtOptions(max_iterations=2))
    b = discrete_geodesic(metric, P, Q1, 2, options={"max_iterations": 2})
    assert a.nit == b.nit == 2 and a.status == "max_iter"
    assert np.array_equal(a.points, b.points)
    with pytest.raises(TypeError, match="unknown levenberg-marquardt setting.*tol"):
        discrete_geodesic(metric, P, Q1, 2, options={"tol": 1e-3})
    with pytest.raises(TypeError, match="takes LevenbergMarquardtOptions"):
        discrete_geodesic(metric, P, Q1, 2, options=NewtonCGOptions())
    with pytest.raises(ValueError, match="unknown discrete-geodesic method"):
        discrete_geodesic(metric, P, Q1, 2, method="bfgs")


def test_a_method_the_metric_cannot_do_is_named(mesh):
    P, Q1 = mesh.points, _bent(mesh)
    complete = CompleteMetric(QualityPenalty(mesh, beta=(1, 1, 0, 1)))
    with pytest.raises(MetricNotImplementedError, match="CompleteMetric.path_model"):
        discrete_geodesic(complete, P, Q1, 2, method="levenberg-marquardt")
    with pytest.raises(ValueError, match="Levenberg–Marquardt"):
        discrete_geodesic(complete, P, Q1, 2, free=np.ones((3, len(P)), bool))


def test_euclidean_is_the_straight_line(mesh):
    P, Q1 = mesh.points, _bent(mesh)
    res = discrete_geodesic(EuclideanMetric(), P, Q1, 4)
    t = np.linspace(0, 1, 5)[:, None, None]
    np.testing.assert_allclose(res.points, (1 - t) * P + t * Q1, rtol=0, atol=1e-15)
    assert res.length == pytest.approx(np.linalg.norm(Q1 - P), rel=1e-12)


@pytest.mark.parametrize("given", [False, True])
def test_newton_cg_from_a_frame_to_itself_stays_there(mesh, given):
    """The ends equal: the geodesic is the frame itself, bit for bit, at once, whatever
    path it is given (a start rounded off the frame stalls on a gradient of rounding)."""
    Q = mesh.points
    path = np.repeat(Q[None], 5, axis=0) + 1e-3 * np.sin(np.arange(5))[:, None, None]
    res = discrete_geodesic(CompleteMetric(QualityPenalty(mesh)), Q, Q, 4, method="newton-cg",
                            path=path if given else None)
    assert res.status == "converged" and res.nit == 0
    assert res.energy == 0.0 and res.length == 0.0
    for frame in res.points:
        np.testing.assert_array_equal(frame, Q)
