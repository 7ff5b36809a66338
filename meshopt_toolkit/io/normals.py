"""Vertex normals that follow the vertices: a file's normals (OBJ ``vn``, PLY ``nx ny
nz``) belong to the points they were read with. A writer given moved points writes the
area-weighted vertex normals of the moved faces instead (oriented as the file's were) and
says so in one warning line, so that no output carries the normals of another shape.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..kernels.surface import pad3
from .cells import NORMALS, CellMesh, check_cells

logger = logging.getLogger(__name__)

#: the cell types whose area vectors make vertex normals
FACES = ("triangle", "quad", "polygon")


@dataclass(frozen=True, eq=False)
class ReadNormals:
    """The points and normals a reader found (a :attr:`~.cells.CellMesh.layout`)."""

    points: np.ndarray
    normals: np.ndarray


def keep_read_normals(cm: CellMesh) -> CellMesh:
    """``cm`` (a reader's, checked) with the normals it read, if any, kept as its layout:
    written back unchanged while the points stay."""
    check_cells(cm)
    if NORMALS in cm.point_data:
        cm.layout = ReadNormals(cm.points, cm.point_data[NORMALS])
    return cm


def vertex_normals(points: np.ndarray, cells) -> np.ndarray:
    """Unit area-weighted vertex normals (N, 3); zero where a vertex is in no face.

    Each face's area vector (Newell's formula, ½ Σ pᵢ × pᵢ₊₁ over its corners: the
    triangle's cross product, a polygon's vector area) is added to each of its vertices.

    Parameters
    ----------
    points : (N, 3) or (N, 2) array
    cells : list of (type, (M, k) int array); blocks other than :data:`FACES` are skipped
    """
    p = pad3(points)
    acc = np.zeros((len(p), 3))
    for t, c in cells:
        if t not in FACES or not len(c):
            continue
        c = np.asarray(c)
        corners = p[c]  # (M, k, 3)
        area = 0.5 * np.cross(corners, np.roll(corners, -1, axis=1)).sum(axis=1)
        for j in range(c.shape[1]):
            np.add.at(acc, c[:, j], area)
    length = np.linalg.norm(acc, axis=1)
    out = np.zeros_like(acc)
    ok = length > 0
    out[ok] = acc[ok] / length[ok, None]
    return out


def normals_to_write(cm: CellMesh, path) -> np.ndarray | None:
    """The normals a writer puts in ``path``: ``cm``'s :data:`~.cells.NORMALS`, or where
    ``cm`` holds the normals read with other points, the moved faces' (one warning line
    naming the input file, once per input)."""
    normals = cm.point_data.get(NORMALS)
    read = cm.layout
    if normals is None or not isinstance(read, ReadNormals) or normals is not read.normals \
            or np.array_equal(cm.points, read.points):
        return normals
    before = vertex_normals(read.points, cm.cells)
    after = vertex_normals(cm.points, cm.cells)
    sign = -1.0 if np.einsum("ij,ij->", before, np.asarray(normals, float)) < 0 else 1.0
    fresh = np.where((np.linalg.norm(after, axis=1) > 0)[:, None], sign * after, normals)
    _say_once(cm.source or str(path))
    return fresh


#: the inputs whose recomputed normals were announced (one line per input, not per frame)
_ANNOUNCED: set[str] = set()


def _say_once(source: str) -> None:
    if source not in _ANNOUNCED:
        _ANNOUNCED.add(source)
        logger.warning("%s: normals recomputed for the moved vertices (area-weighted face "
                       "normals, oriented as the file's)", source)
