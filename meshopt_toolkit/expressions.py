"""A safe evaluator for user expressions in ``x, y`` (and ``z``) with exact gradients.

``parse_expression("2.5*(x1 + 0.4 - x2**2)**2 + x1**2 + x2**2 - 1")`` returns an
:class:`Expression` ``r`` with ``r(X) -> (M,)`` and ``r.gradient(X) -> (M, 2)`` for points
``X`` of shape ``(M, 2)`` (or ``(M, 3)`` for ``x, y, z``, with ``(M, 3)`` gradients).
The gradient is exact: forward-mode differentiation over the
syntax tree, no finite differences.

Grammar (Python's own syntax and precedence, parsed by :func:`ast.parse` in ``"eval"``
mode, then checked against an explicit whitelist of node types; the text is never passed
to ``eval``, ``exec`` or ``compile``):

- numbers (``2``, ``0.5``, ``1e-3``); constants ``pi``, ``e``;
- variables ``x``, ``y``, ``z``, ``x1``, ``x2``, ``x3`` (``x = x1``, ``y = x2``,
  ``z = x3``; ``z`` is refused at planar points ``(M, 2)``);
- ``+ - * / **`` and unary ``+ -`` (``**`` is right-associative and binds tighter than
  unary minus: ``-2**2 == -4``), parentheses;
- functions ``sin cos tan exp log sqrt abs`` (one argument), ``min max`` (two).

Anything else is an :class:`~meshopt_toolkit.errors.ExpressionError` naming the construct
and its column. So is a constant part that is not finite (``1/0``, ``exp(1000)``,
``log(-1)``, ``1e400``): it is evaluated once when parsing and refused with its text and
column. Values that are not finite at some point (``x/0``) are reported when evaluated,
naming the expression and the point; no other exception ever leaves the evaluator.
``abs``, ``min`` and ``max`` are differentiated almost everywhere
(``abs'(0) = 0``; ``min``/``max`` take the first argument's gradient on ties).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ._typing import FloatArray
from .errors import ExpressionError

__all__ = ["MAX_DEPTH", "MAX_LENGTH", "SHOWN_CHARS", "Expression", "parse_expression",
           "quoted"]

#: longest accepted expression text (characters)
MAX_LENGTH = 1000
#: deepest accepted syntax tree
MAX_DEPTH = 64
#: user text (expressions, paths) longer than this is cut where a message shows it
SHOWN_CHARS = 80

_VARIABLES = {"x": 0, "x1": 0, "y": 1, "x2": 1, "z": 2, "x3": 2}
_CONSTANTS = {"pi": np.pi, "e": np.e}
_UNARY = ("sin", "cos", "tan", "exp", "log", "sqrt", "abs")
_BINARY = ("min", "max")
_ALLOWED_NAMES = ", ".join([*_VARIABLES, *_CONSTANTS])
_ALLOWED_FUNCS = ", ".join([*_UNARY, *_BINARY])

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_UNOPS = {ast.USub: "-", ast.UAdd: "+"}

# user-facing names of refused node types
_REFUSED = {
    ast.Attribute: "attribute access is",
    ast.Subscript: "subscripts are",
    ast.Lambda: "lambda is",
    ast.IfExp: "conditional expressions are",
    ast.Compare: "comparisons are",
    ast.BoolOp: "boolean operators are",
    ast.List: "lists are",
    ast.Tuple: "tuples are",
    ast.Set: "sets are",
    ast.Dict: "dicts are",
    ast.ListComp: "comprehensions are",
    ast.SetComp: "comprehensions are",
    ast.DictComp: "comprehensions are",
    ast.GeneratorExp: "comprehensions are",
    ast.JoinedStr: "strings are",
    ast.NamedExpr: "assignment expressions are",
    ast.Starred: "starred arguments are",
    ast.Await: "await is",
    ast.Yield: "yield is",
    ast.YieldFrom: "yield is",
    ast.Slice: "slices are",
}


# ----------------------------------------------------------------------------- nodes
# The checked tree is rebuilt from these small immutable records; evaluation walks them.


#: the right-hand side of the thesis' experiments (SPEC §6), the default of ``meshopt
#: optimize --rhs`` and of :class:`~meshopt_toolkit.fem.poisson.PoissonObjective` ("default")
DEFAULT_RHS = "2.5*(x1 + 0.4 - x2**2)**2 + x1**2 + x2**2 - 1"

@dataclass(frozen=True)
class _Num:
    value: np.float64  # numpy scalar: 1/0 gives inf (checked), never ZeroDivisionError


@dataclass(frozen=True)
class _Var:
    index: int  # 0 = x, 1 = y, 2 = z


@dataclass(frozen=True)
class _Unary:
    op: str  # "-", "+"
    arg: object


@dataclass(frozen=True)
class _Bin:
    op: str  # + - * / **
    left: object
    right: object


@dataclass(frozen=True)
class _Call:
    func: str
    args: tuple


def quoted(text: str, limit: int = SHOWN_CHARS) -> str:
    """``repr(text)`` for a message; longer than ``limit`` characters, its first ``limit``
    and the length: ``'x+x+x'… (100000 chars)``."""
    text = str(text)
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}… ({len(text)} chars)"


def _err(msg: str, node: ast.AST | None = None) -> ExpressionError:
    col = getattr(node, "col_offset", None)
    where = f" at column {col + 1}" if col is not None else ""
    return ExpressionError(f"{msg}{where}")


def _depth(tree: ast.AST) -> int:
    """Depth of an AST, computed without recursion."""
    deepest = 0
    stack = [(tree, 1)]
    while stack:
        node, d = stack.pop()
        deepest = max(deepest, d)
        if deepest > MAX_DEPTH:
            return deepest
        stack.extend((child, d + 1) for child in ast.iter_child_nodes(node))
    return deepest


def _source(node: ast.AST, text: str) -> str:
    """The text of ``node`` in ``text``, shortened for messages."""
    seg = ast.get_source_segment(text, node) or ast.unparse(node)
    return seg if len(seg) <= 40 else seg[:37] + "..."


def _operator(table: dict, node: ast.AST, hint: str = ""):
    """The function of ``node``'s operator in ``table``; one not there is refused."""
    op = table.get(type(node.op))
    if op is None:
        raise _err(f"operator {type(node.op).__name__} is not allowed{hint}", node)
    return op


