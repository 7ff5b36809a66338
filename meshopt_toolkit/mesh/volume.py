"""Tetrahedral volume meshes: :class:`TetMesh`.

An immutable value like :class:`~meshopt_toolkit.mesh.PlanarMesh`: points ``(N, 3)``,
tetrahedra ``(M, 4)`` and the physical tags a gmsh file gives them (per tetrahedron, and
tagged boundary triangles and lines kept beside them, with their names). The topology is
cached: boundary faces oriented outward, boundary vertices, faces in more than two
tetrahedra. *Admissible* means every tetrahedron is positively oriented
(``det[q1 − q0, q2 − q0, q3 − q0] > 0``).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError, NotAdmissibleError
from ..kernels.admissibility import non_finite_problem
from ..kernels.tetrahedra import (TET_FACES, mean_ratios, orientations, signed_volumes,
                                  tet_quality_summary)
from .surface import SurfaceMesh, listed
from .topology import _frozen, new_points, tagged_vertices
from .value import MeshValue

__all__ = ["TetMesh"]


def _indices(values, k: int, name: str, n: int, where: str, required: bool = False):
    """``values`` as a read-only ``(M, k)`` int64 array with every index in ``[0, n)``."""
    if values is None or (not required and not np.size(values)):
        return None
    a = np.asarray(values)
    if a.size == 0:
        raise InvalidMeshError(f"{where}mesh has no {name}")
    if a.ndim != 2 or a.shape[1] != k:
        raise InvalidMeshError(f"{where}{name} must have shape (M, {k}), got {a.shape}")
    if not np.issubdtype(a.dtype, np.integer) and (
            not np.all(np.isfinite(a)) or np.any(a != np.round(a))):
        raise InvalidMeshError(f"{where}{name} indices must be integers")
    a = np.array(a, dtype=np.int64)
    out = np.flatnonzero(((a < 0) | (a >= n)).any(axis=1))
    if out.size:
        raise InvalidMeshError(f"{where}{name} {out[0]} {a[out[0]].tolist()} has a vertex "
                               f"index out of range [0, {n})")
    return _frozen(a)


def _tags(values, m: int, name: str, where: str, default_zero: bool = False):
    if values is None:
        return _frozen(np.zeros(m, np.int64)) if default_zero else None
    t = np.array(values, dtype=np.int64).reshape(-1)
    if t.shape != (m,):
        raise InvalidMeshError(f"{where}{name} must have one entry per element")
    return _frozen(t)


class TetMesh(MeshValue):
    """A tetrahedral mesh ``TetMesh(points, tets)``.

    Parameters
    ----------
    points : (N, 3) array_like of float
    tets : (M, 4) array_like of int
    tet_tags : (M,) array_like of int, optional
        Physical tag per tetrahedron.
    triangles, lines : (K, 3) / (L, 2) array_like of int, optional
        Tagged surface triangles and line elements kept from the file (gmsh boundary
        groups); ``triangle_tags`` / ``line_tags`` their physical tags (zeros if left out).
    tag_names : dict, optional
        ``{name: (tag, dim)}``.
    source : str, optional

    Raises
    ------
    InvalidMeshError
        Points not ``(N, 3)`` or not finite, indices out of range, wrong shapes, no
        tetrahedron.
    """

    _cells, _count = "tets", "n_tets"  # repr and == (MeshValue)

    def __init__(self, points, tets, *, tet_tags=None, triangles=None, triangle_tags=None,
                 lines=None, line_tags=None, tag_names: dict | None = None,
                 source: str | None = None) -> None:
        where = f"{source}: " if source else ""
        pts = np.array(points, dtype=np.float64, copy=True)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InvalidMeshError(f"{where}points must have shape (N, 3), got {pts.shape}")
        if not np.isfinite(pts).all():
            raise InvalidMeshError(where + non_finite_problem(pts, show=True))
        n = len(pts)
        self._points = _frozen(pts)
        self._tets = _indices(tets, 4, "tetrahedra", n, where, required=True)
        self._tet_tags = _tags(tet_tags, len(self._tets), "tet_tags", where)
        self._triangles = _indices(triangles, 3, "triangles", n, where)
        self._triangle_tags = None if self._triangles is None else _tags(
            triangle_tags, len(self._triangles), "triangle_tags", where, default_zero=True)
        self._lines = _indices(lines, 2, "lines", n, where)
        self._line_tags = None if self._lines is None else _tags(
            line_tags, len(self._lines), "line_tags", where, default_zero=True)
        self._tag_names = dict(tag_names or {})
        self._source = source

    # -- plain data -----------------------------------------------------------------
    points = property(lambda self: self._points, doc="Read-only ``(N, 3)`` float64.")
    tets = property(lambda self: self._tets, doc="Read-only ``(M, 4)`` int64.")
    tet_tags = property(lambda self: self._tet_tags, doc="``(M,)`` or None.")
    triangles = property(lambda self: self._triangles, doc="Tagged triangles or None.")
    triangle_tags = property(lambda self: self._triangle_tags, doc="``(K,)`` or None.")
    lines = property(lambda self: self._lines, doc="Tagged lines ``(L, 2)`` or None.")
    line_tags = property(lambda self: self._line_tags, doc="``(L,)`` or None.")
    tag_names = property(lambda self: dict(self._tag_names), doc="``{name: (tag, dim)}``.")
    source = property(lambda self: self._source, doc="The file it was read from.")
    n_vertices = property(lambda self: len(self._points))
    n_tets = property(lambda self: len(self._tets))

    def with_points(self, points) -> TetMesh:
        """A new mesh with the same cells and tags at new positions ``(N, 3)``."""
        return TetMesh(new_points(points, self._points.shape), self._tets, tet_tags=self._tet_tags, triangles=self._triangles,
                       triangle_tags=self._triangle_tags, lines=self._lines,
                       line_tags=self._line_tags, tag_names=self._tag_names,
                       source=self._source)

    def tagged_vertices(self, tag: int | str) -> IntArray:
        """Sorted vertices of the elements carrying a physical tag (a number: lines,
        triangles and tets with it) or name (the elements of its dimension only):
        :func:`~.topology.tagged_vertices`."""
        return tagged_vertices(tag, self._tag_names, (
            (1, self._lines, self._line_tags), (2, self._triangles, self._triangle_tags),
            (3, self._tets, self._tet_tags)))

    # -- topology (cached) ----------------------------------------------------------
    @cached_property
    def _face_data(self) -> tuple[IntArray, IntArray]:
        """All ``4 M`` faces ``(4 M, 3)`` (face ``l M + k`` is opposite vertex ``l`` of tet
        ``k``, outward for a positive tet) and the number of tets holding each."""
        faces = self._tets[:, TET_FACES].transpose(1, 0, 2).reshape(-1, 3)
        key = np.sort(faces, axis=1)
        order = np.lexsort(key.T[::-1])
        k = key[order]
        start = np.ones(len(k), dtype=bool)
        start[1:] = (k[1:] != k[:-1]).any(axis=1)
        group = np.cumsum(start) - 1
        counts = np.bincount(group)
        count = np.empty(len(faces), np.int64)
        count[order] = counts[group]
        return _frozen(faces), _frozen(count)

    @cached_property
    def boundary_faces(self) -> IntArray:
        """Faces of one tetrahedron ``(F, 3)``, oriented outward (right-hand rule)."""
        faces, count = self._face_data
        return _frozen(np.ascontiguousarray(faces[count == 1]))

    @cached_property
    def boundary_vertices(self) -> IntArray:
        """Sorted indices of the vertices on boundary faces."""
        return _frozen(np.unique(self.boundary_faces))

    @cached_property
    def non_manifold_faces(self) -> IntArray:
        """Faces in three or more tetrahedra (each listed once, sorted vertices)."""
        faces, count = self._face_data
        bad = np.sort(faces[count > 2], axis=1)
        return _frozen(np.unique(bad, axis=0) if len(bad) else bad)

    def boundary_surface(self) -> SurfaceMesh:
        """The boundary faces as a :class:`SurfaceMesh` over all the points."""
        return SurfaceMesh(self._points, self.boundary_faces, source=self._source)

    # -- geometry -------------------------------------------------------------------
    @cached_property
    def signed_volumes(self) -> FloatArray:
        """Signed volume per tetrahedron ``(M,)``."""
        return _frozen(signed_volumes(self._points, self._tets))

    def mean_ratios(self) -> FloatArray:
        """Signed mean ratio quality per tetrahedron ``(M,)`` (1: regular)."""
        return mean_ratios(self._points, self._tets)

    def quality(self):
        """:class:`~meshopt_toolkit.kernels.tetrahedra.TetQualitySummary` of the mesh."""
        return tet_quality_summary(self._points, self._tets)

    # -- admissibility --------------------------------------------------------------
    @cached_property
    def inverted(self) -> IntArray:
        """Tetrahedra with signed volume ≤ 0 (inverted or flat), sorted; by the volume's
        sign at the tet's own scale (a volume below the float range is still positive)."""
        return _frozen(np.flatnonzero(orientations(self._points, self._tets) <= 0))

    @property
    def is_admissible(self) -> bool:
        """Every tetrahedron positively oriented."""
        return not len(self.inverted)

    @property
    def problems(self) -> list[str]:
        """One line per problem: inverted or flat tetrahedra, faces in more than two."""
        out = []
        if len(self.inverted):
            out.append(f"{len(self.inverted)} tetrahedra are inverted or flat (signed volume "
                       f"<= 0): {listed(self.inverted)}")
        bad = self.non_manifold_faces
        if len(bad):
            out.append(f"{len(bad)} faces in more than two tetrahedra (first: "
                       f"{tuple(int(i) for i in bad[0])})")
        return out

    def require_admissible(self) -> TetMesh:
        """Return self, or raise :class:`NotAdmissibleError` naming the inverted tets."""
        if len(self.inverted):
            where = f"{self._source}: " if self._source else ""
            raise NotAdmissibleError(f"{where}{self.problems[0]}")
        return self
