"""Handle targets from files or expressions, for ``meshopt move`` and the move filter.

- a table: CSV rows ``index,x,y`` (a header line is allowed) or a ``.npy`` array (k, 3);
  for a tetrahedral mesh rows ``index,x,y,z`` or (k, 4); :func:`fix_boundary` adds the
  boundary vertices the table does not list as handles that stay where they are
  (``--free-boundary`` leaves them free instead);
- a map: ``"X_EXPR; Y_EXPR"``, the new position of each selected vertex as two
  expressions in its ``x, y`` (the whitelisted evaluator of :mod:`..expressions`); for a
  tetrahedral mesh ``"X_EXPR; Y_EXPR; Z_EXPR"`` in ``x, y, z``. The
  candidates are the boundary vertices, or the nodes of a physical group
  (:func:`group_vertices`); the map applies where ``WHERE`` holds (default: every
  candidate) and the other boundary vertices are handles that stay where they are.
  ``WHERE`` is one comparison or several joined by ``and``/``or``, each side an
  expression: ``"x**2 + y**2 < 0.25"``.

A triangle surface in 3D (:class:`~meshopt_toolkit.mesh.SurfaceMesh`) takes the
tetrahedral forms, but its map's candidates are ALL its vertices (a closed surface has no
boundary to choose from): the selected ones are the handles at their mapped positions,
together with the boundary vertices of an open surface, kept where they are; every other
vertex is free.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

from ..._typing import FloatArray, IntArray
from ...cells.registry import cells_of
from ...errors import ExpressionError, InvalidMeshError, ReadError
from ...expressions import parse_expression, quoted
from ...kernels.admissibility import first_non_finite_row
from ...mesh import PlanarMesh, SurfaceMesh, TetMesh
from ...mesh.kinds import is_surface

_COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater,
            ast.GtE: np.greater_equal}
MAX_TABLE_BYTES = 512 * 2**20
_ROW = {2: "index,x,y", 3: "index,x,y,z"}
_MAP = {2: "X_EXPR; Y_EXPR", 3: "X_EXPR; Y_EXPR; Z_EXPR"}


def _dim(mesh) -> int:
    """2 for a planar mesh, 3 for a tetrahedral one (its points' columns)."""
    return int(mesh.points.shape[1])


def _boundary(mesh) -> IntArray:
    """The boundary vertices: of the boundary edges (planar, surface) or faces (tetrahedral);
    none for a closed surface."""
    kind, points, cells = cells_of(mesh, "move")
    return np.unique(kind.boundary_facets(points, cells))


def read_target_table(path: str | Path, dim: int = 2, n_vertices: int | None = None
                      ) -> tuple[IntArray, FloatArray]:
    """Handles and targets from a CSV (``index,x,y``) or ``.npy`` (k, 3) file; with
    ``dim=3`` rows ``index,x,y,z`` or (k, 4).

    With ``n_vertices`` every row is checked against the mesh: its index in range, its
    target finite, no vertex given two different targets; the message names the file
    and the row (``line 3`` of a CSV file, counted as an editor does; ``row 2`` of an
    array, from 0).

    Raises
    ------
    ReadError
        The file cannot be read as such a table, or a row is refused (above).
    """
    path = Path(path)
    if not path.is_file():
        raise ReadError(f"{path}: not a regular file")
    if path.stat().st_size > MAX_TABLE_BYTES:
        raise ReadError(f"{path}: larger than {MAX_TABLE_BYTES // 2**20} MiB")
    lines = None  # the CSV line of each row
    try:
        if path.suffix.lower() == ".npy":
            table = np.load(path, allow_pickle=False)
        else:
            text = path.read_text(encoding="utf-8").splitlines()
            rows = [(k, ln) for k, ln in enumerate(text, start=1)
                    if ln.strip() and not ln.lstrip().startswith("#")]
            if rows and not _is_number(rows[0][1].split(",")[0]):
                rows = rows[1:]  # header
            lines = [k for k, _ in rows]
            table = np.array([[float(v) for v in ln.split(",")] for _, ln in rows], dtype=float)
    except (ValueError, OSError) as exc:
        raise ReadError(f"{path}: cannot read targets: {exc}") from None
    table = np.asarray(table, dtype=float)
    if table.ndim != 2 or table.shape[1] != dim + 1 or len(table) == 0:
        raise ReadError(f"{path}: expected rows '{_ROW[dim]}' (k × {dim + 1}), got shape "
                        f"{table.shape}")
    index = table[:, 0]
    if not np.all(np.isfinite(index)) or np.any(index != np.round(index)):
        raise ReadError(f"{path}: the first column must hold vertex indices (integers)")
    if n_vertices is not None:
        def row(k: int) -> str:
            return f"row {k}" if lines is None else f"line {lines[k]}"

        _check_rows(path, index, table[:, 1:], n_vertices, row)
    return index.astype(np.int64), table[:, 1:]


def _check_rows(path: Path, index: FloatArray, targets: FloatArray, n_vertices: int,
                row) -> None:
    """The rows of a target table against a mesh of ``n_vertices``; ``row(k)`` names
    the k-th row in a message."""
    bad = np.flatnonzero((index < 0) | (index >= n_vertices))
    if bad.size:
        k = int(bad[0])
        raise ReadError(f"{path}: {row(k)}: vertex index {int(index[k])} is out of range "
                        f"(the mesh has {n_vertices} vertices, 0 to {n_vertices - 1})")
    if (k := first_non_finite_row(targets)) is not None:
        raise ReadError(f"{path}: {row(k)}: the target of vertex {int(index[k])} is not "
                        f"finite: {targets[k].tolist()}")
    order = np.argsort(index, kind="stable")
    same = index[order][1:] == index[order][:-1]
    clash = np.flatnonzero(same & np.any(targets[order][1:] != targets[order][:-1], axis=1))
    if clash.size:
        first, second = sorted((int(order[clash[0]]), int(order[clash[0] + 1])))
        raise ReadError(f"{path}: {row(first)} and {row(second)} give vertex "
                        f"{int(index[first])} different targets")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _naming(option: str, text: str, exc: ExpressionError) -> ExpressionError:
    """The error with the option and its text in front (once)."""
    message = str(exc)
    prefix = f"{option} {quoted(text)}"
    return exc if message.startswith(prefix) else ExpressionError(f"{prefix}: {message}")


def _condition(text: str, X: FloatArray) -> np.ndarray:
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as exc:
        raise ExpressionError(f"--where {quoted(text)}: {exc.msg}") from None
    except (RecursionError, MemoryError, ValueError):
        raise ExpressionError(f"--where {quoted(text)}: too deeply nested") from None

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
                    raise ExpressionError(f"--where {quoted(text)}: use <, <=, > or >=")
                right = parse_expression(ast.unparse(right_node))(X)
                out &= _COMPARE[type(op)](left, right)
                left = right
            return out
        raise ExpressionError(f"--where {quoted(text)}: expected a comparison such as 'x < 0.5'")

    try:
        return evaluate(tree)
    except ExpressionError as exc:
        raise _naming("--where", text, exc) from None


def fix_boundary(mesh: PlanarMesh | TetMesh, handles: IntArray, targets: FloatArray
                 ) -> tuple[IntArray, FloatArray]:
    """``handles``/``targets`` plus every boundary vertex they do not list, kept in place.

    A target table moves the vertices it lists; the rest of the boundary stays where it is
    unless the caller leaves it free (``--free-boundary``). A listed boundary vertex keeps
    its listed target.
    """
    handles = np.asarray(handles, dtype=np.int64)
    targets = np.asarray(targets, dtype=float)
    kept = np.setdiff1d(_boundary(mesh), handles)
    return (np.concatenate([handles, kept]),
            np.concatenate([targets.reshape(-1, _dim(mesh)), mesh.points[kept]]))


def group_vertices(mesh: PlanarMesh | TetMesh | SurfaceMesh, group: str,
                   option: str = "--group") -> IntArray:
    """The vertices of the physical group ``group``: its name, or its number as digits.

    Raises
    ------
    InvalidMeshError
        The mesh has no such group (or no element carries it); the message lists the
        groups it has.
    """
    text = str(group).strip()
    key: int | str = int(text) if text.isdigit() else text
    try:
        return mesh.tagged_vertices(key)
    except InvalidMeshError:
        raise InvalidMeshError(f"{option} {quoted(text)}: {_source(mesh)}no such physical "
                               f"group; {_groups(mesh)}") from None


def _source(mesh: PlanarMesh | TetMesh) -> str:
    source = getattr(mesh, "source", None)
    return f"{source} has " if source else "the mesh has "


def _groups(mesh: PlanarMesh | TetMesh) -> str:
    """``"it has: hole (5), rim (6)"``: the named physical groups, then unnamed numbers."""
    names = mesh.tag_names
    used = set()
    for tags in (mesh.line_tags, mesh.triangle_tags, getattr(mesh, "tet_tags", None)):
        if tags is not None:
            used.update(int(v) for v in np.unique(tags))
    shown = [f"{name} ({tag})" for name, (tag, _dim) in sorted(names.items())]
    unnamed = sorted(used - {tag for tag, _dim in names.values()})
    shown += [str(tag) for tag in unnamed]
    return f"it has: {', '.join(shown)}" if shown else "it has no physical groups"


def targets_from_map(mesh: PlanarMesh | TetMesh, mapping: str, where: str | None = None, *,
                     vertices: IntArray | None = None) -> tuple[IntArray, FloatArray]:
    """Handles and targets from ``"X_EXPR; Y_EXPR"``.

    Parameters
    ----------
    mesh : PlanarMesh or TetMesh
        In the units the expressions are written in.
    mapping : str
        The new position of each selected vertex, ``"X_EXPR; Y_EXPR"`` in its ``x, y``
        (a TetMesh: ``"X_EXPR; Y_EXPR; Z_EXPR"`` in ``x, y, z``).
    where : str, optional
        Which candidates move (default: all of them).
    vertices : (k,) int array, optional
        The candidates (default: the boundary vertices), e.g. a physical group's nodes
        (:func:`group_vertices`).

    Returns
    -------
    handles, targets
        The candidates and every boundary vertex: the selected candidates at their mapped
        positions, the others where they are.
    """
    dim = _dim(mesh)
    parts = [p for p in mapping.split(";")]
    if len(parts) != dim or not all(p.strip() for p in parts):
        raise ExpressionError(f"--map {quoted(mapping)}: expected {('two', 'three')[dim - 2]} "
                              f"expressions '{_MAP[dim]}'")
    try:
        fs = [parse_expression(p.strip()) for p in parts]
    except ExpressionError as exc:
        raise _naming("--map", mapping, exc) from None
    except (ZeroDivisionError, OverflowError, ValueError) as exc:
        raise ExpressionError(f"--map {quoted(mapping)}: {exc}") from None
    if dim == 2 and any(f.uses_z for f in fs):
        raise ExpressionError(f"--map {quoted(mapping)}: z is not defined for a planar mesh")
    boundary = _boundary(mesh)
    surface = is_surface(mesh)
    if vertices is not None:
        candidates = np.unique(np.asarray(vertices, np.int64))
    else:  # a surface's: every vertex (a closed one has no boundary)
        candidates = np.arange(mesh.n_vertices) if surface else boundary
    handles = np.union1d(boundary, candidates)
    X = mesh.points[handles]
    selected = np.isin(handles, candidates)
    if where is not None:
        selected[selected] = _condition(where, X[selected])
    what = ("vertex of the group" if vertices is not None
            else "vertex" if surface else "boundary vertex")
    if not selected.any():
        raise InvalidMeshError(f"--where {quoted(where)} selects no {what}")
    if surface:  # the unselected candidates off the boundary are free
        keep = selected | np.isin(handles, boundary)
        handles, X, selected = handles[keep], X[keep], selected[keep]
    targets = X.copy()
    with np.errstate(all="raise"):
        try:
            for k, f in enumerate(fs):
                targets[selected, k] = f(X[selected])
        except (FloatingPointError, ZeroDivisionError, OverflowError) as exc:
            raise ExpressionError(f"--map {quoted(mapping)}: {exc}") from None
    if not np.isfinite(targets).all():
        raise ExpressionError(f"--map {quoted(mapping)}: not finite at some {what}")
    return handles, targets


def handles_of(mesh: PlanarMesh | TetMesh, *, targets: str | Path | None = None,
               mapping: str | None = None, where: str | None = None,
               group: str | None = None, free_boundary: bool = False
               ) -> tuple[IntArray, FloatArray]:
    """Handles and targets as ``meshopt move`` and the move filter choose them.

    Parameters
    ----------
    mesh : PlanarMesh or TetMesh
        In the units of the table and the expressions.
    targets : path, optional
        A table (:func:`read_target_table`, rows ``index,x,y,z`` for a TetMesh); the
        boundary vertices it does not list stay where they are (:func:`fix_boundary`)
        unless ``free_boundary``.
    mapping, where : str, optional
        Used when ``targets`` is None (:func:`targets_from_map`).
    group : str, optional
        With ``mapping``: the map moves this physical group's nodes (name or number)
        instead of the boundary vertices (:func:`group_vertices`).
    free_boundary : bool
        With ``targets``: leave the unlisted boundary vertices free.
    """
    if targets is not None:
        handles, positions = read_target_table(targets, _dim(mesh), mesh.n_vertices)
        return (handles, positions) if free_boundary else fix_boundary(mesh, handles, positions)
    if mapping is None:
        raise ExpressionError(f"give a target table or a map '{_MAP[_dim(mesh)]}'")
    vertices = None if group is None else group_vertices(mesh, group)
    return targets_from_map(mesh, mapping, where, vertices=vertices)