def _convert(node: ast.AST, text: str):
    """Whitelist check and conversion of one AST node (recursion depth is bounded).

    A constant subtree (no ``x``, ``y``) is evaluated once here: a non-finite one (``1/0``,
    ``exp(1000)``, ``log(-1)``) is refused with its text and column, before any point is
    evaluated.
    """
    if isinstance(node, ast.Expression):
        return _convert(node.body, text)
    out = _convert_node(node, text)
    if not isinstance(out, (_Num, _Var)) and _is_constant(out):
        with np.errstate(all="ignore"):
            value = _value(out, np.zeros((1, 2)))
        if not np.isfinite(value):
            raise _err(f"{_source(node, text)!r} is not finite ({_why(out)})", node)
    return out


def _why(node) -> str:
    """A guess at why the constant ``node`` is not finite, for the message."""
    if isinstance(node, _Bin) and node.op == "/":
        with np.errstate(all="ignore"):
            if _value(node.right, np.zeros((1, 2))) == 0:
                return "division by zero"
    if isinstance(node, _Call) and node.func in ("log", "sqrt"):
        return "outside the domain of " + node.func
    return "overflow or a domain error"


def _convert_node(node: ast.AST, text: str):
    if isinstance(node, ast.Constant):
        v = node.value
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            if isinstance(v, (str, bytes)):
                raise _err("strings are not allowed", node)
            raise _err(f"the constant {v!r} is not allowed", node)
        try:
            value = np.float64(float(v))
        except OverflowError:
            value = np.float64(np.inf)
        if not np.isfinite(value):
            raise _err(f"number too large ({_source(node, text)})", node)
        return _Num(value)
    if isinstance(node, ast.Name):
        if node.id in _VARIABLES:
            return _Var(_VARIABLES[node.id])
        if node.id in _CONSTANTS:
            return _Num(np.float64(_CONSTANTS[node.id]))
        if node.id in _UNARY or node.id in _BINARY:
            raise _err(f"function {node.id!r} must be called", node)
        raise ExpressionError(
            f"unknown name {node.id!r} at column {node.col_offset + 1}; allowed: {_ALLOWED_NAMES}"
        )
    if isinstance(node, ast.BinOp):
        return _Bin(_operator(_BINOPS, node, "; use + - * / **"), _convert(node.left, text),
                    _convert(node.right, text))
    if isinstance(node, ast.UnaryOp):
        return _Unary(_operator(_UNOPS, node), _convert(node.operand, text))
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name):
            raise _err("only calls of named functions are allowed", node)
        name = node.func.id
        if name not in _UNARY and name not in _BINARY:
            raise ExpressionError(
                f"unknown function {name!r} at column {node.col_offset + 1}; "
                f"allowed: {_ALLOWED_FUNCS}"
            )
        if node.keywords:
            raise _err(f"{name}() takes no keyword arguments", node)
        want = 1 if name in _UNARY else 2
        if len(node.args) != want:
            raise _err(f"{name}() takes {want} argument{'s' if want > 1 else ''}, "
                       f"got {len(node.args)}", node)
        return _Call(name, tuple(_convert(a, text) for a in node.args))
    kind = _REFUSED.get(type(node), f"{type(node).__name__} nodes are")
    raise _err(f"{kind} not allowed", node)


