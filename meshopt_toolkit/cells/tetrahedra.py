"""Tetrahedra: points ``(N, 3)``, cells ``(C, 4)`` positively oriented.

Measures are the signed volumes and quality the signed mean ratio
(:mod:`..kernels.tetrahedra`), the distortion
:class:`..motion.tets.distortion.TetDistortion`, boundary facets the outward faces of
:class:`..mesh.TetMesh`. Admissibility is exact: every tet positively oriented
(``orient3d``, :mod:`..kernels.predicates`) and a boundary that does not intersect itself
(:mod:`..kernels.intersections3d`).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..kernels.admissibility import non_finite_problem
from ..kernels.intersections3d import self_intersections
from ..kernels.predicates import orient3d
from ..kernels.tetrahedra import mean_ratios, signed_volumes
from ..mesh import TetMesh
from ..mesh.surface import listed
from ..motion.tets.distortion import TetDistortion
from ..motion.tets.metric import TetGraphMetric
from .base import SimplexKind

__all__ = ["TETRAHEDRA", "Tetrahedra"]


def exact_orientations(points: FloatArray, cells: IntArray) -> np.ndarray:
    """Exact signs (C,) int8 of the tets' signed volumes (finite points)."""
    p = np.asarray(points, dtype=float)[np.asarray(cells)]
    return orient3d(p[:, 0], p[:, 1], p[:, 2], p[:, 3])


class Tetrahedra(SimplexKind):
    """The cell kind of tetrahedra."""

    name = "tetrahedra"
    point_dimension = 3
    cell_dimension = 3
    simplex_size = 4
    #: signed volumes (C,), positive iff positively oriented; mean ratio (C,), signed
    #: like the volume; the per-tet distortion (C, 7)
    measure_kernel = staticmethod(signed_volumes)
    quality_kernel = staticmethod(mean_ratios)
    distortion_class = TetDistortion

    def boundary_facets(self, points: FloatArray, cells: IntArray) -> IntArray:
        """Boundary faces (F, 3), outward for positive tets."""
        return TetMesh(points, cells).boundary_faces

    def admissibility_problem(self, points: FloatArray, cells: IntArray) -> str | None:
        """A message naming a non-finite vertex, tets not positively oriented or boundary
        faces that intersect; None when admissible (exact)."""
        V = np.asarray(points, dtype=float)
        problem = non_finite_problem(V)
        if problem is not None:
            return problem
        bad = np.flatnonzero(exact_orientations(V, cells) <= 0)
        if len(bad):
            return (f"{len(bad)} tetrahedra are inverted or flat (signed volume <= 0): "
                    f"{listed(bad)}")
        faces = self.boundary_facets(V, cells)
        hits = self_intersections(V, faces)
        if len(hits):
            a, b = faces[hits[0, 0]], faces[hits[0, 1]]
            return (f"the boundary intersects itself: faces {tuple(int(i) for i in a)} and "
                    f"{tuple(int(i) for i in b)}")
        return None

    def fold_test(self, points: FloatArray, cells: IntArray, rest: FloatArray) -> np.ndarray:
        """Tets (C,) bool whose exact orientation is not the rest one's (or is 0)."""
        return exact_orientations(points, cells) * exact_orientations(rest, cells) <= 0

    def default_metric(self, reference: FloatArray, cells: IntArray) -> TetGraphMetric:
        """``M + w² JᵀJ`` of the tet distortion with ``w = 1``: the metric of ``mt.morph``
        and ``mt.move`` for tet meshes."""
        return TetGraphMetric(np.asarray(reference, dtype=float), np.asarray(cells))


TETRAHEDRA = Tetrahedra()
