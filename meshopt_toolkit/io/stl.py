"""STL (binary and ASCII). STL stores independent triangles, so it is not ordered:
reading merges equal corners into vertices (sorted lexicographically) — "read as
unordered". Binary STL holds float32 coordinates by format (writing rounds them); ASCII
STL is written with ``repr`` floats and read as float64, so its coordinates round-trip
bit-exactly. Writing is binary by default.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np


from ..errors import ReadError, WriteError
from ..kernels.surface import pad3
from ._common import float_array
from ._loss import Part, cells_other_than, data_parts, refuse
from ._files import UNCAPPED, read_input
from .cells import CellMesh, check_cells

_RECORD = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
_VERTEX = re.compile(rb"vertex\s+(\S+)\s+(\S+)\s+(\S+)")


def read_cells(path: Path) -> CellMesh:
    """Read an STL file as points and one triangle block (equal corners merged)."""
    data = read_input(path, UNCAPPED)
    if len(data) >= 84:
        n = int(np.frombuffer(data, "<u4", 1, 80)[0])
        binary = len(data) == 84 + 50 * n
    else:
        binary = False
    if binary and n == 0:
        raise ReadError(f"{path}: binary STL file with no triangle")
    if binary:
        corners = np.frombuffer(data, _RECORD, n, 84)["v"].reshape(-1, 3).astype(np.float64)
    else:
        if not data.lstrip().startswith(b"solid"):
            raise ReadError(f"{path}: not an STL file (neither binary size nor 'solid' header)")
        found = _VERTEX.findall(data)
        if not found or len(found) % 3:
            raise ReadError(f"{path}: ASCII STL with {len(found)} vertices (not a multiple of 3)")
        corners = float_array(found, f"{path}: ASCII STL has a coordinate that is not a number")
    if not np.isfinite(corners).all():
        raise ReadError(f"{path}: STL has a non-finite coordinate")
    pts, inverse = np.unique(corners, axis=0, return_inverse=True)
    cm = CellMesh(pts, [("triangle", inverse.reshape(-1, 3).astype(np.int64))], source=str(path))
    check_cells(cm)
    return cm


def unsupported(cm: CellMesh) -> list[Part]:
    """What STL cannot hold: cells other than triangles, and any data."""
    return cells_other_than(cm, ("triangle",)) + data_parts(cm)


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write an STL file (binary by default) with unit facet normals.

    Binary STL stores float32 by format (coordinates are rounded); ASCII STL
    (``binary=False``) writes every float64 with ``repr``, read back bit-exactly.

    Raises
    ------
    WriteError
        Cells other than triangles, or any data (STL holds independent triangles only).
    """
    refuse(path, "STL", cm, unsupported(cm), "use .vtu or .msh")
    binary = True if binary is None else bool(binary)
    tris = np.concatenate([c for _, c in cm.cells]) if cm.cells else np.zeros((0, 3), np.int64)
    corners = pad3(cm.points)[tris]  # (T, 3, 3)
    # the normal's direction from corners scaled to at most 1 (no overflow for huge ones)
    scale = np.abs(corners).max(axis=(1, 2), initial=0.0)[:, None, None]
    unit = np.divide(corners, scale, out=np.zeros_like(corners), where=scale > 0)
    normal = np.cross(unit[:, 1] - unit[:, 0], unit[:, 2] - unit[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    with open(path, "wb") as fh:
        if binary:
            big = np.abs(corners) > np.finfo(np.float32).max
            if big.any():
                raise WriteError(f"{path}: binary STL holds float32 coordinates; "
                                 f"{float(corners[big][0])!r} is out of range (write ASCII)")
            rec = np.zeros(len(corners), _RECORD)
            rec["normal"] = normal
            rec["v"] = corners
            fh.write(b"meshopt-toolkit binary STL".ljust(80, b" "))
            fh.write(np.array([len(corners)], "<u4").tobytes())
            fh.write(rec.tobytes())
        else:
            table = np.concatenate([normal[:, None, :], corners], axis=1).reshape(len(corners), 12)
            facet = ("facet normal %r %r %r\n outer loop\n  vertex %r %r %r\n  vertex %r %r %r\n"
                     "  vertex %r %r %r\n endloop\nendfacet\n")
            values = table.ravel().tolist()  # repr: float64 read back bit-exactly
            body = (facet * len(table)) % tuple(values)
            fh.write(b"solid meshopt\n" + body.encode() + b"endsolid meshopt\n")