def parse_expression(text: str) -> Expression:
    """Parse and check an expression in ``x, y, z`` (see the module docstring for the grammar).

    Parameters
    ----------
    text : the expression, at most :data:`MAX_LENGTH` characters

    Returns
    -------
    Expression

    Raises
    ------
    ExpressionError
        Syntax errors, refused constructs, unknown names or functions, too long or too
        deeply nested input, constant parts that are not finite (``1/0``). The message
        names the problem and its column.
    """
    if not isinstance(text, str):
        raise ExpressionError(f"an expression must be a string, not {type(text).__name__}")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"expression too long: {len(text)} characters (at most {MAX_LENGTH})")
    if not text.strip():
        raise ExpressionError("empty expression")
    level = np.cumsum([(c in "([{") - (c in ")]}") for c in text]).max(initial=0)
    if level > MAX_DEPTH:
        raise ExpressionError(
            f"expression too deeply nested: {level} levels of brackets (at most {MAX_DEPTH})"
        )
    text = text.strip()
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        col = f" at column {exc.offset}" if exc.offset else ""
        detail = "" if exc.msg in ("invalid syntax", "") else f": {exc.msg}"
        raise ExpressionError(f"invalid syntax{col}{detail}") from None
    except (RecursionError, MemoryError, ValueError):
        raise ExpressionError(f"expression too deeply nested (at most {MAX_DEPTH} levels)") from None
    if _depth(tree) > MAX_DEPTH:
        raise ExpressionError(f"expression too deeply nested (at most {MAX_DEPTH} levels)")
    return Expression(text, _convert(tree, text))


# ------------------------------------------------------------------------- evaluation


# Values are float scalars (constant subtrees) or (M,) arrays; gradients are 0.0 (zero),
# (1, d) unit rows, (M, 1) or (M, d) arrays (d = 2 or 3, the points' dimension).
# Broadcasting combines them, so constants and integer powers stay scalar operations;
# the public methods broadcast the results.


def _col(v):
    """``v`` as a column for products with gradients."""
    return v[:, None] if np.ndim(v) == 1 else v


def _apply(func: str, a):
    if func == "min":
        return np.minimum(*a)
    if func == "max":
        return np.maximum(*a)
    return getattr(np, func)(a[0])


def _value(node, X: FloatArray):
    if isinstance(node, _Num):
        return node.value
    if isinstance(node, _Var):
        return X[:, node.index]
    if isinstance(node, _Unary):
        v = _value(node.arg, X)
        return -v if node.op == "-" else v
    if isinstance(node, _Bin):
        a, b = _value(node.left, X), _value(node.right, X)
        if node.op == "+":
            return a + b
        if node.op == "-":
            return a - b
        if node.op == "*":
            return a * b
        if node.op == "/":
            return a / b
        return np.power(a, b)
    return _apply(node.func, [_value(arg, X) for arg in node.args])


def _is_constant(node) -> bool:
    if isinstance(node, _Num):
        return True
    if isinstance(node, _Var):
        return False
    if isinstance(node, _Unary):
        return _is_constant(node.arg)
    if isinstance(node, _Bin):
        return _is_constant(node.left) and _is_constant(node.right)
    return all(_is_constant(a) for a in node.args)




def _forward(node, X: FloatArray):
    """Value and exact gradient by forward-mode differentiation (see the note above)."""
    if isinstance(node, _Num):
        return node.value, 0.0
    if isinstance(node, _Var):
        unit = np.zeros((1, X.shape[1]))
        unit[0, node.index] = 1.0
        return X[:, node.index], unit
    if isinstance(node, _Unary):
        v, g = _forward(node.arg, X)
        return (-v, -g) if node.op == "-" else (v, g)
    if isinstance(node, _Bin):
        a, da = _forward(node.left, X)
        b, db = _forward(node.right, X)
        if node.op == "+":
            return a + b, da + db
        if node.op == "-":
            return a - b, da - db
        if node.op == "*":
            return a * b, da * _col(b) + _col(a) * db
        if node.op == "/":
            return a / b, (da * _col(b) - _col(a) * db) / _col(b * b)
        v = np.power(a, b)
        if np.ndim(b) == 0:  # constant exponent: d(a^c) = c a^(c-1) da, 0 when c == 0
            c = float(b)
            return v, (0.0 if c == 0.0 else _col(c * np.power(a, c - 1.0)) * da)
        # d(a^b) = b a^(b-1) da + a^b log(a) db; the first term vanishes where b == 0
        safe_b = np.where(b == 0, 1.0, b)
        d_base = np.where(b == 0, 0.0, safe_b * np.power(a, safe_b - 1.0))
        return v, _col(d_base) * da + _col(v * np.log(a)) * db
    if node.func in _BINARY:
        (a, da), (b, db) = (_forward(arg, X) for arg in node.args)
        pick_a = a <= b if node.func == "min" else a >= b
        # the value as in _apply: a NaN argument (a domain error) gives NaN, never the other
        return _apply(node.func, (a, b)), np.where(_col(pick_a), da, db)
    a, da = _forward(node.args[0], X)
    f = node.func
    if f == "sin":
        v, d = np.sin(a), np.cos(a)
    elif f == "cos":
        v, d = np.cos(a), -np.sin(a)
    elif f == "tan":
        v = np.tan(a)
        d = 1.0 + v * v
    elif f == "exp":
        v = np.exp(a)
        d = v
    elif f == "log":
        v, d = np.log(a), 1.0 / a
    elif f == "sqrt":
        v = np.sqrt(a)
        d = 0.5 / v
    else:  # abs
        v, d = np.abs(a), np.sign(a)
    return v, _col(d) * da


