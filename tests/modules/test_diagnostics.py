"""The Taylor diagnostics detect right and wrong derivatives."""

import numpy as np

from meshopt_toolkit.diagnostics import check_gradient, check_hvp


def f(x):
    return float(np.sum(np.sin(x) * x**2))


def grad(x):
    return np.cos(x) * x**2 + 2 * x * np.sin(x)


def hvp(x, v):
    return (-np.sin(x) * x**2 + 4 * x * np.cos(x) + 2 * np.sin(x)) * v


def test_correct_derivatives_have_orders_2_and_3(rng):
    x = rng.standard_normal((5, 2))
    g = check_gradient(f, grad, x, rng=1)
    h = check_hvp(f, grad, hvp, x, rng=1)
    assert g.passed and abs(g.order - 2) < 0.2, g
    assert h.passed and abs(h.order - 3) < 0.2, h


def test_wrong_derivatives_are_caught(rng):
    x = rng.standard_normal((5, 2))
    g = check_gradient(f, lambda x: 1.01 * grad(x), x, rng=1)
    h = check_hvp(f, grad, lambda x, v: 0.9 * hvp(x, v), x, rng=1)
    assert not g.passed and abs(g.order - 1) < 0.2, g
    assert not h.passed and abs(h.order - 2) < 0.2, h
