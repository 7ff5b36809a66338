"""The shared descent steps (descent.py): backtracking over halved steps, Armijo's test,
and L-BFGS against closed-form minima, its iterates kept admissible."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.descent import backtrack, halvings, minimize_lbfgs, sufficient_decrease


def test_halvings_count_and_floor():
    assert list(halvings(count=4)) == [1.0, 0.5, 0.25, 0.125]
    assert list(halvings(2.0, above=0.3)) == [2.0, 1.0, 0.5]
    assert list(halvings(count=0)) == []


def test_backtrack_returns_the_first_accepted_step_and_its_payload():
    tried = []

    def try_step(t):
        tried.append(t)
        return f"ok {t}" if t <= 0.3 else None

    assert backtrack(try_step, halvings(count=10)) == (0.25, "ok 0.25")
    assert tried == [1.0, 0.5, 0.25]
    assert backtrack(lambda t: None, halvings(count=5)) is None


def test_sufficient_decrease_is_armijos_test():
    assert sufficient_decrease(0.9, 1.0, 1.0, -1.0)
    assert not sufficient_decrease(1.0, 1.0, 1.0, -1.0)
    assert not sufficient_decrease(np.inf, 1.0, 1e-3, -1.0)
    assert not sufficient_decrease(np.nan, 1.0, 1e-3, -1.0)
    assert sufficient_decrease(0.5, 1.0, 1.0, -1.0, c1=0.4)
    assert not sufficient_decrease(0.5, 1.0, 1.0, -1.0, c1=0.6)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(2, 8))
def test_lbfgs_finds_the_minimum_of_a_convex_quadratic(seed, n):
    """``½ uᵀAu − bᵀu`` with ``A`` SPD: the minimizer ``A⁻¹b`` (closed form)."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(n, n))
    A = B @ B.T + n * np.eye(n)
    b = rng.normal(size=n)
    u = minimize_lbfgs(lambda u: (0.5 * u @ A @ u - b @ u, A @ u - b), np.zeros(n), 200,
                       first_step=0.1)
    np.testing.assert_allclose(u, np.linalg.solve(A, b), atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6), wall=st.floats(0.05, 0.9))
def test_lbfgs_iterates_never_leave_the_admissible_set(seed, wall):
    """The unconstrained minimum lies past the wall ``u_0 ≤ wall``: every objective call
    that is accepted is admissible, so the result is, and it is no worse than the start."""
    rng = np.random.default_rng(seed)
    target = np.r_[1.0 + rng.random(), rng.normal(size=2)]
    seen = []

    def objective(u):
        return 0.5 * np.sum((u - target) ** 2), u - target

    def admissible(u):
        seen.append(u[0])
        return u[0] <= wall

    u = minimize_lbfgs(objective, np.zeros(3), 50, first_step=0.5, admissible=admissible)
    assert u[0] <= wall
    assert objective(u)[0] <= objective(np.zeros(3))[0]
