"""Safe expression evaluator: values, exact gradients, precedence, refused constructs."""

from __future__ import annotations

import builtins

import numpy as np
import pytest

from meshopt_toolkit.errors import ExpressionError
from meshopt_toolkit.expressions import MAX_LENGTH, parse_expression


@pytest.fixture
def X(rng):
    # points in (0.1, 1.1) x (-0.6, 0.9): log/sqrt arguments below stay positive
    return np.column_stack([rng.uniform(0.1, 1.1, 50), rng.uniform(-0.6, 0.9, 50)])


# (text, value(x, y), gradient(x, y)) written out by hand with numpy
BATTERY = [
    ("x", lambda x, y: x, lambda x, y: (1 + 0 * x, 0 * x)),
    ("x2", lambda x, y: y, lambda x, y: (0 * x, 1 + 0 * x)),
    ("3", lambda x, y: 3 + 0 * x, lambda x, y: (0 * x, 0 * x)),
    ("1e-3*x1", lambda x, y: 1e-3 * x, lambda x, y: (1e-3 + 0 * x, 0 * x)),
    ("x*y - y/x", lambda x, y: x * y - y / x, lambda x, y: (y + y / x**2, x - 1 / x)),
    ("-x**2 + +y", lambda x, y: -(x**2) + y, lambda x, y: (-2 * x, 1 + 0 * x)),
    ("x**y", lambda x, y: x**y, lambda x, y: (y * x ** (y - 1), x**y * np.log(x))),
    ("2**x", lambda x, y: 2**x, lambda x, y: (2**x * np.log(2), 0 * x)),
    ("y**3", lambda x, y: y**3, lambda x, y: (0 * x, 3 * y**2)),
    ("y**0", lambda x, y: 1 + 0 * y, lambda x, y: (0 * x, 0 * x)),
    ("sin(x)*cos(y)", lambda x, y: np.sin(x) * np.cos(y),
     lambda x, y: (np.cos(x) * np.cos(y), -np.sin(x) * np.sin(y))),
    ("tan(x*y)", lambda x, y: np.tan(x * y),
     lambda x, y: (y / np.cos(x * y) ** 2, x / np.cos(x * y) ** 2)),
    ("exp(-x*y)", lambda x, y: np.exp(-x * y),
     lambda x, y: (-y * np.exp(-x * y), -x * np.exp(-x * y))),
    ("log(x) + sqrt(x + y**2)", lambda x, y: np.log(x) + np.sqrt(x + y**2),
     lambda x, y: (1 / x + 0.5 / np.sqrt(x + y**2), y / np.sqrt(x + y**2))),
    ("abs(y)", lambda x, y: np.abs(y), lambda x, y: (0 * x, np.sign(y))),
    ("min(x, y)", lambda x, y: np.minimum(x, y),
     lambda x, y: ((x <= y) * 1.0, (x > y) * 1.0)),
    ("max(x**2, y)", lambda x, y: np.maximum(x**2, y),
     lambda x, y: ((x**2 >= y) * 2 * x, (x**2 < y) * 1.0)),
    ("pi*e", lambda x, y: np.pi * np.e + 0 * x, lambda x, y: (0 * x, 0 * x)),
    ("2.5*(x1 + 0.4 - x2**2)**2 + x1**2 + x2**2 - 1",
     lambda x, y: 2.5 * (x + 0.4 - y**2) ** 2 + x**2 + y**2 - 1,
     lambda x, y: (5 * (x + 0.4 - y**2) + 2 * x, -10 * y * (x + 0.4 - y**2) + 2 * y)),
]


@pytest.mark.parametrize("text,f,g", BATTERY, ids=[b[0] for b in BATTERY])
def test_values_and_exact_gradients(text, f, g, X):
    expr = parse_expression(text)
    x, y = X.T
    np.testing.assert_allclose(expr(X), f(x, y), rtol=1e-14, atol=1e-14)
    gx, gy = g(x, y)
    want = np.column_stack([np.broadcast_to(gx, x.shape), np.broadcast_to(gy, x.shape)])
    np.testing.assert_allclose(expr.gradient(X), want, rtol=1e-13, atol=1e-13)
    v, grad = expr.value_and_gradient(X)
    assert v.shape == (len(X),) and grad.shape == (len(X), 2)


def test_precedence_as_in_python(X):
    one = np.zeros((1, 2))
    assert parse_expression("-2**2")(one)[0] == -4
    assert parse_expression("2**3**2")(one)[0] == 512
    assert parse_expression("2*3+4/8-1")(one)[0] == 5.5
    assert parse_expression("(2+3)*4")(one)[0] == 20
    assert parse_expression("2**-1")(one)[0] == 0.5


def test_nonfinite_results_are_reported():
    with pytest.raises(ExpressionError, match="not finite at"):
        parse_expression("log(x)")(np.array([[1.0, 0.0], [-1.0, 0.0]]))
    with pytest.raises(ExpressionError, match="gradient .* not finite"):
        parse_expression("sqrt(x)").gradient(np.array([[0.0, 0.0]]))


REFUSED = [
    ("__import__('os')", "unknown function '__import__'"),
    ("x.__class__", "attribute access"),
    ("open('f')", "unknown function 'open'"),
    ("[1]", "lists"),
    ("lambda: 1", "lambda"),
    ('"a"', "strings"),
    ("x if x else y", "conditional"),
    ("1;2", "invalid syntax"),
    ("foo(x)", "unknown function 'foo'"),
    ("os", "unknown name 'os' at column 1; allowed: x"),
    ("x + os", "unknown name 'os' at column 5"),
    ("x[0]", "subscripts"),
    ("[i for i in x]", "comprehensions"),
    ("x == 1", "comparisons"),
    ("x and y", "boolean"),
    ("x // 2", "FloorDiv"),
    ("True", "constant True"),
    ("1j", "constant 1j"),
    ("sin(x, y)", "takes 1 argument"),
    ("min(x)", "takes 2 arguments"),
    ("sin", "must be called"),
    ("sin(x=1)", "keyword"),
    ("(x := 1)", "assignment"),
    ("x" * (MAX_LENGTH + 9000), "too long"),
    ("(" * 200 + "x" + ")" * 200, "too deeply nested"),
    ("-" * 500 + "x", "too deeply nested"),
    ("", "empty"),
]


@pytest.mark.parametrize("text,message", REFUSED, ids=[r[0][:20] for r in REFUSED])
def test_refused_constructs(text, message, monkeypatch):
    def boom(*args, **kwargs):
        raise AssertionError("the evaluator executed user code")

    monkeypatch.setattr(builtins, "open", boom)
    monkeypatch.setattr(builtins, "__import__", boom)
    with pytest.raises(ExpressionError, match=message) as info:
        parse_expression(text)
    assert "\n" not in str(info.value)


def test_not_a_string():
    with pytest.raises(ExpressionError):
        parse_expression(3)  # type: ignore[arg-type]


def test_points_shape_checked():
    with pytest.raises(ExpressionError, match=r"\(M, 2\)"):
        parse_expression("x")(np.zeros(3))
