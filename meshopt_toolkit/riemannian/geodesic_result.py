"""The results of the geodesic computations: :class:`GeodesicResult` of
:func:`~meshopt_toolkit.riemannian.geodesics.geodesic` with the invariant checks made when
it is assembled (energy drift, the growth bound of f, admissibility of every returned
configuration; see the guards in :mod:`.geodesics`' docstring), and the boundary-value
results :class:`DiscreteGeodesic` (:mod:`.discrete_geodesic`) and :class:`LogMapResult`
(:mod:`.log_map`)."""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._typing import FloatArray
from ..errors import IntegrationError
from ..ode import energy

logger = logging.getLogger(__name__)


class GeodesicWarning(UserWarning):
    """A runtime invariant (energy, f-growth bound) of a geodesic was violated."""


@dataclass
class GeodesicResult:
    """A geodesic sampled at output times.

    Attributes
    ----------
    times : (K,) output times (as requested, including t = 0 first when asked for)
    points : (K, N, 2) positions γ(t)
    velocities : (K, N, 2) velocities γ'(t)
    energy : (K,) ``(γ', γ')_g`` (constant along an exact geodesic)
    penalty : (K,) f(γ(t)) (NaN for the Euclidean metric)
    admissible : (K,) bool, all signed areas positive (always True for a complete metric)
    n_evaluations : penalty calls made
    n_steps, n_rejected : accepted / rejected integrator steps
    method : integrator used
    max_energy_drift : max relative energy drift over all steps (per step before the
        energy projection of ``"line-search"``)
    warnings : messages of violated invariants (empty when all held)
    last_step : step size the adaptive integrator would have tried next (NaN otherwise):
        a good ``h0`` for a similar geodesic
    """

    times: FloatArray
    points: FloatArray
    velocities: FloatArray
    energy: FloatArray
    penalty: FloatArray
    admissible: np.ndarray
    n_evaluations: int = 0
    n_steps: int = 0
    n_rejected: int = 0
    method: str = "auto"
    max_energy_drift: float = 0.0
    warnings: list[str] = field(default_factory=list)
    last_step: float = float("nan")

    @property
    def final(self) -> FloatArray:
        """Position at the last output time, (N, 2)."""
        return self.points[-1]

    def at(self, t: float) -> FloatArray:
        """Position at an output time ``t`` (exact match up to 1e-12), (N, 2)."""
        idx = np.flatnonzero(np.abs(self.times - t) <= 1e-12 * max(1.0, abs(t)))
        if idx.size == 0:
            raise KeyError(f"t = {t} is not an output time of this geodesic")
        return self.points[idx[0]]


def _report(msg: str, on_violation: str, bucket: list[str]) -> None:
    bucket.append(msg)
    if on_violation == "raise":
        raise IntegrationError(msg)
    if on_violation == "warn":
        warnings.warn(msg, GeodesicWarning, stacklevel=3)
    logger.info(msg)


def _assemble(fld, Q, V, f0, req, positive, out, method_used, monitor, rtol, energy_tol,
              on_violation) -> GeodesicResult:
    """Outputs in the requested order, with the invariant checks when ``monitor``."""
    K = req.size
    if out is not None and np.isfinite(out.initial_energy):
        e0 = out.initial_energy
    else:
        e0 = energy(fld.gradient(Q), V)
    pts = np.empty((K,) + Q.shape)
    vel = np.empty((K,) + Q.shape)
    en = np.empty(K)
    for j, t in enumerate(req):
        if t == 0 or out is None:  # (out is None: t = 0 only, or V = 0 and γ is constant)
            pts[j], vel[j], en[j] = Q, V, e0
        else:
            i = int(np.searchsorted(positive, t))
            pts[j], vel[j], en[j] = out.points[i], out.velocities[i], out.energy[i]
    fvals = np.full(K, f0)
    if monitor:
        for j, t in enumerate(req):
            if t == 0 or out is None:
                continue
            if np.isnan(en[j]):  # an interpolated output: energy from the gradient there
                fvals[j], grad = fld.value_and_gradient(pts[j])
                en[j] = energy(grad, vel[j])
            else:
                fvals[j] = fld.value(pts[j])
    else:
        fvals[req != 0] = np.nan
    # every returned configuration was checked by the integrator (areas at every output,
    # the boundary exactly or by certificate); recheck the areas in one batched pass
    adm = np.ones(K, dtype=bool)
    if fld.triangles is not None:
        z = np.ascontiguousarray(pts).view(np.complex128)[..., 0][:, fld.triangles.T]
        adm = ((z[:, 1] - z[:, 0]).conj() * (z[:, 2] - z[:, 0])).imag.min(axis=1) > 0
    else:
        adm = np.array([fld.admissible(p) for p in pts])
    if not adm.all():  # cannot happen: every accepted step is checked
        raise IntegrationError("internal error: the integrator produced an inverted mesh")

    notes: list[str] = []
    drift = 0.0 if out is None else out.max_energy_drift
    if monitor:
        if energy_tol is None:
            if method_used == "stormer-verlet":
                energy_tol = 1e-2
            else:
                energy_tol = max(1e-3, 1e4 * rtol)
        if e0 > 0 and drift > energy_tol:
            _report(f"geodesic energy drifted by {drift:.3g} (relative) > {energy_tol:g}; "
                    "tighten the tolerance or use more steps", on_violation, notes)
        e_max = max(e0, float(np.max(en)))
        bound = np.sqrt(e_max) * req * (1 + energy_tol) + 1e-10 * (1 + abs(f0))
        excess = np.abs(fvals - f0) - bound
        if np.any(excess > 0):
            j = int(np.argmax(excess))
            _report(f"f-growth bound violated at t = {req[j]:.6g}: |f(γ(t)) − f(γ(0))| = "
                    f"{abs(fvals[j] - f0):.6g} > √e·t = {bound[j]:.6g}", on_violation, notes)
    return GeodesicResult(
        times=req, points=pts, velocities=vel, energy=en, penalty=fvals, admissible=adm,
        n_evaluations=fld.n_evaluations, n_steps=0 if out is None else out.n_steps,
        n_rejected=0 if out is None else out.n_rejected, method=method_used,
        max_energy_drift=drift, warnings=notes,
        last_step=np.nan if out is None else out.h_last,
    )


