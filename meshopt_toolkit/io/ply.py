"""Stanford ``.ply``: ASCII and binary (little/big endian) reading, writing as binary
little-endian (bit-exact) or ASCII with ``repr`` coordinates.

Reading needs a ``vertex`` element with ``x``, ``y`` (and usually ``z``) and a ``face``
element with a ``vertex_indices``/``vertex_index`` list. Faces of any size are kept (runs
of one size are one cell block); other scalar vertex properties (colours, quality) become
point data and other scalar face properties cell data, with their PLY type, so that they
are written back. Float ``nx ny nz`` become the point data :data:`~.cells.NORMALS` and
``texture_u texture_v`` (or ``s t``, ``u v``, as trimesh reads them) the point data
:data:`~.cells.TEXCOORDS`; they are written as ``nx ny nz`` and ``texture_u texture_v``
(the names MeshLab reads). ASCII values must fit their declared type (a ``uchar`` of 300
or a face index beyond int64 is refused, never wrapped). List properties other than the
face's vertices and other elements are listed in :attr:`~.cells.CellMesh.dropped`.
Binary faces are read vectorized when every face has the same number of vertices, else
row by row.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np


from ..errors import ReadError, WriteError
from ..kernels.surface import pad3
from ._common import parse_rows
from ._files import UNCAPPED, read_input
from ._loss import Part, cells_other_than, refuse
from .cells import NORMALS, TEXCOORDS, CellMesh, face_blocks
from .normals import keep_read_normals, normals_to_write

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_FACE_LISTS = ("vertex_indices", "vertex_index")
_NORMAL_AXES = ("nx", "ny", "nz")
#: texture coordinate property pairs read (trimesh's list); the first is written (MeshLab's)
_TEX_NAMES = (("texture_u", "texture_v"), ("s", "t"), ("u", "v"))
#: numpy dtype (kind + size) → PLY type name, for writing
_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int",
          "u4": "uint", "f4": "float", "f8": "double"}


def _parse_header(data: bytes, path) -> tuple[str, list, int]:
    """``(format, elements, body offset)``; elements are ``(name, count, props)`` with
    props ``(name, type)`` or ``(name, count_type, item_type)`` for lists."""
    if not data.startswith(b"ply"):
        raise ReadError(f"{path}: not a PLY file (no 'ply' magic)")
    end = data.find(b"end_header")
    if end < 0:
        raise ReadError(f"{path}: PLY header has no 'end_header'")
    nl = data.find(b"\n", end)
    offset = len(data) if nl < 0 else nl + 1
    fmt, elements = None, []
    for raw in data[:end].decode("latin-1").splitlines()[1:]:
        words = raw.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                if int(words[2]) < 0:
                    raise ValueError("negative count")
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property" and words[1] == "list":
                elements[-1][2].append((words[4], _TYPES[words[2]], _TYPES[words[3]]))
            elif words[0] == "property":
                elements[-1][2].append((words[2], _TYPES[words[1]]))
            else:
                raise ReadError(f"{path}: unknown PLY header line {raw.strip()!r}")
        except (IndexError, KeyError, ValueError):
            raise ReadError(f"{path}: bad PLY header line {raw.strip()!r}") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ReadError(f"{path}: unknown PLY format {fmt!r}")
    return fmt, elements, offset


def _binary_elements(data: bytes, offset: int, elements: list, endian: str, path) -> dict:
    """``{element: {property: array}}``; a list property gives a list of per-row arrays
    when its rows differ in length, else an ``(M, k)`` array."""
    out = {}
    for name, count, props in elements:
        cols, offset = _binary_element(data, offset, count, props, endian, path, name)
        out[name] = cols
    return out


def _binary_element(data, offset, count, props, endian, path, name):
    fields = []
    for p in props:
        if len(p) == 2:
            fields.append((p[0], endian + p[1]))
        else:
            if count == 0:
                fields.append((p[0] + "#n", endian + p[1]))
                continue
            first = np.frombuffer(data, endian + p[1], 1, offset + _size(fields)) \
                if offset + _size(fields) + np.dtype(p[1]).itemsize <= len(data) else []
            if len(first) == 0:
                raise ReadError(f"{path}: truncated binary PLY file")
            k = int(first[0])
            if k < 0 or k > 1 << 20:
                raise ReadError(f"{path}: element {name!r} has a list of length {k}")
            fields.append((p[0] + "#n", endian + p[1]))
            fields.append((p[0], endian + p[2], (k,)))
    dtype = np.dtype(fields)
    if dtype.itemsize * count <= len(data) - offset:
        arr = np.frombuffer(data, dtype, count, offset)
        same = all(len(p) == 2 or count == 0 or (arr[p[0] + "#n"] == arr[p[0] + "#n"][0]).all()
                   for p in props)
        if same:
            cols = {}
            for p in props:
                if len(p) == 2:
                    cols[p[0]] = arr[p[0]]
                else:
                    cols[p[0]] = arr[p[0]] if count else np.zeros((0, 3), np.int64)
            return cols, offset + dtype.itemsize * count
    elif not any(len(p) == 3 for p in props):
        raise ReadError(f"{path}: truncated binary PLY file: element {name!r} needs "
                        f"{dtype.itemsize * count} bytes, {len(data) - offset} left")
    return _binary_rows(data, offset, count, props, endian, path, name)


def _binary_rows(data, offset, count, props, endian, path, name):
    """Row-by-row reading of an element whose lists differ in length."""
    cols: dict[str, list] = {p[0]: [] for p in props}
    for _ in range(count):
        for p in props:
            if len(p) == 2:
                t = np.dtype(endian + p[1])
                if offset + t.itemsize > len(data):
                    raise ReadError(f"{path}: truncated binary PLY file (element {name!r})")
                cols[p[0]].append(np.frombuffer(data, t, 1, offset)[0])
                offset += t.itemsize
            else:
                tn, ti = np.dtype(endian + p[1]), np.dtype(endian + p[2])
                if offset + tn.itemsize > len(data):
                    raise ReadError(f"{path}: truncated binary PLY file (element {name!r})")
                k = int(np.frombuffer(data, tn, 1, offset)[0])
                offset += tn.itemsize
                if k < 0 or offset + k * ti.itemsize > len(data):
                    raise ReadError(f"{path}: truncated binary PLY file (element {name!r})")
                cols[p[0]].append(np.frombuffer(data, ti, k, offset))
                offset += k * ti.itemsize
    out = {}
    for p in props:
        out[p[0]] = np.array(cols[p[0]], dtype=np.dtype(p[1])) if len(p) == 2 else cols[p[0]]
    return out, offset


def _size(fields) -> int:
    return np.dtype(fields).itemsize if fields else 0


def _ascii_elements(data: bytes, offset: int, elements: list, path) -> dict:
    lines = [s for s in data[offset:].decode("latin-1").splitlines() if s.strip()]
    out, pos = {}, 0
    for name, count, props in elements:
        block = lines[pos:pos + count]
        if len(block) < count:
            raise ReadError(f"{path}: truncated PLY file: element {name!r} has {len(block)} of "
                            f"{count} rows")
        pos += count
        has_list = any(len(p) == 3 for p in props)
        if not has_list:
            rows = parse_rows(block, path, name, len(props)) if count else \
                np.zeros((0, len(props)))
            out[name] = {p[0]: _cast(rows[:, c], p[1], path, name, p[0])
                         for c, p in enumerate(props)}
            continue
        cols: dict[str, list] = {p[0]: [] for p in props}
        try:
            for row in block:
                values = row.split()
                c = 0
                for p in props:
                    if len(p) == 2:
                        cols[p[0]].append(float(values[c]))
                        c += 1
                    else:
                        k = int(values[c])
                        if k < 0 or c + 1 + k > len(values):
                            raise ValueError(f"list of {k} items in {row.strip()!r}")
                        cols[p[0]].append(np.array(values[c + 1:c + 1 + k], dtype=np.float64))
                        c += 1 + k
        except (ValueError, IndexError) as exc:
            raise ReadError(f"{path}: bad {name!r} row in PLY file ({exc})") from None
        out[name] = {p[0]: (_cast(np.array(cols[p[0]], np.float64), p[1], path, name, p[0])
                            if len(p) == 2 else cols[p[0]]) for p in props}
    return out


def _cast(a: np.ndarray, code: str, path, element: str, prop: str) -> np.ndarray:
    """ASCII values (parsed as float64) as the declared type, refusing what does not fit
    (never wrapped, truncated or overflowed to infinity)."""
    dt = np.dtype(code)
    a = np.asarray(a, np.float64)
    if dt.kind in "iu":
        info = np.iinfo(dt)
        ok = np.isfinite(a) & (a == np.round(a)) & (a >= info.min) & (a <= info.max)
    else:
        ok = ~np.isfinite(a) | (np.abs(a) <= np.finfo(dt).max)
    if not ok.all():
        bad = float(a[~ok][0])
        raise ReadError(f"{path}: {element} property {prop!r}: value {bad!r} does not fit "
                        f"its type {_NAMES[code]}")
    return a.astype(dt)


def read_cells(path: Path) -> CellMesh:
    """Read vertices, faces of any size and scalar vertex/face properties, in file order."""
    data = read_input(path, UNCAPPED)
    fmt, elements, offset = _parse_header(data, path)
    names = [e[0] for e in elements]
    if "vertex" not in names or "face" not in names:
        raise ReadError(f"{path}: PLY file needs 'vertex' and 'face' elements, has {names}")
    if fmt == "ascii":
        els = _ascii_elements(data, offset, elements, path)
    else:
        endian = "<" if fmt.endswith("little_endian") else ">"
        els = _binary_elements(data, offset, elements, endian, path)
    v, f = els["vertex"], els["face"]
    vspec = elements[names.index("vertex")][2]
    vprops = [p[0] for p in vspec]
    if "x" not in vprops or "y" not in vprops:
        raise ReadError(f"{path}: PLY vertex element has no x/y properties")
    axes = ["x", "y", "z"] if "z" in vprops else ["x", "y"]
    pts = np.column_stack([np.asarray(v[a], dtype=np.float64) for a in axes])
    fspec = elements[names.index("face")][2]
    fprops = [p[0] for p in fspec]
    key = next((k for k in _FACE_LISTS if k in fprops), None)
    if key is None:
        raise ReadError(f"{path}: PLY face element has no vertex_indices list")
    faces = f[key]
    if isinstance(faces, list):
        sizes = np.fromiter(map(len, faces), np.int64, count=len(faces))
        flat = np.concatenate(faces) if faces else np.zeros(0)
    else:
        faces = np.asarray(faces)
        nf = len(faces)
        faces = faces.reshape(nf, -1) if nf else np.zeros((0, 3))
        sizes = np.full(nf, faces.shape[1], np.int64)
        flat = faces.ravel()
    flat = np.asarray(flat)
    if flat.size and (not np.isfinite(flat.astype(np.float64)).all()
                      or (flat.astype(np.float64) != np.round(flat.astype(np.float64))).any()):
        raise ReadError(f"{path}: PLY face indices must be integers")
    if flat.size and (np.abs(flat.astype(np.float64)) > 2.0**62).any():
        big = flat.astype(np.float64)[np.abs(flat.astype(np.float64)) > 2.0**62][0]
        raise ReadError(f"{path}: PLY face index {big:.0f} out of range")
    if len(sizes) and sizes.min() < 3:
        bad = int(np.argmin(sizes))
        raise ReadError(f"{path}: face {bad} has {sizes[bad]} vertices (at least 3 needed)")
    cells = face_blocks(flat.astype(np.int64), sizes)
    dropped = []
    point_data = {}
    for p in vspec:
        if p[0] in axes:
            continue
        if len(p) == 2:
            point_data[p[0]] = np.asarray(v[p[0]])
        else:
            dropped.append(f"vertex list property {p[0]!r}")
    _combine(point_data)
    cell_data = {}
    bounds = np.cumsum([0] + [len(c) for _, c in cells])
    for p in fspec:
        if p[0] == key:
            continue
        if len(p) == 2:
            col = np.asarray(f[p[0]])
            cell_data[p[0]] = [col[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
        else:
            dropped.append(f"face list property {p[0]!r}")
    dropped += [f"PLY element {n!r}" for n in names if n not in ("vertex", "face")]
    cm = CellMesh(pts, cells, point_data=point_data, cell_data=cell_data, source=str(path),
                  dropped=dropped)
    return keep_read_normals(cm)


def _combine(point_data: dict) -> None:
    """Float ``nx ny nz`` → :data:`NORMALS`, a texture pair → :data:`TEXCOORDS` (in place)."""
    def floats(names):
        return all(n in point_data and point_data[n].dtype.kind == "f" for n in names)

    if floats(_NORMAL_AXES) and NORMALS not in point_data:
        point_data[NORMALS] = np.column_stack([point_data.pop(n) for n in _NORMAL_AXES])
    for pair in _TEX_NAMES:
        if floats(pair) and TEXCOORDS not in point_data:
            point_data[TEXCOORDS] = np.column_stack([point_data.pop(n) for n in pair])
            break


def _columns(name: str, a) -> list[tuple[str, np.ndarray]]:
    """The PLY properties of one point datum: normals and texture coordinates split."""
    a = np.asarray(a)
    if name == NORMALS and a.ndim == 2 and a.shape[1] == 3 and a.dtype.kind == "f":
        return [(n, a[:, j]) for j, n in enumerate(_NORMAL_AXES)]
    if name == TEXCOORDS and a.ndim == 2 and a.shape[1] == 2 and a.dtype.kind == "f":
        return [(n, a[:, j]) for j, n in enumerate(_TEX_NAMES[0])]
    return [(name, a)]


def _holds(name: str, a) -> bool:
    try:
        _ply_type(name, a, "")
    except WriteError:
        return False
    return True


def unsupported(cm: CellMesh) -> list[Part]:
    """What PLY cannot hold: cells other than faces, field data, and data that is not
    one number per point or cell (normals (N, 3) and texture coordinates (N, 2) aside)."""
    parts = cells_other_than(cm, ("triangle", "quad", "polygon"))
    taken = {n for k, v in cm.point_data.items() for n, _ in _columns(k, v) if n != k}
    for k, v in cm.point_data.items():
        cols = _columns(k, v)
        if (len(cols) == 1 and k in taken) or not all(_holds(n, c) for n, c in cols):
            parts.append(("point", k))
    for k, v in cm.cell_data.items():
        col = np.concatenate([np.asarray(x) for x in v]) if v else np.zeros(0)
        if not _holds(k, col):
            parts.append(("cell", k))
    return parts + [("field", k) for k in cm.field_data]


def _ply_type(name: str, a: np.ndarray, path) -> tuple[str, np.ndarray]:
    """PLY type name and the array to write (int64 values that fit become int32)."""
    if not re.fullmatch(r"[A-Za-z0-9_:.\-]+", name) or name in ("x", "y", "z", *_FACE_LISTS):
        raise WriteError(f"{path}: PLY cannot hold a property named {name!r}")
    a = np.asarray(a)
    if a.ndim != 1:
        raise WriteError(f"{path}: PLY files cannot hold data {name!r} with "
                         f"{a.shape[1:]} components per entry (use .vtu)")
    code = f"{a.dtype.kind}{a.dtype.itemsize}"
    if code in ("i8", "u8") and (a.size == 0 or (int(a.min()) >= -2**31 and int(a.max()) < 2**31)):
        a, code = a.astype(np.int32), "i4"
    if code == "b1":
        a, code = a.astype(np.uint8), "u1"
    if code not in _NAMES:
        raise WriteError(f"{path}: PLY files cannot hold data {name!r} of type {a.dtype}")
    return _NAMES[code], a


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write a PLY file: faces of any size, scalar point and cell data as properties;
    binary little-endian by default, ASCII (``repr`` floats) with ``binary=False``.

    Raises
    ------
    WriteError
        What :func:`unsupported` lists.
    """
    refuse(path, "PLY", cm, unsupported(cm))
    binary = True if binary is None else bool(binary)
    pts = pad3(cm.points)
    point_data = dict(cm.point_data)
    if NORMALS in point_data:  # those of the moved faces where the points moved
        point_data[NORMALS] = normals_to_write(cm, path)
    pdata = [(n, *_ply_type(n, c, path)) for k, v in point_data.items()
             for n, c in _columns(k, v)]
    cdata = [(k, *_ply_type(k, np.concatenate([np.asarray(x) for x in v]) if v else
                            np.zeros(0), path)) for k, v in cm.cell_data.items()]
    nf = cm.n_cells
    kmax = max((c.shape[1] for _, c in cm.cells), default=3)
    count_t = "uchar" if kmax < 256 else "int"
    fmt = "binary_little_endian" if binary else "ascii"
    header = [f"ply\nformat {fmt} 1.0\ncomment meshopt-toolkit",
              f"element vertex {len(pts)}", "property double x", "property double y",
              "property double z"]
    header += [f"property {t} {k}" for k, t, _ in pdata]
    header += [f"element face {nf}", f"property list {count_t} int vertex_indices"]
    header += [f"property {t} {k}" for k, t, _ in cdata]
    header.append("end_header\n")
    with open(path, "wb") as fh:
        fh.write("\n".join(header).encode("ascii"))
        start = 0
        if binary:
            rec = np.empty(len(pts), dtype=[("p", "<f8", (3,))] +
                           [(k, "<" + _code(a)) for k, _, a in pdata])
            rec["p"] = pts
            for k, _, a in pdata:
                rec[k] = a
            fh.write(rec.tobytes())
            for _, c in cm.cells:
                m, k = c.shape
                rec = np.empty(m, dtype=[("n", "u1" if count_t == "uchar" else "<i4"),
                                         ("v", "<i4", (k,))] +
                               [(name, "<" + _code(a)) for name, _, a in cdata])
                rec["n"] = k
                rec["v"] = c
                for name, _, a in cdata:
                    rec[name] = a[start:start + m]
                start += m
                fh.write(rec.tobytes())
            return
        cols = [pts[:, 0], pts[:, 1], pts[:, 2]] + [a for _, _, a in pdata]
        fh.write(_ascii_rows(cols).encode())
        for _, c in cm.cells:
            m, k = c.shape
            ccols = [np.full(m, k)] + [c[:, j] for j in range(k)] + \
                [a[start:start + m] for _, _, a in cdata]
            start += m
            fh.write(_ascii_rows(ccols).encode())


def _code(a: np.ndarray) -> str:
    return f"{a.dtype.kind}{a.dtype.itemsize}"


def _ascii_rows(cols: list[np.ndarray]) -> str:
    """One text row per entry: ``repr`` for floats (bit-exact), ``%d`` for integers."""
    n = len(cols[0]) if cols else 0
    if n == 0:
        return ""
    row = " ".join("%r" if np.asarray(c).dtype.kind == "f" else "%d" for c in cols) + "\n"
    values = [np.asarray(c).tolist() for c in cols]
    flat = [x for r in zip(*values) for x in r]
    return (row * n) % tuple(flat)
