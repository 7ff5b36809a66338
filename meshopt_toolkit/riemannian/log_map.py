"""The log map by shooting: Newton–Krylov on ``exp_{Q0}(V) − Q1``."""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._options import options_of
from .._typing import FloatArray
from ..descent import backtrack, halvings
from ..errors import IntegrationError, InvalidMeshError, NotAdmissibleError, OptionError
from ._boundary_value import DEFAULT_TOL, SHOOTING_RTOL, _as_points, _diameter, _require_finite
from .discrete_geodesic import discrete_geodesic
from .geodesic_result import DiscreteGeodesic, LogMapResult
from .geodesics import penalty_of

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class LogMapOptions:
    """Settings of :func:`log_map`'s Newton–Krylov shooting; every field has a default.

    Attributes
    ----------
    tolerance : max-norm tolerance on the residual (None: ``1e-8 ·`` diameter of ``Q0``)
    max_iterations : Newton iterations
    max_exp : budget of exponential maps (a Newton step needs 1 + #GMRES iterations)
    krylov : GMRES iterations per Newton step
    rtol : relative tolerance of the exponential maps of the residual
        (:func:`~.geodesics.geodesic`); check a log with ``exp_map(metric, Q0, V, rtol=rtol)``
    jacobian_rtol, jacobian_step : tolerance of the exponential maps of the directional
        differences ``J v ≈ (exp(V + h v̂) − exp(V))/h·|v|`` and ``h = jacobian_step·|V|``
        (integration noise ~1e-7/1e-3 and truncation ~1e-3: Newton converges linearly
        with a rate of about 1e-3)
    """

    tolerance: float | None = None
    max_iterations: int = 12
    max_exp: int = 2000
    krylov: int = 60
    rtol: float = SHOOTING_RTOL
    jacobian_rtol: float = 1e-7
    jacobian_step: float = 1e-3

    @classmethod
    def of(cls, options: LogMapOptions | Mapping | None = None, **changes) -> LogMapOptions:
        """``options`` (an instance, a mapping of its fields, or None: the defaults) with
        ``changes`` applied; an unknown field raises :class:`OptionError`."""
        return options_of(cls, options, changes, error=OptionError, what="log map option(s)")


