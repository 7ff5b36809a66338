"""How :func:`~meshopt_toolkit.riemannian.geodesics.geodesic` integrates: one options
object instead of a dozen keyword arguments (the methods are described in
:mod:`.geodesics`' docstring)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .._options import check_choice, options_of, require_at_least, require_positive
from ..errors import IntegrationError

#: the integration methods (see :mod:`.geodesics`)
METHODS = ("auto", "dop853", "dopri5", "bs3", "line-search", "stormer-verlet", "scipy")

#: what a violated invariant does
ON_VIOLATION = ("warn", "raise", "ignore")


@dataclass(frozen=True)
class GeodesicOptions:
    """Settings of one geodesic integration; every field has a default.

    Attributes
    ----------
    method : one of :data:`METHODS` ("auto" = "dop853")
    rtol, atol : adaptive tolerances (defaults per method, ``atol = rtol·scale``)
    energy_tol : allowed relative energy drift before a violation is reported (default
        ``max(1e-3, 1e4·rtol)`` for the adaptive methods, 1e-2 for Störmer–Verlet)
    on_violation : "warn" (GeodesicWarning), "raise" (IntegrationError) or "ignore"
    max_steps : cap on adaptive steps
    dense : adaptive methods only. True (default): outputs inside a step are interpolated
        — by DOP853's 7th-order continuous extension (3 more penalty calls in a step that
        holds outputs; positions and velocities as accurate as the steps), by the quintic
        Hermite interpolant of ``(Q, Q', Q'')`` for the other pairs (velocities one order
        less accurate, so ``energy`` at such outputs shows the interpolation error) — so
        many output times are cheap. False: every output time is a step end.
    monitor : True: evaluate ``f`` (and ``∇f`` at interpolated outputs, for the energy)
        at every output and check the invariants (one penalty call per output). False:
        positions only — ``penalty`` is NaN except at t = 0 and ``energy`` is NaN at
        interpolated outputs; no invariant is checked. None (default): False for
        ``"line-search"``, else True.
    h0 : first step of the adaptive methods (e.g. ``last_step`` of a previous, similar
        geodesic); default Hairer's tolerance-aware heuristic (one penalty call), for
        ``"line-search"`` ``LINE_SEARCH_FIRST_STEP`` of the interval.
    steps : Störmer–Verlet steps on [0, time] (default 1024)
    fixed_point_tolerance, fixed_point_max_iterations : Störmer–Verlet fixed-point tolerance
        and cap
    """

    method: str = "auto"
    rtol: float | None = None
    atol: float | None = None
    energy_tol: float | None = None
    on_violation: str = "warn"
    max_steps: int = 100_000
    dense: bool = True
    monitor: bool | None = None
    h0: float | None = None
    steps: int | None = None
    fixed_point_tolerance: float = 1e-8
    fixed_point_max_iterations: int = 10

    def __post_init__(self) -> None:
        check_choice(self.method, METHODS, "geodesic method", error=IntegrationError)
        if self.on_violation not in ON_VIOLATION:
            raise IntegrationError("on_violation must be 'warn', 'raise' or 'ignore', got "
                                   f"{self.on_violation!r}")
        for name in ("rtol", "energy_tol", "h0"):
            require_positive(name, getattr(self, name), error=IntegrationError)
        if self.atol is not None and not self.atol >= 0:
            raise IntegrationError(f"atol must be >= 0, got {self.atol!r}")
        for name in ("max_steps", "fixed_point_max_iterations", "steps"):
            require_at_least(name, getattr(self, name), 1, error=IntegrationError)

    @classmethod
    def of(cls, options: GeodesicOptions | Mapping | None = None, **settings) -> GeodesicOptions:
        """``options`` (an instance, a mapping of fields, or None for the defaults) with
        ``settings`` (fields) on top; an unknown field is a TypeError naming it."""
        return options_of(cls, options, settings, error=TypeError, what="geodesic setting(s)")