def _max_index(node) -> int:
    """The largest variable index in ``node`` (-1: none)."""
    if isinstance(node, _Num):
        return -1
    if isinstance(node, _Var):
        return node.index
    if isinstance(node, _Unary):
        return _max_index(node.arg)
    if isinstance(node, _Bin):
        return max(_max_index(node.left), _max_index(node.right))
    return max(_max_index(a) for a in node.args)


class Expression:
    """A checked expression ``r(x, y)`` or ``r(x, y, z)``; create it with
    :func:`parse_expression`.

    Calling it on ``X (M, 2)`` or ``X (M, 3)`` returns ``(M,)`` values; :meth:`gradient`
    returns the exact ``(M, 2)`` or ``(M, 3)`` gradient. An expression in ``z`` at planar
    points ``(M, 2)`` is an :class:`ExpressionError`. Non-finite results (``log`` of a
    negative number, division by zero, overflow) raise :class:`ExpressionError` naming the
    first offending point.
    """

    def __init__(self, text: str, tree) -> None:
        self.text = text
        self._tree = tree
        self.is_constant = _is_constant(tree)
        #: True when the expression uses ``z`` (it needs points ``(M, 3)``)
        self.uses_z = _max_index(tree) >= 2

    def __repr__(self) -> str:
        return f"Expression({self.text!r})"

    @contextmanager
    def _arithmetic(self) -> Iterator[None]:
        """Any arithmetic exception left (none is expected: constants are numpy scalars)
        becomes an :class:`ExpressionError` naming the expression."""
        try:
            yield
        except ArithmeticError as exc:
            raise ExpressionError(f"{quoted(self.text)} cannot be evaluated: {exc}") from None

    def _points(self, X) -> FloatArray:
        """``X`` as ``(M, 2)`` or ``(M, 3)`` floats, refused when ``z`` is used on 2D."""
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] not in (2, 3):
            raise ExpressionError("expressions are evaluated at points of shape (M, 2) or "
                                  f"(M, 3), got {X.shape}")
        if self.uses_z and X.shape[1] == 2:
            raise ExpressionError(f"{quoted(self.text)}: z is not defined for a planar mesh")
        return X

    def _check(self, v: FloatArray, X: FloatArray, what: str) -> FloatArray:
        bad = ~np.isfinite(v)
        if bad.any():
            i = int(np.flatnonzero(bad.reshape(len(X), -1).any(axis=1))[0])
            names = "x, y" if X.shape[1] == 2 else "x, y, z"
            raise ExpressionError(
                f"{what} of {quoted(self.text)} is not finite at ({names}) = "
                f"({', '.join(f'{c:.6g}' for c in X[i])})"
            )
        return v

    def __call__(self, X) -> FloatArray:
        """Values ``(M,)`` at points ``X (M, 2)`` or ``(M, 3)``."""
        X = self._points(X)
        with np.errstate(all="ignore"), self._arithmetic():
            v = np.array(np.broadcast_to(_value(self._tree, X), (len(X),)), dtype=float)
        return self._check(v, X, "value")

    def value_and_gradient(self, X) -> tuple[FloatArray, FloatArray]:
        """Values ``(M,)`` and exact gradients ``(M, d)`` in one pass (``d = X.shape[1]``)."""
        X = self._points(X)
        with np.errstate(all="ignore"), self._arithmetic():
            v, g = _forward(self._tree, X)
            v = np.array(np.broadcast_to(v, (len(X),)), dtype=float)
            g = np.array(np.broadcast_to(g, X.shape), dtype=float)
        return self._check(v, X, "value"), self._check(g, X, "gradient")

    def gradient(self, X) -> FloatArray:
        """Exact gradients ``(M, d)`` at points ``X (M, d)``, ``d`` = 2 or 3."""
        return self.value_and_gradient(X)[1]
