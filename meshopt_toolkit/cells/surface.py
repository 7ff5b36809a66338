"""Triangles in space: points ``(N, 3)``, cells ``(T, 3)`` (a surface, open or closed).

A triangle in space has no orientation of its own: measures are the unsigned areas and
quality the unsigned aspect ratio 2r/R (:mod:`..kernels.surface`); a fold is a normal
turned against the rest normal carried by its neighbourhood's best rotation
(:class:`..motion.surface.folds.FoldTest`). Admissibility is exact
(:mod:`..kernels.intersections3d`): finite points, no triangle of exactly collinear
corners, no two triangles that intersect improperly. The distortion is the membrane one,
:class:`..motion.surface.distortion.SurfaceDistortion`, its Jacobians those of the maps
from each rest triangle's own plane.
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..kernels.admissibility import non_finite_problem
from ..kernels.cell_maps import triangle_plane_coordinates
from ..kernels.intersections3d import degenerate_triangles_exact, self_intersections
from ..kernels.surface import areas, aspect_ratios
from ..mesh import SurfaceMesh
from ..mesh.surface import listed
from ..motion.surface.distortion import SurfaceDistortion
from ..motion.surface.folds import FoldTest
from ..motion.surface.metric import SurfaceGraphMetric
from .base import SimplexKind

__all__ = ["SURFACE", "SurfaceTriangles"]


class SurfaceTriangles(SimplexKind):
    """The cell kind of triangles in space."""

    name = "surface triangles"
    point_dimension = 3
    cell_dimension = 2
    simplex_size = 3
    #: areas (T,) ≥ 0 (unsigned: no orientation of its own); aspect ratio 2r/R (T,) in
    #: [0, 1]; the membrane distortion (T, 3)
    measure_kernel = staticmethod(areas)
    quality_kernel = staticmethod(aspect_ratios)
    distortion_class = SurfaceDistortion

    def rest_coordinates(self, rest: FloatArray, cells: IntArray) -> FloatArray:
        """Rest corners in an orthonormal frame of each triangle's own plane (T, 3, 2)."""
        return triangle_plane_coordinates(rest, cells)

    def boundary_facets(self, points: FloatArray, cells: IntArray) -> IntArray:
        """Boundary edges (B, 2), directed as in their triangle."""
        return SurfaceMesh(points, cells).boundary_edges

    def admissibility_problem(self, points: FloatArray, cells: IntArray) -> str | None:
        """A message naming a non-finite vertex, triangles with exactly collinear corners
        or two triangles that intersect improperly; None when admissible (exact)."""
        V = np.asarray(points, dtype=float)
        F = np.asarray(cells, dtype=np.int64)
        problem = non_finite_problem(V)
        if problem is not None:
            return problem
        flat = np.flatnonzero(degenerate_triangles_exact(V, F))
        if len(flat):
            return f"{len(flat)} triangles have collinear corners (zero area): {listed(flat)}"
        hits = self_intersections(V, F)
        if len(hits):
            return (f"{len(hits)} pairs of triangles intersect (first: triangles "
                    f"{hits[0, 0]} and {hits[0, 1]})")
        return None

    def fold_test(self, points: FloatArray, cells: IntArray, rest: FloatArray) -> np.ndarray:
        """Folded triangles (T,) bool against ``rest`` (:class:`FoldTest`)."""
        return FoldTest(rest, cells).mask(np.asarray(points, dtype=float))

    def default_metric(self, reference: FloatArray, cells: IntArray) -> SurfaceGraphMetric:
        """The surface morph's metric (membrane distortion and shell bending at
        ``mt.morph``'s defaults)."""
        return SurfaceGraphMetric(np.asarray(reference, dtype=float), np.asarray(cells))


SURFACE = SurfaceTriangles()
