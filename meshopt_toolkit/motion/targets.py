"""Handle targets from files or expressions, for ``meshopt move`` and the move filter.

- a table: CSV rows ``index,x,y`` (a header line is allowed) or a ``.npy`` array (k, 3);
- a map: ``"X_EXPR; Y_EXPR"``, the new position of each selected boundary vertex as two
  expressions in its ``x, y`` (the whitelisted evaluator of :mod:`..expressions`), applied
  where ``WHERE`` holds (default: every boundary vertex); the other boundary vertices are
  handles that stay where they are. ``WHERE`` is one comparison or several joined by
  ``and``/``or``, each side an expression: ``"x**2 + y**2 < 0.25"``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import ExpressionError, InvalidMeshError, ReadError
from ..expressions import parse_expression
from ..mesh import PlanarMesh

_COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater,
            ast.GtE: np.greater_equal}
MAX_TABLE_BYTES = 512 * 2**20


def read_target_table(path: str | Path) -> tuple[IntArray, FloatArray]:
    """Handles and targets from a CSV (``index,x,y``) or ``.npy`` (k, 3) file."""
    path = Path(path)
    if not path.is_file():
        raise ReadError(f"{path}: not a regular file")
    if path.stat().st_size > MAX_TABLE_BYTES:
        raise ReadError(f"{path}: larger than {MAX_TABLE_BYTES // 2**20} MiB")
    try:
        if path.suffix.lower() == ".npy":
            table = np.load(path, allow_pickle=False)
        else:
            text = path.read_text(encoding="utf-8").splitlines()
            rows = [ln for ln in text if ln.strip() and not ln.lstrip().startswith("#")]
            if rows and not _is_number(rows[0].split(",")[0]):
                rows = rows[1:]  # header
            table = np.array([[float(v) for v in ln.split(",")] for ln in rows], dtype=float)
    except (ValueError, OSError) as exc:
        raise ReadError(f"{path}: cannot read targets: {exc}") from None
    table = np.asarray(table, dtype=float)
    if table.ndim != 2 or table.shape[1] != 3 or len(table) == 0:
        raise ReadError(f"{path}: expected rows 'index,x,y' (k × 3), got shape {table.shape}")
    index = table[:, 0]
    if not np.all(np.isfinite(index)) or np.any(index != np.round(index)):
        raise ReadError(f"{path}: the first column must hold vertex indices (integers)")
    return index.astype(np.int64), table[:, 1:]


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _naming(option: str, text: str, exc: ExpressionError) -> ExpressionError:
    """The error with the option and its text in front (once)."""
    message = str(exc)
    prefix = f"{option} {text!r}"
    return exc if message.startswith(prefix) else ExpressionError(f"{prefix}: {message}")


def _condition(text: str, X: FloatArray) -> np.ndarray:
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as exc:
        raise ExpressionError(f"--where {text!r}: {exc.msg}") from None
    except (RecursionError, MemoryError, ValueError):
        raise ExpressionError(f"--where {text!r}: too deeply nested") from None

    def evaluate(node) -> np.ndarray:
        if isinstance(node, ast.BoolOp):
            parts = [evaluate(v) for v in node.values]
            op = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
            out = parts[0]
            for p in parts[1:]:
                out = op(out, p)
            return out
        if isinstance(node, ast.Compare):
            left = parse_expression(ast.unparse(node.left))(X)
            out = np.ones(len(X), bool)
            for op, right_node in zip(node.ops, node.comparators):
                if type(op) not in _COMPARE:
                    raise ExpressionError(f"--where {text!r}: use <, <=, > or >=")
                right = parse_expression(ast.unparse(right_node))(X)
                out &= _COMPARE[type(op)](left, right)
                left = right
            return out
        raise ExpressionError(f"--where {text!r}: expected a comparison such as 'x < 0.5'")

    try:
        return evaluate(tree)
    except ExpressionError as exc:
        raise _naming("--where", text, exc) from None


def targets_from_map(mesh: PlanarMesh, mapping: str, where: str | None = None
                     ) -> tuple[IntArray, FloatArray]:
    """Handles (every boundary vertex) and targets from ``"X_EXPR; Y_EXPR"``."""
    parts = [p for p in mapping.split(";")]
    if len(parts) != 2 or not all(p.strip() for p in parts):
        raise ExpressionError(f"--map {mapping!r}: expected two expressions 'X_EXPR; Y_EXPR'")
    try:
        fx, fy = (parse_expression(p.strip()) for p in parts)
    except ExpressionError as exc:
        raise _naming("--map", mapping, exc) from None
    except (ZeroDivisionError, OverflowError, ValueError) as exc:
        raise ExpressionError(f"--map {mapping!r}: {exc}") from None
    handles = np.unique(mesh.boundary_edges)
    X = mesh.points[handles]
    selected = np.ones(len(handles), bool) if where is None else _condition(where, X)
    if not selected.any():
        raise InvalidMeshError(f"--where {where!r} selects no boundary vertex")
    targets = X.copy()
    with np.errstate(all="raise"):
        try:
            targets[selected, 0] = fx(X[selected])
            targets[selected, 1] = fy(X[selected])
        except (FloatingPointError, ZeroDivisionError, OverflowError) as exc:
            raise ExpressionError(f"--map {mapping!r}: {exc}") from None
    if not np.isfinite(targets).all():
        raise ExpressionError(f"--map {mapping!r}: not finite at some boundary vertex")
    return handles, targets
