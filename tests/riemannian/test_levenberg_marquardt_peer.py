"""The discrete geodesics' Levenberg–Marquardt (riemannian.levenberg_marquardt, a
configuration of least_squares.damped_step): the minimum of the planar distortion path
energy equals scipy's least-squares minimum of the same residuals, every iteration lowers
the energy, and the damping carried from step to step is the step's."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh
from motion_helpers import record_damped_steps
from scipy.optimize import least_squares

import meshopt_toolkit.riemannian.levenberg_marquardt as lm
from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.riemannian.discrete_geodesic import discrete_geodesic


@pytest.mark.parametrize("seed", [0, 1])
def test_minimum_is_scipys_and_every_iteration_a_decrease(monkeypatch, seed):
    mesh = grid_mesh(4, jitter=0.3, seed=seed)
    P = mesh.points
    bump = np.sin(np.pi * P[:, 0]) * np.sin(np.pi * P[:, 1])
    Q1 = P + 0.15 * bump[:, None] * np.array([1.0, -0.5])
    metric, K = GraphMetric(P, mesh.triangles), 3
    steps = record_damped_steps(monkeypatch, lm)
    res = discrete_geodesic(metric, P, Q1, K, options={"gtol": 1e-14, "max_iterations": 300})
    assert res.converged and steps
    # each step lowers E, or, where E's change is rounding, its gradient
    assert all(b[0] < a[0] or b[1] < a[1] for a, b in zip(res.history, res.history[1:]))
    assert res.energy < res.history[0][0]
    # each step starts from the damping the step before left
    assert all(b[0] == a[1].damping for a, b in zip(steps, steps[1:]))

    t = np.linspace(0.0, 1.0, K + 1)[:, None, None]
    frames = (1.0 - t) * P + t * Q1
    free = np.ones(frames.shape[:2], bool)
    free[0] = free[-1] = False
    model = metric.path_model(frames, free)

    def residual(x):
        return model.evaluate(model.with_unknowns(x), jacobian=False)[0]

    def jacobian(x):
        return model.evaluate(model.with_unknowns(x), jacobian=True)[1].toarray()

    # MINPACK's Levenberg–Marquardt on the same residuals
    peer = least_squares(residual, model.unknowns(frames), jac=jacobian, method="lm",
                         xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert res.energy == pytest.approx(2.0 * peer.cost, rel=1e-12)
    np.testing.assert_allclose(model.unknowns(res.points), peer.x, atol=1e-9)
