"""Taylor tests: verify derivatives by the decay rate of expansion remainders.

For a smooth ``f`` and direction ``v``

- first order:  ``|f(x + εv) − f(x) − ε ∇f(x)·v|                  = O(ε²)``
- second order: ``|f(x + εv) − f(x) − ε ∇f(x)·v − ½ε² v·∇²f(x) v| = O(ε³)``

A wrong derivative gives order 1 (or 2). The observed order is the slope of
``log(remainder)`` against ``log(ε)`` on a log-spaced sweep, fitted only where the
remainder stands clear of floating-point round-off. These are public diagnostics: run them
on your own objectives before handing them to an optimizer.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ._options import require_shape

__all__ = ["TaylorResult", "check_gradient", "check_hvp", "taylor_remainders"]


@dataclass(frozen=True)
class TaylorResult:
    """Outcome of a Taylor test.

    Attributes
    ----------
    eps : (K,) step sizes (decreasing)
    remainders : (K,) remainder magnitudes
    order : observed order (median slope over the usable range)
    expected : the order a correct derivative gives
    usable : (K,) bool, points above the round-off floor used for the fit
    """

    eps: np.ndarray
    remainders: np.ndarray
    order: float
    expected: int
    usable: np.ndarray

    @property
    def passed(self) -> bool:
        """True when the observed order is within 0.3 of the expected one (or the
        remainders sit at round-off for every ε, i.e. the expansion is exact)."""
        if not self.usable.any():
            return True
        return bool(self.order > self.expected - 0.3)

    def __str__(self) -> str:
        rows = "\n".join(f"  eps={e:9.3e}  remainder={r:10.3e}" for e, r in zip(self.eps, self.remainders))
        return f"Taylor test: observed order {self.order:.3f} (expected {self.expected})\n{rows}"


def _as_direction(x: np.ndarray, direction, rng) -> np.ndarray:
    if direction is None:
        rng = np.random.default_rng(rng)
        direction = rng.standard_normal(np.shape(x))
    return require_shape("direction", np.asarray(direction, dtype=float), np.shape(x))


def taylor_remainders(
    f: Callable[[np.ndarray], float],
    x: np.ndarray,
    v: np.ndarray,
    slope: float,
    curvature: float | None,
    eps: np.ndarray,
) -> np.ndarray:
    """Remainders ``|f(x+εv) − f(x) − ε slope [− ½ε² curvature]|`` for each ε."""
    f0 = float(f(x))
    out = np.empty(len(eps))
    for k, e in enumerate(eps):
        model = f0 + e * slope
        if curvature is not None:
            model += 0.5 * e * e * curvature
        out[k] = abs(float(f(x + e * v)) - model)
    return out


def _observed_order(eps, rem, scale, expected):
    floor = 1e3 * np.finfo(float).eps * max(scale, 1e-300)
    usable = rem > floor
    idx = np.flatnonzero(usable)
    if idx.size < 2:
        return float("nan") if idx.size else float(expected), usable
    le, lr = np.log(eps[idx]), np.log(rem[idx])
    slopes = np.diff(lr) / np.diff(le)
    return float(np.median(slopes)), usable


def _slope_along(gradient, x, direction, rng) -> tuple[np.ndarray, np.ndarray, float]:
    """``(x, v, ∇f(x)·v)``: x as floats, the direction ``v`` (:func:`_as_direction`)."""
    x = np.asarray(x, dtype=float)
    v = _as_direction(x, direction, rng)
    return x, v, float(np.vdot(gradient(x), v))


def _taylor_test(f, x, v, slope: float, curvature: float | None, eps0: float,
                 n: int) -> TaylorResult:
    """The Taylor test along ``v`` of the first-order model (``curvature`` None: expect
    order 2) or the second-order one (expect order 3), on ``n`` steps halving ``eps0``."""
    eps = eps0 * 2.0 ** -np.arange(n)
    rem = taylor_remainders(f, x, v, slope, curvature, eps)
    scale = abs(float(f(x))) + abs(slope) * eps0
    if curvature is not None:
        scale += abs(curvature) * eps0**2
    expected = 2 if curvature is None else 3
    order, usable = _observed_order(eps, rem, scale, expected)
    return TaylorResult(eps, rem, order, expected, usable)


def check_gradient(f: Callable[[np.ndarray], float], gradient: Callable[[np.ndarray], np.ndarray],
                   x: np.ndarray, direction: np.ndarray | None = None, *, eps0: float = 1e-2,
                   n: int = 10, rng=None) -> TaylorResult:
    """First-order Taylor test of ``gradient`` against ``f`` at ``x``: expect order 2.

    Parameters
    ----------
    f : callable, x -> float
    gradient : callable, x -> array shaped like x
    x : array (any shape, e.g. (N, 2) node positions)
    direction : array shaped like x, optional (random normal by default)
    eps0 : largest step; the sweep halves it ``n - 1`` times
    n : number of steps
    rng : seed or Generator for the random direction

    Returns
    -------
    TaylorResult with ``expected = 2``.
    """
    x, v, slope = _slope_along(gradient, x, direction, rng)
    return _taylor_test(f, x, v, slope, None, eps0, n)


def check_hvp(
    f: Callable[[np.ndarray], float],
    gradient: Callable[[np.ndarray], np.ndarray],
    hvp: Callable[[np.ndarray, np.ndarray], np.ndarray],
    x: np.ndarray,
    direction: np.ndarray | None = None,
    *,
    eps0: float = 1e-2,
    n: int = 10,
    rng=None,
) -> TaylorResult:
    """Second-order Taylor test of ``hvp(x, v) = ∇²f(x) v``: expect order 3.

    Parameters are as in :func:`check_gradient`; ``hvp`` takes ``(x, v)``.

    Returns
    -------
    TaylorResult with ``expected = 3``.
    """
    x, v, slope = _slope_along(gradient, x, direction, rng)
    return _taylor_test(f, x, v, slope, float(np.vdot(v, hvp(x, v))), eps0, n)
