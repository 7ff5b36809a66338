"""Triangles in the plane: points ``(N, 2)``, cells ``(T, 3)`` counter-clockwise.

Measures are the signed areas and quality the signed aspect ratio 2r/R
(:mod:`..kernels.triangles`), the distortion :class:`..motion.planar.distortion.TriangleDistortion`,
admissibility the exact tests of :mod:`..kernels.admissibility` (areas, then the
boundary), boundary facets the mesh's directed boundary edges (:class:`..mesh.TriangleMesh`).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..kernels.admissibility import BoundaryCheck, area_problem, area_signs
from ..kernels.triangles import aspect_ratios, signed_areas
from ..mesh import TriangleMesh
from ..motion.planar.distortion import TriangleDistortion
from ..motion.planar.metric import GraphMetric
from .base import SimplexKind

__all__ = ["PLANAR", "PlanarTriangles"]


def exact_orientations(points: FloatArray, cells: IntArray) -> np.ndarray:
    """Exact signs (T,) int8 of the triangles' signed areas (finite points)."""
    tri_t = np.ascontiguousarray(np.asarray(cells).T)
    _, sign, _ = area_signs(np.asarray(points, dtype=float), tri_t)
    return np.ones(len(cells), np.int8) if sign is None else sign


class PlanarTriangles(SimplexKind):
    """The cell kind of triangles in the plane."""

    name = "planar triangles"
    point_dimension = 2
    cell_dimension = 2
    simplex_size = 3
    #: signed areas (T,), positive iff counter-clockwise; aspect ratio 2r/R (T,), signed
    #: like the area; the per-triangle distortion (T, 3)
    measure_kernel = staticmethod(signed_areas)
    quality_kernel = staticmethod(aspect_ratios)
    distortion_class = TriangleDistortion

    def boundary_facets(self, points: FloatArray, cells: IntArray) -> IntArray:
        """Boundary edges (B, 2), directed as in their triangle (interior on the left)."""
        return TriangleMesh(points, cells).boundary_edges

    def admissibility_problem(self, points: FloatArray, cells: IntArray) -> str | None:
        """A message naming a non-finite vertex, a non-positive triangle, or a boundary
        that folds, touches or crosses itself or whose loops nest wrongly; None when
        admissible. Every sign is exact."""
        Q = np.ascontiguousarray(points, dtype=float)
        problem = area_problem(Q, np.ascontiguousarray(np.asarray(cells).T))
        if problem is not None:
            return problem
        mesh = TriangleMesh(Q, cells)
        return BoundaryCheck(mesh.boundary_edges, mesh.boundary_vertices).test(Q)

    def fold_test(self, points: FloatArray, cells: IntArray, rest: FloatArray) -> np.ndarray:
        """Triangles (T,) bool whose exact orientation is not the rest one's (or is 0)."""
        now = exact_orientations(points, cells)
        return now * exact_orientations(rest, cells) <= 0

    def default_metric(self, reference: FloatArray, cells: IntArray) -> GraphMetric:
        """``M + w² JᵀJ`` with ``w = 1``: the metric of ``mt.morph``'s default
        (``metric="distortion"``) and of ``mt.move`` in the plane."""
        return GraphMetric(np.asarray(reference, dtype=float), np.asarray(cells))


PLANAR = PlanarTriangles()
