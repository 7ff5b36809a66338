"""Compatibility alias: the integrators now live in :mod:`meshopt_toolkit.ode` and the
geodesic field they integrate in :mod:`meshopt_toolkit.riemannian.field`.

New code imports the new paths.
"""

from .ode import *  # noqa: F401,F403
from .ode import __all__ as _ode_all
from .riemannian.field import BoundaryGuard, GeodesicField  # noqa: F401

__all__ = [*_ode_all, "BoundaryGuard", "GeodesicField"]
