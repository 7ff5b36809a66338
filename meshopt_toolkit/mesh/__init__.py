"""Triangle meshes with fixed connectivity (SPEC §1).

:class:`TriangleMesh` is the *readable* level: finite coordinates in 2D or 3D, indices in
range, at least one triangle. It is what file I/O and conversion work with.
:class:`PlanarMesh` adds planarity (points are stored as ``(N, 2)``) and is the object
every deformation and optimization works on. Both are immutable values: moving nodes
returns a new mesh (:meth:`PlanarMesh.with_points`), and derived topology is cached.

The planar-manifold checks of SPEC §1 and admissibility are reported by
:func:`check_mesh` (a :class:`MeshReport`) and enforced by :func:`require_admissible`.
A clean mesh is recognised by one exact pass over whole arrays (:func:`_clean_manifold`:
one sort of the half-edges, a breadth-first search, a walk around every vertex); only a
mesh with a problem pays for the edge list and the description of its first problem.
"""

from . import checks, core, topology  # noqa: F401 (submodules, for tests and readers)
from .checks import (MeshReport, _check_mesh, boundary_self_intersections, check_mesh,  # noqa: F401
                     require_admissible)
from .core import PlanarMesh, TriangleMesh, _frozen  # noqa: F401
from .topology import (_clean_manifold, _corner_table, _fans_per_vertex,  # noqa: F401
                       _manifold_problems, _sorted_half_edges)

__all__ = [
    "MeshReport",
    "PlanarMesh",
    "TriangleMesh",
    "boundary_self_intersections",
    "check_mesh",
    "require_admissible",
]
