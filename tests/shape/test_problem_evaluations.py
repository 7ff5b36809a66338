"""What one trial point costs :class:`~meshopt_toolkit.shape.problem.ShapeProblem`: a
planar penalty gives its gradient with its value and tests the boundary, so the
accepted point's derivative needs no second penalty evaluation and the boundary is
tested once."""

from __future__ import annotations

import numpy as np
from conftest import grid_mesh

import meshopt_toolkit.shape.problem as problem_module
from meshopt_toolkit.fem.poisson import PoissonObjective
from meshopt_toolkit.optimize import DEFAULT_PENALTY_BETA
from meshopt_toolkit.penalties import QualityPenalty
from meshopt_toolkit.riemannian.metrics import ElasticityMetric
from meshopt_toolkit.shape.problem import ShapeProblem
from meshopt_toolkit.shape.setup import contact_options


def _problem(mesh, penalty):
    free = np.ones(mesh.n_vertices, bool)
    free[mesh.boundary_vertices] = False
    return ShapeProblem(PoissonObjective(mesh), penalty, ElasticityMetric(mesh), mesh.triangles,
                        mesh.boundary_edges, free), free


def test_the_accepted_points_derivative_reuses_the_penalty_gradient(rng, monkeypatch):
    """``values`` then ``derivative`` at one point evaluate the penalty once, and the
    derivative is ``j' + f2'`` on the free vertices (f2' from a separate evaluation)."""
    mesh = grid_mesh(6, jitter=0.2, seed=1)
    penalty = QualityPenalty(mesh, beta=DEFAULT_PENALTY_BETA, **contact_options(mesh))
    problem, free = _problem(mesh, penalty)
    Q = mesh.points.copy()
    Q[free] += 0.01 * rng.standard_normal((free.sum(), 2))
    expected = PoissonObjective(mesh).derivative(Q) + penalty.gradient(Q)
    calls = []
    monkeypatch.setattr(penalty, "gradient", lambda X: calls.append(X) or 0 / 0)
    F, J = problem.values(Q)
    assert np.isfinite(F) and F == J + penalty.value(Q)
    P = problem.derivative(Q)
    assert not calls
    np.testing.assert_allclose(P[free], expected[free], rtol=1e-13, atol=1e-14)
    assert not P[~free].any()


def test_a_planar_penalty_tests_the_boundary_and_a_fold_is_rejected_unsolved(monkeypatch):
    """Each trial's boundary is tested once, by the penalty; a trial outside M+ is
    rejected before the state solve."""
    mesh = grid_mesh(4)
    penalty = QualityPenalty(mesh, beta=DEFAULT_PENALTY_BETA, **contact_options(mesh))
    problem, _ = _problem(mesh, penalty)
    tested = []
    real = problem_module.boundary_self_intersections
    monkeypatch.setattr(problem_module, "boundary_self_intersections",
                        lambda *a: tested.append(1) or real(*a))
    assert np.isfinite(problem.values(mesh.points)[0])
    assert not tested
    solved = []
    monkeypatch.setattr(problem.objective, "value", lambda X: solved.append(1) or 0.0)
    bent = mesh.points.copy()
    corner = np.flatnonzero((bent == [1.0, 1.0]).all(axis=1))[0]
    bent[corner] = [0.1, 0.9]  # folds the corner's triangles over
    F, _ = problem.values(bent)
    assert F == np.inf and not solved and problem.n_rejected == 1
