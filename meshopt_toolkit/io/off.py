"""Object File Format ``.off`` (text): ``OFF``, counts, vertex rows, ``3 a b c`` faces.

Comments (``#``) are ignored; extra values after a vertex or face (colours) are dropped.
Coordinates are written with ``repr`` (bit-exact on reading).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import ReadError
from ..mesh import TriangleMesh
from ._common import build_mesh, decode_text, format_rows, parse_rows, points3d, require_text_mode

_COMMENT = re.compile(r"#.*")


def read(path: Path) -> TriangleMesh:
    """Read an OFF file (``OFF``/``COFF``/``NOFF`` headers with 3D vertices)."""
    text = decode_text(Path(path).read_bytes(), path)
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
    if len(rest) < nv + nf:
        raise ReadError(f"{path}: truncated: expected {nv} vertices and {nf} faces, "
                        f"found {len(rest)} data lines")
    pts = parse_rows(rest[:nv], path, "vertex", 3)[:, :3]
    faces = parse_rows(rest[nv:nv + nf], path, "face", 4, dtype=np.int64)
    if (faces[:, 0] != 3).any():
        k = int(np.flatnonzero(faces[:, 0] != 3)[0])
        raise ReadError(
            f"{path}: face {k} has {faces[k, 0]} vertices; only triangles are supported"
        )
    return build_mesh(pts, faces[:, 1:4], path)


def write(path: Path, mesh: TriangleMesh, binary: bool | None = None) -> None:
    """Write an OFF file (text only); planar meshes get z = 0."""
    require_text_mode(binary, path, "OFF")
    with open(path, "w", encoding="ascii") as fh:
        fh.write(f"OFF\n{mesh.n_vertices} {mesh.n_triangles} 0\n")
        fh.write(format_rows(points3d(mesh), "%r"))
        fh.write(format_rows(mesh.triangles, "%d", "3 "))
