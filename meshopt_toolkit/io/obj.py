"""Wavefront ``.obj`` (text): ``v x y z`` and ``f a b c`` lines, 1-based indices.

Coordinates are written with ``repr`` (≤ 17 significant digits, read back bit-exactly).
Reading keeps every vertex in file order (unlike trimesh without ``maintain_order``);
``a/b/c`` face tokens and negative (relative) indices are understood; faces with more
than three vertices are refused.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import ReadError
from ..mesh import TriangleMesh
from ._common import build_mesh, decode_text, format_rows, parse_rows, points3d, require_text_mode

_SLASH = re.compile(r"/\S*")


def read(path: Path) -> TriangleMesh:
    """Read the vertices and triangles of an OBJ file (other statements are ignored)."""
    text = decode_text(Path(path).read_bytes(), path)
    lines = text.splitlines()
    vlines = [s[2:] for s in lines if s.startswith(("v ", "v\t"))]
    flines = [s[2:] for s in lines if s.startswith(("f ", "f\t"))]
    if not vlines and not flines:
        raise ReadError(f"{path}: not an OBJ file (no 'v' or 'f' lines)")
    pts = parse_rows(vlines, path, "vertex", 2)
    if pts.shape[1] > 3:  # x y z w, or x y z r g b
        pts = pts[:, :3]
    faces = parse_rows([_SLASH.sub("", s) for s in flines], path, "face", 3, dtype=np.int64)
    if faces.shape[1] != 3:
        raise ReadError(
            f"{path}: face with {faces.shape[1]} vertices; only triangles are supported"
        )
    if (faces < 0).any():
        # relative index: -1 is the last vertex defined before this face line
        kinds = np.array([1 if s.startswith(("v ", "v\t")) else 2 if s.startswith(("f ", "f\t"))
                          else 0 for s in lines])
        n_before = np.cumsum(kinds == 1)[kinds == 2]
        faces = np.where(faces < 0, n_before[:, None] + faces + 1, faces)
    if (faces == 0).any():
        raise ReadError(f"{path}: face index 0 (OBJ indices start at 1)")
    return build_mesh(pts, faces - 1, path)


def write(path: Path, mesh: TriangleMesh, binary: bool | None = None) -> None:
    """Write an OBJ file (text only); planar meshes get z = 0."""
    require_text_mode(binary, path, "OBJ")
    with open(path, "w", encoding="ascii") as fh:
        fh.write("# meshopt-toolkit\n")
        fh.write(format_rows(points3d(mesh), "%r", "v "))
        fh.write(format_rows(mesh.triangles + 1, "%d", "f "))
