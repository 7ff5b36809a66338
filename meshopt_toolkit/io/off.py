"""Object File Format ``.off`` (text): ``OFF``, counts, vertex rows, ``k i1 ... ik`` faces.

Faces of any size are kept (runs of one size become one cell block). Comments (``#``) are
ignored; values after a vertex or a face (colours) are listed in
:attr:`~.cells.CellMesh.dropped` (``convert`` refuses such a file, ``load`` ignores them).
Coordinates are written with ``repr`` (bit-exact on reading).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import ReadError
from ._common import (cells_other_than, data_names, decode_text, format_rows, pad3, refuse,
                      require_text_mode)
from ._files import UNCAPPED, read_input
from .cells import CellMesh, face_blocks, check_cells

_COMMENT = re.compile(r"#.*")


def read_cells(path: Path) -> CellMesh:
    """Read an OFF file (``OFF``/``COFF``/``NOFF`` headers with 3D vertices)."""
    text = decode_text(read_input(path, UNCAPPED), path)
    lines = [s for s in (_COMMENT.sub("", s).strip() for s in text.splitlines()) if s]
    if not lines or not re.fullmatch(r"[CN]*OFF", lines[0].split()[0]):
        raise ReadError(f"{path}: not an OFF file (first line must be 'OFF')")
    head = lines[0].split()[1:]
    rest = lines[1:]
    if not head:
        if not rest:
            raise ReadError(f"{path}: OFF file has no counts line")
        head, rest = rest[0].split(), rest[1:]
    try:
        nv, nf = int(head[0]), int(head[1])
    except (ValueError, IndexError):
        raise ReadError(f"{path}: bad OFF counts line {' '.join(head)!r}") from None
    if nv < 0 or nf < 0 or len(rest) < nv + nf:
        raise ReadError(f"{path}: truncated: expected {nv} vertices and {nf} faces, "
                        f"found {len(rest)} data lines")
    dropped = []
    vsplit = [s.split() for s in rest[:nv]]
    vlen = np.fromiter(map(len, vsplit), np.int64, count=nv)
    if nv and vlen.min() < 3:
        bad = int(np.argmin(vlen))
        raise ReadError(f"{path}: vertex {bad} has {vlen[bad]} values, expected 3: "
                        f"{rest[bad]!r}")
    if (vlen > 3).any():
        dropped.append("vertex colours")
    try:
        pts = np.array([v[:3] for v in vsplit], dtype=np.float64).reshape(nv, 3)
        fsplit = [s.split() for s in rest[nv:nv + nf]]
        sizes = np.array([int(f[0]) for f in fsplit], dtype=np.int64)
    except ValueError:
        raise ReadError(f"{path}: a vertex or face value is not a number") from None
    flen = np.fromiter(map(len, fsplit), np.int64, count=nf)
    if nf and ((sizes < 3) | (flen < sizes + 1)).any():
        bad = int(np.flatnonzero((sizes < 3) | (flen < sizes + 1))[0])
        raise ReadError(f"{path}: face {bad} {rest[nv + bad]!r} does not have the "
                        f"{sizes[bad]} vertex indices it announces (at least 3)")
    if (flen > sizes + 1).any():
        dropped.append("face colours")
    try:
        flat = np.array([x for f, k in zip(fsplit, sizes.tolist()) for x in f[1:k + 1]],
                        dtype=np.int64)
    except ValueError:
        raise ReadError(f"{path}: face indices must be integers") from None
    cm = CellMesh(pts, face_blocks(flat, sizes), source=str(path), dropped=dropped)
    check_cells(cm)
    return cm


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write the faces of ``cm`` (triangles, quads, polygons) in block order.

    Raises
    ------
    WriteError
        Line or vertex cells, other cell types, or any data.
    """
    require_text_mode(binary, path, "OFF")
    refuse(path, "OFF", cells_other_than(cm, ("triangle", "quad", "polygon")) + data_names(cm))
    with open(path, "w", encoding="ascii") as fh:
        fh.write(f"OFF\n{cm.n_points} {cm.n_cells} 0\n")
        fh.write(format_rows(pad3(cm.points), "%r"))
        for _, c in cm.cells:
            c = np.asarray(c)
            fh.write(format_rows(c, "%d", f"{c.shape[1]} "))
