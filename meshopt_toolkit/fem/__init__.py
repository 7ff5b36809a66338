"""Finite elements: planar P1 stiffness and loads (``p1``), the Poisson model problem and
its shape derivative (``poisson``), linear elasticity (``elasticity``) and the
as-rigid-as-possible interpolation built on them (``interpolation``); on triangles and
tetrahedra alike, P1/P2 elements (``simplex``), the Poisson objective
(``poisson_simplex``), elasticity with the compliance (``linear_elasticity``) and
Taylor–Hood Stokes flow with the dissipation (``stokes``).

``from meshopt_toolkit import fem; fem.PoissonSolver`` keeps working: the names of
``fem.p1`` are re-exported here.
"""

from __future__ import annotations

from .p1 import (  # noqa: F401 (re-exported)
    AMG_THRESHOLD,
    PoissonSolver,
    centroids,
    element_stiffness,
    lumped_load,
    nodal_mass_weights,
    p1_stiffness,
    poisson_shape_derivative,
)
from .p1 import __all__ as _p1_all

__all__ = list(_p1_all)
