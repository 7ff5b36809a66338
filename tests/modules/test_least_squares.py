"""The damped Gauss–Newton step (least_squares.py): the model decrease exact for linear
residuals, one undamped step to numpy's least-squares solution, a loop of damped steps to
scipy's Levenberg–Marquardt minimum, every accepted step a decrease, the damping raised
by ``increase`` per refused attempt and updated by the rules after an accepted one."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares

from meshopt_toolkit.descent import halvings
from meshopt_toolkit.least_squares import (STOP, damped_step, gain_ratio_damping,
                                           model_decrease, step_length_damping)


def _linear(seed, m=7, n=4):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(m, n)), rng.normal(size=m), rng.normal(size=n)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6))
def test_model_decrease_is_the_exact_decrease_of_a_linear_residual(seed):
    A, b, x = _linear(seed)
    s = np.random.default_rng(seed + 1).normal(size=x.size)

    def E(x):
        return 0.5 * float(np.sum((A @ x - b) ** 2))

    g = A.T @ (A @ x - b)
    assert model_decrease(g, s, A.T @ (A @ s)) == pytest.approx(E(x) - E(x + s), rel=1e-10,
                                                                 abs=1e-10)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6))
def test_an_undamped_step_of_a_linear_problem_is_numpys_least_squares_solution(seed):
    A, b, x = _linear(seed)
    g, H = A.T @ (A @ x - b), A.T @ A
    out = damped_step(lambda lam, attempt: np.linalg.solve(H + lam * np.eye(len(x)), -g),
                      lambda s, t: x + t * s, 0.0)
    assert out.accepted and out.length == 1.0
    np.testing.assert_allclose(out.payload, np.linalg.lstsq(A, b, rcond=None)[0], atol=1e-9)


def _fit_problem(seed):
    """Fit ``a e^{b t} + c`` to noisy samples: residuals and Jacobian."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, 20)
    y = 2.0 * np.exp(-1.3 * t) + 0.5 + 0.01 * rng.normal(size=t.size)

    def r(p):
        return p[0] * np.exp(p[1] * t) + p[2] - y

    def J(p):
        e = np.exp(p[1] * t)
        return np.column_stack([e, p[0] * t * e, np.ones_like(t)])

    return r, J


@settings(max_examples=15, deadline=None, derandomize=True, database=None)
@given(seed=st.integers(0, 10**6), start=st.floats(-0.5, 0.5))
@example(seed=0, start=0.020245775884746187)
def test_damped_steps_reach_scipys_minimum_each_one_a_decrease(seed, start):
    r, J = _fit_problem(seed)
    x, lam = np.array([1.0, start, 0.0]), 1e-3
    energies = [0.5 * float(r(x) @ r(x))]
    for _ in range(200):
        res, jac = r(x), J(x)
        g, H = jac.T @ res, jac.T @ jac
        if np.linalg.norm(g) < 1e-12:
            break

        def try_step(s, t, x=x, g=g, H=H, E=energies[-1]):
            E_t = 0.5 * float(r(x + s) @ r(x + s))
            return (x + s, (E - E_t) / model_decrease(g, s, H @ s)) if E_t < E else None

        out = damped_step(lambda lam, attempt, H=H, g=g: np.linalg.solve(
            H + lam * np.diag(np.diag(H)), -g), try_step, lam, attempts=30,
            update=lambda lam, t, p: gain_ratio_damping(lam, p[1]))
        if not out.accepted:
            break
        x, lam = out.payload[0], out.damping
        energies.append(0.5 * float(r(x) @ r(x)))
    assert all(b < a for a, b in zip(energies, energies[1:]))
    # scipy's Levenberg–Marquardt and trust-region fits, those that converged (its LM can
    # run out of evaluations on an exponential diverging to ±4000, seed 0)
    peers = [least_squares(r, np.array([1.0, start, 0.0]), jac=J, method=method, xtol=1e-15,
                           ftol=1e-15, gtol=1e-15) for method in ("lm", "trf")]
    peer = min((p for p in peers if p.status > 0), key=lambda p: p.cost)
    assert energies[-1] == pytest.approx(peer.cost, rel=1e-9)
    np.testing.assert_allclose(x, peer.x, rtol=1e-5, atol=1e-7)


def test_each_refused_attempt_raises_the_damping_and_a_none_solve_spends_one():
    seen = []

    def solve(lam, attempt):
        seen.append((lam, attempt))
        return None if attempt == 1 else np.ones(2)

    out = damped_step(solve, lambda s, t: "ok" if len(seen) == 4 else None, 0.5,
                      attempts=6, increase=10.0, update=lambda lam, t, p: lam / 7.0)
    assert seen == [(0.5, 0), (5.0, 1), (50.0, 2), (500.0, 3)]
    assert out.accepted and out.payload == "ok" and out.damping == 500.0 / 7.0
    out = damped_step(lambda lam, a: np.ones(2), lambda s, t: None, 1.0, attempts=3)
    assert out.outcome == "refused" and out.damping == 64.0


def test_trials_follow_the_lengths_and_stop_and_stationary_end_the_step():
    tried = []

    def try_step(s, t):
        tried.append(t)
        return "ok" if t < 0.3 else None

    out = damped_step(lambda lam, a: np.ones(1), try_step, 1.0,
                      lengths=lambda s: halvings(0.8, count=3))
    assert tried == [0.8, 0.4, 0.2] and out.length == 0.2 and out.damping == 1.0
    out = damped_step(lambda lam, a: np.ones(1), lambda s, t: STOP, 1.0, attempts=5)
    assert out.outcome == "stopped" and not out.accepted
    calls = []
    out = damped_step(lambda lam, a: np.ones(1), lambda s, t: calls.append(t), 1.0,
                      stationary=lambda s, lam: True)
    assert out.outcome == "stationary" and calls == []


@settings(max_examples=50, deadline=None)
@given(lam=st.floats(1e-14, 1e6), ratio=st.floats(-10.0, 10.0))
def test_the_damping_rules(lam, ratio):
    new = gain_ratio_damping(lam, ratio, decrease=0.25)
    expected = lam * 0.25 if ratio > 0.75 else lam if ratio > 0.25 else 2.0 * lam
    assert new == max(expected, 1e-12)
    assert step_length_damping(lam, 1.0) == max(lam / 3.0, 1e-8)
    assert step_length_damping(lam, 0.5) == 2.0 * lam