@dataclass
class DiscreteGeodesic:
    """A minimizer of the discrete path energy (both methods of :func:`discrete_geodesic`).

    Attributes
    ----------
    points : (K+1, N, 2) frames, ``points[0] = Q0`` exactly (and ``points[K] = Q1`` where
        the last frame is fixed)
    penalty : (K+1,) ``f`` at each frame (Newton–CG; NaN for Levenberg–Marquardt and
        straight lines)
    energy : path energy ``E`` (``√E`` is the discrete length for an equally spaced path)
    length : ``Σ_k |X(Q_{k+1}) − X(Q_k)|``, the length of the polygon through the embedded
        frames (``X(Q) = (Q, f(Q))`` for a complete metric)
    nit : iterations
    gradient_norm : final ``√(∇E · H_GN⁻¹ ∇E)`` (Newton–CG; 0 for K = 1) or ``|∇E|``
        (Levenberg–Marquardt)
    converged : whether the method's gradient test was met (``status == "converged"``)
    n_evaluations : penalty calls (values, gradients and Hessian-vector products;
        Newton–CG)
    status : why the iteration stopped: "converged" (gradient test, or the minimum to
        machine precision), "max_iter", and for Newton–CG "stationary" (the energy
        stagnated) or "line_search" (no decrease found), for Levenberg–Marquardt
        "stalled" (no admissible step lowers the energy); "stopped" when the callback
        returned True
    history : ``(E, |∇E|)`` at each Levenberg–Marquardt iteration
    initial_energy : the energy of the start where the method reports it (the surface
        path model's; None where the start was returned unevaluated)
    factorizations : the step solver's factorizations where the method reports them
    """

    points: FloatArray
    penalty: FloatArray
    energy: float
    length: float
    nit: int = 0
    gradient_norm: float = 0.0
    converged: bool = True
    n_evaluations: int = 0
    status: str = "converged"
    history: list = field(default_factory=list)
    initial_energy: float | None = None
    factorizations: int = 0

    @property
    def segments(self) -> int:
        return len(self.points) - 1

    def initial_velocity(self) -> FloatArray:
        """``γ'(0)`` from the frames: ``K(−3Q_0 + 4Q_1 − Q_2)/2`` (second order), (N, 2)."""
        K = self.segments
        P = self.points
        if K == 1:
            return P[1] - P[0]
        return 0.5 * K * (-3.0 * P[0] + 4.0 * P[1] - P[2])


@dataclass
class LogMapResult:
    """Outcome of :func:`log_map`.

    Attributes
    ----------
    velocity : (N, 2) ``V`` with ``exp_{Q0}(V) ≈ Q1``
    residual : ``max |exp_{Q0}(V) − Q1|`` (max-norm over coordinates)
    tol : the tolerance asked for
    iterations : Newton iterations of the shooting
    path_length : ``|V|_g`` at ``Q0`` = length of the geodesic ``t ↦ exp(tV)``, t ∈ [0, 1]
    success : ``residual ≤ tol``
    n_exp : exponential maps evaluated (residuals and directional differences)
    discrete : the discrete geodesic that gave the initial guess (None if not used)
    message : a one-line account
    seconds : wall time
    """

    velocity: FloatArray
    residual: float
    tol: float
    iterations: int
    path_length: float
    success: bool
    n_exp: int = 0
    discrete: DiscreteGeodesic | None = None
    message: str = ""
    seconds: float = 0.0