def log_map(
    metric,
    Q0: FloatArray,
    Q1: FloatArray,
    *,
    V0: FloatArray | None = None,
    segments: int = 16,
    discrete: DiscreteGeodesic | None = None,
    options: LogMapOptions | Mapping | None = None,
    raise_on_failure: bool = True,
) -> LogMapResult:
    """The logarithm ``V = log_{Q0}(Q1)``: ``exp_map(metric, Q0, V, rtol=rtol) ≈ Q1``.

    Newton–Krylov shooting on ``R(V) = exp_{Q0}(V) − Q1`` (module docstring, stage 3)
    from the initial guess of a discrete geodesic of ``segments`` segments (or ``V0``).

    Parameters
    ----------
    metric : CompleteMetric (or its penalty); EuclideanMetric/None give ``Q1 − Q0``
    Q0, Q1 : (N, 2) admissible meshes of the same connectivity (arrays or meshes)
    V0 : (N, 2) initial guess (skips the discrete geodesic)
    segments : segments of the discrete geodesic of the initial guess
    discrete : a precomputed discrete geodesic from Q0 to Q1 to start from
    options : :class:`LogMapOptions` (or a mapping of its fields): the residual's
        ``tolerance``, ``max_iterations``, the budgets and the exponential maps'
        tolerances
    raise_on_failure : raise IntegrationError when the tolerance is not met (else return
        the result with ``success = False``)

    Returns
    -------
    LogMapResult
        ``velocity``, ``residual``, ``iterations``, ``path_length`` (= ``|V|_g``), ...

    Raises
    ------
    InvalidMeshError
        Shapes differ.
    NotAdmissibleError
        ``Q0`` or ``Q1`` is not admissible, or no admissible path joins them.
    IntegrationError
        The shooting did not reach the tolerance (with ``raise_on_failure``).
    OptionError
        An unknown option.
    """
    from scipy.sparse.linalg import LinearOperator, gmres

    from .geodesics import exp_map

    o = LogMapOptions.of(options)
    rtol, jacobian_rtol = o.rtol, o.jacobian_rtol
    start = time.perf_counter()
    Q0 = _as_points(Q0, "Q0")
    Q1 = _as_points(Q1, "Q1")
    if Q0.shape != Q1.shape:
        raise InvalidMeshError(f"Q0 and Q1 have shapes {Q0.shape} and {Q1.shape}")
    tol = DEFAULT_TOL * _diameter(Q0) if o.tolerance is None else float(o.tolerance)
    pen = penalty_of(metric)
    if pen is None:
        V = Q1 - Q0
        return LogMapResult(V, 0.0, tol, 0, float(np.linalg.norm(V)), True,
                            message="Euclidean metric: V = Q1 − Q0",
                            seconds=time.perf_counter() - start)
    _require_finite(pen, Q0, "the source")
    _require_finite(pen, Q1, "the target")
    if V0 is None:
        if discrete is None:
            discrete = discrete_geodesic(metric, Q0, Q1, segments)
        V = discrete.initial_velocity()
    else:
        V = np.array(V0, dtype=np.float64)
        if V.shape != Q0.shape:
            raise InvalidMeshError(f"V0 must have shape {Q0.shape}, got {V.shape}")
    n_exp = 0

    def expo(W, tolerance=rtol):
        nonlocal n_exp
        n_exp += 1
        return exp_map(metric, Q0, W, rtol=tolerance, on_violation="ignore")

    def residual_of(W):
        try:
            E = expo(W)
        except (IntegrationError, NotAdmissibleError) as exc:
            logger.debug("shooting: exp failed: %s", exc)
            return None, np.inf
        R = E - Q1
        return R, float(np.max(np.abs(R)))

    R, res = residual_of(V)
    if R is None:
        raise IntegrationError("log_map: the exponential map of the initial guess failed")
    it = 0
    message = "converged" if res <= tol else ""
    while res > tol:
        if it >= o.max_iterations or n_exp >= o.max_exp:
            message = (f"not converged: residual {res:.3g} > tol {tol:.3g} after {it} Newton "
                       f"iterations ({n_exp} exponential maps)")
            break
        it += 1
        # directional differences at a looser tolerance (cheaper steps; J needs ~1e-3)
        vnorm = max(float(np.linalg.norm(V)), 1e-3 * _diameter(Q0))
        h = o.jacobian_step * vnorm
        try:
            base = expo(V, jacobian_rtol)
        except (IntegrationError, NotAdmissibleError):
            message = "not converged: the exponential map failed at the current velocity"
            break

        def jv(v, base=base, V=V, h=h):
            v = v.reshape(V.shape)
            nv = float(np.linalg.norm(v))
            if nv == 0.0:
                return np.zeros(v.size)
            try:
                E = expo(V + (h / nv) * v, jacobian_rtol)
                sign = 1.0
            except (IntegrationError, NotAdmissibleError):
                E = expo(V - (h / nv) * v, jacobian_rtol)
                sign = -1.0
            return (sign * (E - base) * (nv / h)).ravel()

        A = LinearOperator((V.size, V.size), matvec=jv, dtype=np.float64)
        k = min(o.krylov, V.size, max(1, o.max_exp - n_exp))
        dV, _info = gmres(A, -R.ravel(), rtol=1e-3, atol=0.0,
                          restart=k, maxiter=1)
        dV = dV.reshape(V.shape)

        def try_step(lam: float, V=V, dV=dV, res=res):
            Rn, rn = residual_of(V + lam * dV)
            return (Rn, rn) if rn < res else None

        # damping: halve the step while the residual grows
        found = backtrack(try_step, halvings(count=8))
        if found is None:
            message = f"not converged: the Newton step does not reduce the residual {res:.3g}"
            break
        lam, (R, res) = found
        V = V + lam * dV
        logger.debug("shooting %d: residual %.3g (step %.3g, %d exps)", it, res, lam, n_exp)
    success = res <= tol
    if success:
        message = f"converged: residual {res:.3g} <= {tol:.3g} in {it} Newton iterations"
    from .metrics import CompleteMetric

    cm = metric if hasattr(metric, "norm") else CompleteMetric(pen)
    out = LogMapResult(V, res, tol, it, float(cm.norm(Q0, V)), bool(success), n_exp, discrete,
                       message, time.perf_counter() - start)
    if not success and raise_on_failure:
        raise IntegrationError(f"log_map: {message}")
    return out


# ---------------------------------------------------------------------------------------
# the morph
# ---------------------------------------------------------------------------------------


