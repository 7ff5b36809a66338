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
from ..kernels.surface import pad3
from ._common import decode_text, float_array, format_rows, require_text_mode
from ._files import UNCAPPED, read_input
from ._loss import Part, cells_other_than, data_parts, refuse
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
    if max(nv, nf) > 2**62:
        raise ReadError(f"{path}: OFF counts {nv} {nf} out of range")
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
    pts = float_array([v[:3] for v in vsplit],
                      f"{path}: a vertex value is not a number").reshape(nv, 3)
    fsplit = [s.split() for s in rest[nv:nv + nf]]
    sizes = _integers([f[0] for f in fsplit], path, "face size")
    flen = np.fromiter(map(len, fsplit), np.int64, count=nf)
    if nf and ((sizes < 3) | (flen - 1 < sizes)).any():
        bad = int(np.flatnonzero((sizes < 3) | (flen - 1 < sizes))[0])
        raise ReadError(f"{path}: face {bad} {rest[nv + bad]!r} does not have the "
                        f"{sizes[bad]} vertex indices it announces (at least 3)")
    if (flen - 1 > sizes).any():
        dropped.append("face colours")
    flat = _integers([x for f, k in zip(fsplit, sizes.tolist()) for x in f[1:k + 1]],
                     path, "face index")
    cm = CellMesh(pts, face_blocks(flat, sizes), source=str(path), dropped=dropped)
    check_cells(cm)
    return cm


def _integers(tokens: list[str], path, what: str) -> np.ndarray:
    """Decimal integers as int64; a non-integer or one beyond int64 is refused."""
    try:
        return np.array([int(t) for t in tokens], dtype=np.int64)
    except ValueError:
        raise ReadError(f"{path}: {what}s must be integers") from None
    except OverflowError:
        big = next(t for t in tokens if abs(int(t)) >= 2**63)
        raise ReadError(f"{path}: {what} {big} out of range") from None


def unsupported(cm: CellMesh) -> list[Part]:
    """What OFF cannot hold: cells other than faces, and any data."""
    return cells_other_than(cm, ("triangle", "quad", "polygon")) + data_parts(cm)


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write the faces of ``cm`` (triangles, quads, polygons) in block order.

    Raises
    ------
    WriteError
        Line or vertex cells, other cell types, or any data.
    """
    require_text_mode(binary, path, "OFF")
    refuse(path, "OFF", cm, unsupported(cm))
    with open(path, "w", encoding="ascii") as fh:
        fh.write(f"OFF\n{cm.n_points} {cm.n_cells} 0\n")
        fh.write(format_rows(pad3(cm.points), "%r"))
        for _, c in cm.cells:
            c = np.asarray(c)
            fh.write(format_rows(c, "%d", f"{c.shape[1]} "))
