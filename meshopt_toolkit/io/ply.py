"""Stanford ``.ply``: ASCII and binary (little/big endian) reading, writing as binary
little-endian doubles (bit-exact) or ASCII with ``repr`` coordinates.

Reading needs a ``vertex`` element with ``x``, ``y`` (and usually ``z``) and a ``face``
element with a ``vertex_indices``/``vertex_index`` list; other properties (colours,
normals, quality) are skipped. Binary lists are read vectorized on the assumption that
every face has three vertices, which is verified.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ReadError
from ..mesh import TriangleMesh
from ._common import build_mesh, format_rows, parse_rows, points3d

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_FACE_LISTS = ("vertex_indices", "vertex_index")


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
    out = {}
    for name, count, props in elements:
        fields = []
        for p in props:
            if len(p) == 2:
                fields.append((p[0], endian + p[1]))
            else:
                if count == 0:
                    fields.append((p[0] + "#n", endian + p[1]))
                    continue
                first = np.frombuffer(data, endian + p[1], 1, offset + _size(fields))
                if len(first) == 0:
                    raise ReadError(f"{path}: truncated binary PLY file")
                k = int(first[0])
                fields.append((p[0] + "#n", endian + p[1]))
                fields.append((p[0], endian + p[2], (k,)))
        dtype = np.dtype(fields)
        if offset + dtype.itemsize * count > len(data):
            raise ReadError(f"{path}: truncated binary PLY file: element {name!r} needs "
                            f"{dtype.itemsize * count} bytes, {len(data) - offset} left")
        arr = np.frombuffer(data, dtype, count, offset)
        for p in props:
            if len(p) == 3 and count and (arr[p[0] + "#n"] != arr[p[0] + "#n"][0]).any():
                raise ReadError(f"{path}: element {name!r} has lists of different lengths "
                                "(only triangle faces are supported)")
        offset += dtype.itemsize * count
        out[name] = arr
    return out


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
        rows = parse_rows(block, path, name, 1) if count else np.zeros((0, 0))
        cols, c = {}, 0
        for p in props:
            if len(p) == 2:
                cols[p[0]] = rows[:, c] if count else np.zeros(0)
                c += 1
            else:
                k = int(rows[0, c]) if count else 3
                if count and (rows[:, c] != k).any():
                    raise ReadError(f"{path}: element {name!r} has lists of different lengths "
                                    "(only triangle faces are supported)")
                cols[p[0]] = rows[:, c + 1:c + 1 + k] if count else np.zeros((0, 3))
                c += 1 + k
        out[name] = cols
    return out


def read(path: Path) -> TriangleMesh:
    """Read vertices and triangular faces of a PLY file, in file order."""
    data = Path(path).read_bytes()
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
    vprops = [p[0] for p in elements[names.index("vertex")][2]]
    if "x" not in vprops or "y" not in vprops:
        raise ReadError(f"{path}: PLY vertex element has no x/y properties")
    axes = ["x", "y", "z"] if "z" in vprops else ["x", "y"]
    pts = np.column_stack([np.asarray(v[a], dtype=np.float64) for a in axes])
    fprops = [p[0] for p in elements[names.index("face")][2]]
    key = next((k for k in _FACE_LISTS if k in fprops), None)
    if key is None:
        raise ReadError(f"{path}: PLY face element has no vertex_indices list")
    faces = np.asarray(f[key])
    faces = faces.reshape(len(faces), -1) if len(faces) else np.zeros((0, 3), np.int64)
    if faces.shape[1] != 3 and len(faces):
        raise ReadError(
            f"{path}: faces have {faces.shape[1]} vertices; only triangles are supported"
        )
    return build_mesh(pts, faces.astype(np.int64), path)


def write(path: Path, mesh: TriangleMesh, binary: bool | None = None) -> None:
    """Write a PLY file: binary little-endian doubles by default, ASCII if ``binary=False``."""
    binary = True if binary is None else bool(binary)
    pts = points3d(mesh)
    fmt = "binary_little_endian" if binary else "ascii"
    header = (
        f"ply\nformat {fmt} 1.0\ncomment meshopt-toolkit\n"
        f"element vertex {len(pts)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {mesh.n_triangles}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        if binary:
            fh.write(pts.astype("<f8").tobytes())
            rec = np.empty(mesh.n_triangles, dtype=[("n", "u1"), ("v", "<i4", (3,))])
            rec["n"] = 3
            rec["v"] = mesh.triangles
            fh.write(rec.tobytes())
        else:
            fh.write(format_rows(pts, "%r").encode())
            fh.write(format_rows(mesh.triangles, "%d", "3 ").encode())
