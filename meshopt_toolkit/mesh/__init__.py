"""Meshes: the immutable triangle-mesh values (``core``), triangle surfaces in 3D
(``surface``) and tetrahedral meshes (``volume``), their half-edge topology
(``topology``) and the planar-manifold checks and admissibility of SPEC §1 (``checks``).

``from meshopt_toolkit.mesh import PlanarMesh`` keeps working.
"""

from __future__ import annotations

from ..kernels.boundary import boundary_self_intersections
from .checks import MeshReport, check_mesh, require_admissible
from .core import PlanarMesh, TriangleMesh
from .surface import SurfaceMesh
from .topology import _fans_per_vertex
from .volume import TetMesh

__all__ = [
    "MeshReport",
    "PlanarMesh",
    "SurfaceMesh",
    "TetMesh",
    "TriangleMesh",
    "boundary_self_intersections",
    "check_mesh",
    "require_admissible",
]

# a private name another module imports from here (orientation), kept importable
_PRIVATE_REEXPORTS = (_fans_per_vertex,)
