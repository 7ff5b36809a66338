"""The tet least squares (motion.tets.least_squares.minimize, the undamped configuration of
least_squares.damped_step): Gauss–Newton's minimum equals scipy's BFGS minimum of the same
energy, and every accepted step lowers the energy by Armijo's test from the first of the
halvings whose trial passes it."""

from __future__ import annotations

import numpy as np
import pytest
from motion_helpers import record_damped_steps
from scipy.optimize import minimize as scipy_minimize
from test_tet_move import cube_tets

import meshopt_toolkit.motion.tets.least_squares as ls
from meshopt_toolkit.cells.base import lumped_mass
from meshopt_toolkit.descent import sufficient_decrease
from meshopt_toolkit.motion.engine.similarity_3d import tet_boundary_faces
from meshopt_toolkit.motion.tets.distortion import TetDistortion


@pytest.mark.parametrize("seed", [0, 1])
def test_gauss_newton_minimum_is_scipys_and_every_step_armijos(monkeypatch, seed):
    P, T = cube_tets(3, jitter=0.3, seed=seed)
    handles = np.unique(tet_boundary_faces(T))
    problem = ls.Problem.build(TetDistortion(P, T), 1.5, lumped_mass(P, T), handles)
    anchor = 0.1 * np.random.default_rng(seed).standard_normal((len(T), 7))
    ones, free = np.ones(len(T)), problem.pattern.free
    steps = record_damped_steps(monkeypatch, ls)
    res = ls.minimize(problem, P, P, anchor, rtol=1e-8, max_iterations=100)
    assert res.gradient_ratio <= 1e-8 and steps

    def lift(x):
        out = P.copy()
        out.reshape(-1)[free] = x
        return out

    Q = P
    for _, out in steps:
        if not out.accepted:
            break
        E = problem.energy(Q, P, anchor, ones)
        slope = float(out.step @ problem.normal_equations(Q, P, anchor, ones, False)[0])
        trial, E_t = out.payload
        assert E_t == problem.energy(trial, P, anchor, ones)
        assert sufficient_decrease(E_t, E, out.length, slope) and E_t <= E
        if out.length < 1.0:  # the trial twice as long failed the test
            longer = lift(Q.reshape(-1)[free] + 2 * out.length * out.step)
            assert not sufficient_decrease(problem.energy(longer, P, anchor, ones), E,
                                           2 * out.length, slope)
        Q = trial
    np.testing.assert_array_equal(Q, res.points)
    assert res.energy < problem.energy(P, P, anchor, ones)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # trials may invert
        peer = scipy_minimize(lambda x: problem.energy(lift(x), P, anchor, ones),
                              P.reshape(-1)[free], jac=lambda x: problem.normal_equations(lift(x), P, anchor, ones,
                                                                     False)[0],
                              method="BFGS", options={"maxiter": 5000, "gtol": 1e-12})
    assert res.energy == pytest.approx(peer.fun, rel=1e-10)
    np.testing.assert_allclose(res.points.reshape(-1)[free], peer.x, atol=1e-6)
