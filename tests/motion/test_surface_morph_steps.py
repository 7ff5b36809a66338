"""The surface morph's Levenberg–Marquardt (motion.surface.morph._minimize: the discrete
geodesic of the surface metric, its steps least_squares.damped_step configured by
motion.surface.path.SurfaceRules): its minimum of the path energy equals
MINPACK's on the same residuals, every accepted step lowers the energy, and the damping
after a step is ``step_length_damping`` of the damping the step was solved with."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from motion_helpers import record_damped_steps
from scipy.optimize import least_squares
from test_surface_morph import bent, tube

import meshopt_toolkit.motion.surface.morph as sm
import meshopt_toolkit.riemannian.levenberg_marquardt as lm
from meshopt_toolkit.least_squares import step_length_damping
from meshopt_toolkit.motion.surface.metric import BENDING, WEIGHT


@pytest.mark.parametrize("angle", [np.pi / 3, np.pi / 2])
def test_minimum_is_minpacks_each_step_a_decrease_and_the_damping_rule(monkeypatch, angle):
    V0, F = tube(6, 4, length=2.0)
    V1 = bent(V0, angle, length=2.0)
    problem = sm._PathProblem(V0, V1, F, WEIGHT, BENDING)
    K = 3
    start, _ = sm._initial_path(problem, V0, V1, F, np.linspace(0.0, 1.0, K + 1))
    steps = record_damped_steps(monkeypatch, lm)
    path, status, iterations, _, E0, _ = sm._minimize(problem, list(start), 60, 1e-13, None)
    assert iterations > 2 and status in ("converged", "stalled")

    def frames_of(x):
        return [V0] + list(x.reshape(K - 1, -1, 3)) + [V1]

    def residual(x):
        X = [problem.embed(Q) for Q in frames_of(x)]
        return np.concatenate([problem.segment(X[k], X[k + 1]) for k in range(K)])

    def jacobian(x):
        D = [problem.jacobian(Q) for Q in frames_of(x)]
        return sp.bmat([[D[j] if j == k + 1 else -D[j] if j == k else None
                         for j in range(1, K)] for k in range(K)]).toarray()

    energies = [E0]
    for damping, out in steps:
        if not out.accepted:
            break
        assert out.damping in [step_length_damping(damping * 10.0**a, out.length)
                               for a in range(4)]
        trial, _, E_t, _ = out.payload
        x = np.concatenate([Q.ravel() for Q in trial[1:-1]])
        assert E_t == pytest.approx(0.5 * float(residual(x) @ residual(x)), rel=1e-12)
        assert E_t < energies[-1]
        energies.append(E_t)
    x0 = np.concatenate([Q.ravel() for Q in start[1:-1]])
    peer = least_squares(residual, x0, jac=jacobian, method="lm", xtol=1e-15, ftol=1e-15,
                         gtol=1e-15)
    assert energies[-1] == pytest.approx(peer.cost, rel=1e-9)
    np.testing.assert_allclose(np.concatenate([Q.ravel() for Q in path[1:-1]]), peer.x,
                               atol=1e-6)
