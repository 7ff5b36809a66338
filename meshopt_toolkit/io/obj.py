"""Wavefront ``.obj`` (text): ``v``, ``vt``, ``vn``, ``f``, ``l`` and ``p`` statements.

Coordinates are written with ``repr`` (≤ 17 significant digits, read back bit-exactly).
Reading keeps every vertex in file order (unlike trimesh without ``maintain_order``) and
every face with all its vertices: runs of faces of one size become one cell block
(``triangle``, ``quad``, ``polygon``), so a quad after triangles is never cut to a
triangle. ``a/b/c`` face tokens and negative (relative) indices are understood. Vertices
must all have 2 coordinates, or all 3 (a ``v x y`` line among ``v x y z`` lines is
refused, never read by dropping every z).

Normals (``vn``) and texture coordinates (``vt``) become point data
:data:`~.cells.NORMALS` (N, 3) and :data:`~.cells.TEXCOORDS` (N, k) when they are per
vertex: every face corner of a vertex names the same ``vn``/``vt`` (or faces name none and
there is one per vertex, in order). Otherwise, and for statements the mesh cannot
represent (groups, materials, vertex colours), they are listed in
:attr:`~.cells.CellMesh.dropped`: ``load`` ignores them, ``convert`` refuses the file
unless ``--allow-loss``. Writing puts the two point data back as ``vt``/``vn`` lines with
``f v/t/n`` corners (the same index three times); normals read with other points than
those written are those of the moved faces (:mod:`.normals`).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import ReadError
from ..kernels.surface import pad3
from ._common import decode_text, float_array, format_rows, require_text_mode
from ._files import UNCAPPED, read_input
from ._loss import Part, cells_other_than, data_parts, refuse
from .cells import NORMALS, TEXCOORDS, CellMesh, face_blocks
from .normals import keep_read_normals, normals_to_write

_ELEMENTS = ("f", "l", "p")
#: one face corner "v", "v/vt", "v//vn" or "v/vt/vn" per line of the joined tokens
_CORNER = re.compile(r"^([^/\n]*)(?:/([^/\n]*))?(?:/([^/\n]*))?$", re.M)
#: statements that only restate the default (smoothing off)
_NO_OPS = {("s", "off"), ("s", "0")}
_LABELS = {"vt": "texture coordinates 'vt'", "vn": "normals 'vn'"}


def read_cells(path: Path) -> CellMesh:
    """Read vertices, per-vertex normals and texture coordinates and every face, line and
    point element of an OBJ file, in order."""
    text = decode_text(read_input(path, UNCAPPED), path)
    vrows: list[str] = []
    attr_rows: dict[str, list[str]] = {"vt": [], "vn": []}
    erows: list[tuple[str, str, tuple[int, int, int]]] = []  # (kind, indices, counts before)
    other: dict[str, int] = {}
    for number, line in enumerate(text.splitlines(), 1):
        words = line.split(None, 1)
        if not words or words[0].startswith("#"):
            continue
        key = words[0]
        rest = words[1] if len(words) > 1 else ""
        if key == "v":
            vrows.append(rest)
        elif key in attr_rows:
            attr_rows[key].append(rest)
        elif key in _ELEMENTS:
            if not rest.strip():
                raise ReadError(f"{path}: line {number}: '{key}' statement without indices")
            erows.append((key, rest, (len(vrows), len(attr_rows["vt"]), len(attr_rows["vn"]))))
        elif (key, rest.strip().lower()) not in _NO_OPS:
            other[key] = other.get(key, 0) + 1
    if not vrows and not erows:
        raise ReadError(f"{path}: not an OBJ file (no 'v' or 'f' lines)")
    pts, dropped = _vertices(vrows, path)
    cells, corners = _elements(erows, path)
    point_data = {}
    v = corners["v"]
    in_range = not v.size or (int(v.min()) >= 0 and int(v.max()) < len(pts))
    for key, name in (("vt", TEXCOORDS), ("vn", NORMALS)) if in_range else ():
        rows = _attribute_rows(attr_rows[key], key, path)
        values, why = _per_vertex(rows, corners[key], corners["v"], corners["f"], len(pts),
                                  _LABELS[key], path)
        if values is not None:
            point_data[name] = values
        elif why:
            dropped.append(why)
    dropped += [f"{n} '{k}' statements" for k, n in other.items()]
    cm = CellMesh(pts, cells, point_data=point_data, source=str(path), dropped=dropped)
    return keep_read_normals(cm)


def _attribute_rows(rows: list[str], key: str, path) -> np.ndarray:
    """``vn`` rows as (n, 3), ``vt`` rows as (n, k) (k = 1..3; shorter rows padded with
    OBJ's default 0)."""
    split = [r.split() for r in rows]
    if not split:
        return np.zeros((0, 3 if key == "vn" else 2))
    lengths = np.fromiter(map(len, split), dtype=np.int64, count=len(split))
    lo, hi = (3, 3) if key == "vn" else (1, 3)
    if lengths.min() < lo or lengths.max() > hi:
        bad = int(np.flatnonzero((lengths < lo) | (lengths > hi))[0])
        raise ReadError(f"{path}: '{key} {rows[bad].strip()}' has {lengths[bad]} values "
                        f"(expected {lo if lo == hi else f'{lo} to {hi}'})")
    k = int(lengths.max())
    if (lengths != k).any():
        split = [s + ["0"] * (k - len(s)) for s in split]
    arr = float_array(split, f"{path}: a '{key}' value is not a number")
    if not np.isfinite(arr).all():
        raise ReadError(f"{path}: a '{key}' value is not finite")
    return arr


def _per_vertex(rows: np.ndarray, corner_x: np.ndarray, corner_v: np.ndarray,
                is_face: np.ndarray, n: int, label: str, path) -> tuple[np.ndarray | None, str]:
    """Rows of ``vt``/``vn`` as point data, or None and why they are not per vertex.

    ``corner_x`` are the 0-based attribute indices of the element corners (-1: none
    given), ``corner_v`` their vertices, ``is_face`` whether a corner is a face's.
    """
    given = corner_x >= 0
    if given.any() and int(corner_x.max()) >= len(rows):
        return None, (f"{label} (an index out of range: the file has {len(rows)}; "
                      "not per vertex)")
    if not len(rows):
        return None, ""
    if not given.any():
        if len(rows) == n:  # one per vertex, in order (faces name none)
            return rows, ""
        return None, f"{len(rows)} {label} not referenced by any face"
    if (is_face & ~given).any():
        return None, f"{label} (given for some face corners only: not per vertex)"
    use = given
    table = np.full(n, -1, np.int64)
    table[corner_v[use]] = corner_x[use]
    if (table[corner_v[use]] != corner_x[use]).any():
        return None, f"{label} (not per vertex: a vertex has different ones in different faces)"
    if (table < 0).any():
        if len(rows) == n and np.array_equal(corner_x[use], corner_v[use]):
            table = np.arange(n)
        else:
            return None, f"{label} (not per vertex: a vertex in no face has none)"
    return rows[table], ""


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
    arr = float_array(split, f"{path}: a vertex coordinate is not a number")
    dropped = []
    if k == 4 and (arr[:, 3] != 1).any():
        dropped.append("vertex weights w")
    elif k in (6, 7):
        dropped.append("vertex colours")
    elif k == 5 or k > 7:
        raise ReadError(f"{path}: vertices have {k} values (expected x y [z [w]] or x y z r g b)")
    return arr[:, : (2 if k == 2 else 3)], dropped


def _indices(tokens: list[str], before: np.ndarray, path, what: str) -> np.ndarray:
    """1-based (or negative, relative to ``before``) OBJ indices → 0-based int64."""
    idx = float_array(tokens, f"{path}: {what} is not a number")
    if not np.isfinite(idx).all() or (idx != np.round(idx)).any():
        raise ReadError(f"{path}: {what}s must be integers")
    if (np.abs(idx) > 2.0**62).any():  # beyond any count, and not castable to int64
        raise ReadError(f"{path}: {what} {idx[np.abs(idx) > 2.0**62][0]:.0f} out of range")
    idx = idx.astype(np.int64)
    if (idx == 0).any():
        raise ReadError(f"{path}: {what} 0 (OBJ indices start at 1)")
    neg = idx < 0  # relative: -1 is the last one defined before the statement
    if neg.any():
        idx = np.where(neg, before + idx + 1, idx)
    return idx - 1


def _elements(rows: list[tuple[str, str, tuple[int, int, int]]], path):
    """Cell blocks of ``f``/``l``/``p`` statements in file order (runs of one kind and
    size), and the corners: ``{"v", "vt", "vn": 0-based indices (-1: none), "f": bool}``."""
    empty = np.zeros(0, np.int64)
    if not rows:
        return [], {"v": empty, "vt": empty, "vn": empty, "f": np.zeros(0, bool)}
    sizes, flat, lengths, before = [], [], [], []
    for n, (key, rest, n_before) in enumerate(rows):
        tokens = rest.split()
        if key == "f" and len(tokens) < 3:
            raise ReadError(f"{path}: face {n + 1} has {len(tokens)} vertices: 'f {rest.strip()}'")
        if key == "l" and len(tokens) != 2:
            raise ReadError(f"{path}: line element 'l {rest.strip()}' has {len(tokens)} vertices; "
                            "only 2-vertex lines are supported")
        flat.extend(tokens)
        lengths.append(len(tokens))
        before.append(n_before)
        if key == "p":
            sizes.extend([1] * len(tokens))
        else:
            sizes.append(len(tokens))
    counts = np.repeat(np.asarray(before, np.int64).reshape(-1, 3), lengths, axis=0)
    # "v", "v/t", "v//n", "v/t/n": three token lists ("" when absent), in one regex pass
    fields: list = [flat, None, None]
    joined = "\n".join(flat)
    if "/" in joined:
        found = _CORNER.findall(joined)
        if len(found) != len(flat):
            bad = next(t for t in flat if t.count("/") > 2)
            raise ReadError(f"{path}: bad element token {bad!r} (at most v/vt/vn)")
        fields = [[f[j] for f in found] for j in range(3)]  # (zip(*found) is slow)
    if "" in fields[0]:
        raise ReadError(f"{path}: an element corner has no vertex index")
    corners = {}
    for j, (name, what) in enumerate((("v", "element index"), ("vt", "texture index"),
                                      ("vn", "normal index"))):
        out = np.full(len(flat), -1, np.int64)
        if fields[j] is not None:
            tokens = np.array(fields[j]) if j else fields[j]
            have = tokens != "" if j else np.ones(len(tokens), bool)
            if have.any():
                found = _indices(tokens[have] if j else tokens, counts[have, j], path, what)
                # a relative index before the first one: out of range, never "none given"
                out[have] = np.where(found < 0, np.iinfo(np.int64).max, found)
        corners[name] = out
    # a face has 3 corners or more, a line 2, a point 1: the size tells the kind
    sizes_arr = np.asarray(sizes, np.int64)
    corners["f"] = np.repeat(sizes_arr >= 3, sizes_arr)
    return face_blocks(corners["v"], sizes_arr), corners


def unsupported(cm: CellMesh) -> list[Part]:
    """What OBJ cannot hold: volume cells, cell and field data, and point data other than
    :data:`~.cells.NORMALS` (N, 3) and :data:`~.cells.TEXCOORDS` (N, 1..3) floats."""
    parts = cells_other_than(cm, ("triangle", "quad", "polygon", "line", "vertex"))
    for k, v in cm.point_data.items():
        a = np.asarray(v)
        fits = a.dtype.kind == "f" and a.ndim == 2 and (
            (k == NORMALS and a.shape[1] == 3) or (k == TEXCOORDS and 1 <= a.shape[1] <= 3))
        if not fits:
            parts.append(("point", k))
    return parts + data_parts(cm, point=False)


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write vertices, ``vt``/``vn`` (from point data), then faces (``f``), lines (``l``)
    and vertices (``p``) in block order.

    Raises
    ------
    WriteError
        What :func:`unsupported` lists (OBJ has no place for it).
    """
    require_text_mode(binary, path, "OBJ")
    refuse(path, "OBJ", cm, unsupported(cm))
    tex, normals = cm.point_data.get(TEXCOORDS), normals_to_write(cm, path)
    # a face corner names its vertex, texture coordinate and normal: the same index
    token = "%d" + ("/%d" if tex is not None else "/" if normals is not None else "") + \
        ("/%d" if normals is not None else "")
    reps = 1 + (tex is not None) + (normals is not None)
    with open(path, "w", encoding="ascii") as fh:
        fh.write("# meshopt-toolkit\n")
        fh.write(format_rows(pad3(cm.points), "%r", "v "))
        if tex is not None:
            fh.write(format_rows(np.asarray(tex, np.float64), "%r", "vt "))
        if normals is not None:
            fh.write(format_rows(np.asarray(normals, np.float64), "%r", "vn "))
        for t, c in cm.cells:
            c = np.asarray(c) + 1
            if t in ("line", "vertex"):
                fh.write(format_rows(c, "%d", {"line": "l ", "vertex": "p "}[t]))
            else:
                fh.write(format_rows(np.repeat(c, reps, axis=1), token, "f ", group=reps))
