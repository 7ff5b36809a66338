"""Safe expression evaluator: values, exact gradients, precedence, refused constructs."""

from __future__ import annotations

import builtins

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


# constant parts that are not finite: refused when parsing, with their text and column
NONFINITE_CONSTANTS = [
    ("1/0", "'1/0' is not finite (division by zero) at column 1"),
    ("0/0", "'0/0' is not finite (division by zero) at column 1"),
    ("x + 2*(1/(1-1))", "'1/(1-1)' is not finite (division by zero) at column 8"),
    ("2**10000", "'2**10000' is not finite (overflow or a domain error) at column 1"),
    ("exp(1000)*x", "'exp(1000)' is not finite (overflow or a domain error) at column 1"),
    ("1e308*10", "'1e308*10' is not finite (overflow or a domain error) at column 1"),
    ("log(-1)", "'log(-1)' is not finite (outside the domain of log) at column 1"),
    ("y + log(0)", "'log(0)' is not finite (outside the domain of log) at column 5"),
    ("sqrt(-1)", "'sqrt(-1)' is not finite (outside the domain of sqrt) at column 1"),
    ("(-8)**(1/3)", "'(-8)**(1/3)' is not finite (overflow or a domain error) at column 1"),
    ("1e400", "number too large (1e400) at column 1"),
    ("x**1e999", "number too large (1e999) at column 4"),
    ("9" * 400, "number too large (" + "9" * 37 + "...) at column 1"),
]


@pytest.mark.parametrize("text,message", NONFINITE_CONSTANTS,
                         ids=[t[0][:20] for t in NONFINITE_CONSTANTS])
def test_nonfinite_constants_refused_when_parsed(text, message):
    with pytest.raises(ExpressionError) as info:
        parse_expression(text)
    assert str(info.value) == message


@pytest.mark.parametrize("text", ["x/0", "(0*x)**-1", "log(x - 10)", "exp(1000*x)"])
def test_nonfinite_values_name_the_expression_and_point(text):
    X = np.array([[1.0, 0.5]])
    expr = parse_expression(text)
    for evaluate in (expr, expr.gradient, expr.value_and_gradient):
        with pytest.raises(ExpressionError,
                           match=r"of '.*' is not finite at \(x, y\) = \(1, 0.5\)"):
            evaluate(X)


_LEAVES = st.sampled_from(["x", "y", "0", "1", "2", "0.5", "1e300", "1e-300", "pi"])


def _combine(children):
    binary = st.tuples(children, st.sampled_from(["+", "-", "*", "/", "**"]), children).map(
        lambda t: f"({t[0]} {t[1]} {t[2]})")
    unary = st.tuples(st.sampled_from(["sin", "cos", "tan", "exp", "log", "sqrt", "abs", "-"]),
                      children).map(lambda t: f"{t[0]}({t[1]})")
    pair = st.tuples(st.sampled_from(["min", "max"]), children, children).map(
        lambda t: f"{t[0]}({t[1]}, {t[2]})")
    return binary | unary | pair


@settings(max_examples=300, deadline=None)
@given(text=st.recursive(_LEAVES, _combine, max_leaves=8))
def test_fuzz_only_expression_errors_or_finite_values(text):
    """Any expression of the grammar: a finite value and gradient, or an ExpressionError
    (never ZeroDivisionError, OverflowError, a warning or a non-finite number)."""
    X = np.array([[0.0, 0.0], [1.0, -1.0], [0.3, 0.7]])
    try:
        expr = parse_expression(text)
        v, g = expr.value_and_gradient(X)
    except ExpressionError as exc:
        assert "\n" not in str(exc)
        return
    assert np.isfinite(v).all() and np.isfinite(g).all()
    np.testing.assert_array_equal(expr(X), v)


# (text, value(x, y, z), gradient(x, y, z)) written out by hand with numpy
BATTERY_3D = [
    ("z", lambda x, y, z: z, lambda x, y, z: (0 * x, 0 * x, 1 + 0 * x)),
    ("x3*x - y", lambda x, y, z: z * x - y, lambda x, y, z: (z, -1 + 0 * x, x)),
    ("sin(x*z) + y**2", lambda x, y, z: np.sin(x * z) + y**2,
     lambda x, y, z: (z * np.cos(x * z), 2 * y, x * np.cos(x * z))),
    ("x + y", lambda x, y, z: x + y, lambda x, y, z: (1 + 0 * x, 1 + 0 * x, 0 * x)),
]


@pytest.mark.parametrize("text,f,g", BATTERY_3D)
def test_values_and_exact_gradients_in_3d(text, f, g, rng):
    X = rng.uniform(-1.0, 1.0, (40, 3))
    r = parse_expression(text)
    x, y, z = X.T
    np.testing.assert_allclose(r(X), f(x, y, z), rtol=1e-14, atol=1e-14)
    v, grad = r.value_and_gradient(X)
    assert grad.shape == (40, 3)
    np.testing.assert_allclose(grad, np.column_stack(g(x, y, z)), rtol=1e-13, atol=1e-14)
    np.testing.assert_array_equal(v, r(X))


def test_z_on_planar_points_is_an_expression_error():
    r = parse_expression("x + z")
    assert r.uses_z and not parse_expression("x*y").uses_z
    for call in (r, r.gradient, r.value_and_gradient):
        with pytest.raises(ExpressionError, match="z is not defined for a planar mesh"):
            call(np.zeros((3, 2)))
    # 2D expressions keep (M, 2) gradients
    assert parse_expression("x*y").gradient(np.ones((4, 2))).shape == (4, 2)


def test_nonfinite_value_in_3d_names_the_point():
    with pytest.raises(ExpressionError, match=r"\(x, y, z\) = \(0, 1, 0\)"):
        parse_expression("1/z")(np.array([[0.0, 1.0, 0.0]]))
