"""Wavefront ``.obj`` (text): ``v``, ``f``, ``l`` and ``p`` statements, 1-based indices.

Coordinates are written with ``repr`` (≤ 17 significant digits, read back bit-exactly).
Reading keeps every vertex in file order (unlike trimesh without ``maintain_order``) and
every face with all its vertices: runs of faces of one size become one cell block
(``triangle``, ``quad``, ``polygon``), so a quad after triangles is never cut to a
triangle. ``a/b/c`` face tokens and negative (relative) indices are understood. Vertices
must all have 2 coordinates, or all 3 (a ``v x y`` line among ``v x y z`` lines is
refused, never read by dropping every z). Statements the mesh cannot represent (texture
coordinates, normals, groups, materials, vertex colours) are listed in
:attr:`~.cells.CellMesh.dropped`: ``load`` ignores them, ``convert`` refuses the file.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import ReadError
from ._common import (cells_other_than, data_names, decode_text, format_rows, pad3, refuse,
                      require_text_mode)
from ._files import UNCAPPED, read_input
from .cells import CellMesh, check_cells

_SLASH = re.compile(r"/\S*")
_ELEMENTS = ("f", "l", "p")


def read_cells(path: Path) -> CellMesh:
    """Read vertices and every face, line and point element of an OBJ file, in order."""
    text = decode_text(read_input(path, UNCAPPED), path)
    lines = text.splitlines()
    vrows: list[str] = []
    erows: list[tuple[str, str, int]] = []  # (kind, indices, vertices defined before)
    other: dict[str, int] = {}
    for number, line in enumerate(lines, 1):
        words = line.split(None, 1)
        if not words or words[0].startswith("#"):
            continue
        key = words[0]
        rest = words[1] if len(words) > 1 else ""
        if key == "v":
            vrows.append(rest)
        elif key in _ELEMENTS:
            if not rest.strip():
                raise ReadError(f"{path}: line {number}: '{key}' statement without indices")
            erows.append((key, rest, len(vrows)))
        else:
            other[key] = other.get(key, 0) + 1
    if not vrows and not erows:
        raise ReadError(f"{path}: not an OBJ file (no 'v' or 'f' lines)")
    pts, dropped = _vertices(vrows, path)
    cells = _elements(erows, path)
    dropped += [f"{n} '{k}' statements" for k, n in other.items()]
    cm = CellMesh(pts, cells, source=str(path), dropped=dropped)
    check_cells(cm)
    return cm


def _vertices(rows: list[str], path) -> tuple[np.ndarray, list[str]]:
    split = [r.split() for r in rows]
    if not split:
        return np.zeros((0, 3)), []
    lengths = np.fromiter(map(len, split), dtype=np.int64, count=len(split))
    k = int(lengths.max())
    if k < 2 or int(lengths.min()) < 2:
        bad = int(np.argmin(lengths))
        raise ReadError(f"{path}: vertex {bad + 1} has {lengths[bad]} coordinates: "
                        f"'v {rows[bad].strip()}'")
    if k > 2 and int(lengths.min()) == 2:
        bad = int(np.flatnonzero(lengths == 2)[0])
        raise ReadError(f"{path}: vertex {bad + 1} has 2 coordinates ('v {rows[bad].strip()}') "
                        f"where others have {k}")
    if (lengths != k).any() and not (k <= 4 and int(lengths.min()) >= 3):
        bad = int(np.flatnonzero(lengths != k)[0])
        raise ReadError(f"{path}: vertex {bad + 1} has {lengths[bad]} values where others "
                        f"have {k}")
    if (lengths != k).any():  # x y z with and without w
        split = [s + ["1"] * (k - len(s)) for s in split]
    try:
        arr = np.array(split, dtype=np.float64)
    except ValueError:
        raise ReadError(f"{path}: a vertex coordinate is not a number") from None
    dropped = []
    if k == 4 and (arr[:, 3] != 1).any():
        dropped.append("vertex weights w")
    elif k in (6, 7):
        dropped.append("vertex colours")
    elif k == 5 or k > 7:
        raise ReadError(f"{path}: vertices have {k} values (expected x y [z [w]] or x y z r g b)")
    return arr[:, : (2 if k == 2 else 3)], dropped


def _elements(rows: list[tuple[str, str, int]], path) -> list[tuple[str, np.ndarray]]:
    """Cell blocks of ``f``/``l``/``p`` statements in file order (runs of one kind and size)."""
    if not rows:
        return []
    kinds, sizes, flat, before = [], [], [], []
    for n, (key, rest, n_before) in enumerate(rows):
        tokens = _SLASH.sub("", rest).split()
        if key == "p":
            for t in tokens:
                kinds.append("p")
                sizes.append(1)
                flat.append(t)
                before.append(n_before)
            continue
        if key == "f" and len(tokens) < 3:
            raise ReadError(f"{path}: face {n + 1} has {len(tokens)} vertices: 'f {rest.strip()}'")
        if key == "l" and len(tokens) != 2:
            raise ReadError(f"{path}: line element 'l {rest.strip()}' has {len(tokens)} vertices; "
                            "only 2-vertex lines are supported")
        kinds.append(key)
        sizes.append(len(tokens))
        flat.extend(tokens)
        before.extend([n_before] * len(tokens))
    try:
        idx = np.array(flat, dtype=np.float64)
    except ValueError:
        raise ReadError(f"{path}: an element index is not a number") from None
    if not np.isfinite(idx).all() or (idx != np.round(idx)).any():
        raise ReadError(f"{path}: element indices must be integers")
    if (np.abs(idx) > 2.0**62).any():  # beyond any vertex count, and not castable to int64
        raise ReadError(f"{path}: element index {idx[np.abs(idx) > 2.0**62][0]:.0f} out of range")
    idx = idx.astype(np.int64)
    if (idx == 0).any():
        raise ReadError(f"{path}: element index 0 (OBJ indices start at 1)")
    neg = idx < 0  # relative: -1 is the last vertex defined before the statement
    if neg.any():
        idx = np.where(neg, np.asarray(before, np.int64) + idx + 1, idx)
    idx -= 1
    sizes_arr = np.asarray(sizes, np.int64)
    code = sizes_arr * 4 + np.array([{"f": 0, "l": 1, "p": 2}[k] for k in kinds])
    cut = np.flatnonzero(np.diff(code)) + 1
    starts = np.concatenate([[0], cut]).tolist()
    stops = np.concatenate([cut, [len(code)]]).tolist()
    offsets = np.concatenate([[0], np.cumsum(sizes_arr)])
    cells = []
    for a, b in zip(starts, stops):
        k = int(sizes_arr[a])
        name = {"l": "line", "p": "vertex"}.get(kinds[a]) or \
            {3: "triangle", 4: "quad"}.get(k, "polygon")
        cells.append((name, idx[offsets[a]:offsets[b]].reshape(b - a, k)))
    return cells


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write faces (``f``), lines (``l``) and vertices (``p``) in block order.

    Raises
    ------
    WriteError
        Other cell types, or any point, cell or field data (OBJ has no place for them).
    """
    require_text_mode(binary, path, "OBJ")
    refuse(path, "OBJ", cells_other_than(cm, ("triangle", "quad", "polygon", "line", "vertex"))
           + data_names(cm))
    with open(path, "w", encoding="ascii") as fh:
        fh.write("# meshopt-toolkit\n")
        fh.write(format_rows(pad3(cm.points), "%r", "v "))
        for t, c in cm.cells:
            prefix = {"line": "l ", "vertex": "p "}.get(t, "f ")
            fh.write(format_rows(np.asarray(c) + 1, "%d", prefix))
