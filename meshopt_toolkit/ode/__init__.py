"""Integrators for second-order fields ``Q'' = A(Q, Q')`` on node positions (SPEC §5):
the declared field interface and output (``base``), the Runge–Kutta pairs and Hermite
dense output (``tableaus``), adaptive Runge–Kutta (``runge_kutta``) and Störmer–Verlet
(``verlet``). See :mod:`.base` for the method notes.
"""

from __future__ import annotations

from .base import IntegrationOutput, SecondOrderField, energy
from .runge_kutta import StepControl, bs3, dop853, dopri5, runge_kutta
from .tableaus import BS3_TABLEAU, DOPRI5_TABLEAU, PAIRS, _hermite, _hermite_many, rk_pair
from .verlet import stormer_verlet

__all__ = [
    "BS3_TABLEAU",
    "DOPRI5_TABLEAU",
    "PAIRS",
    "IntegrationOutput",
    "SecondOrderField",
    "StepControl",
    "bs3",
    "dop853",
    "dopri5",
    "energy",
    "rk_pair",
    "runge_kutta",
    "stormer_verlet",
]

_PRIVATE_REEXPORTS = (_hermite, _hermite_many)  # tests import them from here
