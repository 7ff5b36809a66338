"""Meshes: the immutable triangle-mesh values (``core``), their half-edge topology
(``topology``) and the planar-manifold checks and admissibility of SPEC §1 (``checks``).

``from meshopt_toolkit.mesh import PlanarMesh`` keeps working.
"""

from __future__ import annotations

from ..kernels.boundary import boundary_self_intersections
from .checks import MeshReport, check_mesh, require_admissible
from .core import PlanarMesh, TriangleMesh
from .topology import _fans_per_vertex

__all__ = [
    "MeshReport",
    "PlanarMesh",
    "TriangleMesh",
    "boundary_self_intersections",
    "check_mesh",
    "require_admissible",
]

# a private name another module imports from here (orientation), kept importable
_PRIVATE_REEXPORTS = (_fans_per_vertex,)
