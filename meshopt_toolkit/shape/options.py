"""The settings of :func:`meshopt_toolkit.optimize.optimize` beyond the problem: stopping
rules, line search, L-BFGS memory and preconditioner, metric and retraction
(:class:`OptimizeOptions`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .._options import options_of, require_positive
from ..errors import OptionError
from .setup import DEFAULT_RETRACTION

__all__ = ["OptimizeOptions"]


@dataclass(frozen=True)
class OptimizeOptions:
    """Stopping rules, line search and retraction of :func:`~meshopt_toolkit.optimize`;
    every field has a default.

    Attributes
    ----------
    tolerance : stop when ``max_{m=1..5} F_{n−m} − F_n ≤ tolerance · max(|F_n|, 1)``
        (every method; the thesis' rule (6.26), made relative where ``|F_n| > 1``); None
        disables it (a fixed iteration count, as for the unpenalized runs).
    gtol : stop when the Riemannian gradient norm ``‖grad F‖_g`` falls to ``gtol`` times
        its first value (every method); None disables it.
    memory : number of L-BFGS curvature pairs kept.
    sigma, tau : Armijo parameters (6.21) (``sigma`` is ``c1`` of the Wolfe search) and
        the backtracking factor of steepest descent.
    c2 : Wolfe curvature constant (default 0.9 for lbfgs, 0.1 for cg).
    segment_fraction : lbfgs/cg with the straight-line retraction: trial steps go at most
        this fraction of the way to the first degenerate triangle along ``Q + t d``.
    min_step : a run fails (``step_too_small``) when a trial step drops below this.
    metric_options : extra keyword arguments of the metric (e.g. elasticity ``E``, ``nu``).
    retraction : complete-complete only: ``"second-order"`` (default) or ``"exp"`` (the
        exponential map), see :data:`~meshopt_toolkit.optimize.RETRACTIONS`.
    exp_options : settings of ``retraction="exp"`` (fields of
        :class:`~meshopt_toolkit.riemannian.geodesics.GeodesicOptions`, or
        ``{"options": GeodesicOptions(...)}``), on top of
        :data:`~meshopt_toolkit.optimize.EXP_DEFAULTS`.
    lbfgs_preconditioner : the L-BFGS initial inverse Hessian ``H_0 = γ B⁻¹``
        (:mod:`meshopt_toolkit.shape.preconditioners`): ``"none"`` (``B`` = the metric,
        the Riemannian two-loop with ``H_0 = γ id``), ``"penalty"`` (``B`` ≈ the Hessian
        of the penalty f2, refactorized every 5 iterations), ``"elasticity"`` (``B`` =
        the elasticity matrix), or ``"auto"`` (default): ``"penalty"`` for the complete-*
        variants with a penalty (β1 > 0), else ``"none"``. Table 6.4 set 2: complete-
        complete L-BFGS 56 → 21 iterations (steepest descent 233), 247 → 50 on the
        2198-vertex disc.
    """

    tolerance: float | None = 1e-6
    gtol: float | None = 1e-5
    memory: int = 10
    sigma: float = 1e-4
    tau: float = 0.5
    c2: float | None = None
    segment_fraction: float = 0.5
    min_step: float = 1e-6
    metric_options: dict | None = None
    retraction: str = DEFAULT_RETRACTION
    exp_options: dict | None = None
    lbfgs_preconditioner: str = "auto"

    @classmethod
    def of(cls, options: OptimizeOptions | Mapping | None = None, **changes) -> OptimizeOptions:
        """``options`` (an instance, a mapping of its fields, or None: the defaults) with
        ``changes`` applied; an unknown field raises :class:`OptionError`."""
        out = options_of(cls, options, changes, error=OptionError, what="optimize option(s)")
        out._check()
        return out

    def _check(self) -> None:
        for name in ("memory", "sigma", "min_step"):
            require_positive(name, getattr(self, name))
        if not 0 < self.tau < 1:
            raise OptionError(f"tau must be in (0, 1), got {self.tau}")
        if not 0 < self.segment_fraction <= 1:
            raise OptionError(f"segment_fraction must be in (0, 1], got {self.segment_fraction}")
        for name, value in (("tolerance", self.tolerance), ("gtol", self.gtol)):
            if value is not None and not value >= 0:
                raise OptionError(f"{name} must be >= 0 or None, got {value}")
