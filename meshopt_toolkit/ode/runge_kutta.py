"""Adaptive embedded Runge–Kutta integration of ``Q'' = A(Q, Q')`` (see the package
docstring)."""

from __future__ import annotations


from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._options import options_of
from .._typing import FloatArray
from ..errors import IntegrationError, NotAdmissibleError
from .base import IntegrationOutput, SecondOrderField, _combine, energy
from .tableaus import _Pair, _error_norm, _hermite_many, dense_evaluate, dense_polynomial, rk_pair


def _acceleration(field: SecondOrderField, y: FloatArray) -> FloatArray | None:
    """The field's acceleration at the state ``y = (Q, V)``, None where ``Q`` is not
    admissible."""
    try:
        return field.acceleration(y[0], y[1])[0]
    except NotAdmissibleError:
        return None


def _initial_step(field: SecondOrderField, y, a, rk: _Pair, rtol, atol, time: float) -> float:
    """Starting step of Hairer, Nørsett & Wanner I, II.4 (as in scipy's ``solve_ivp``), in
    the scaled max-norm: ``h₀ = 0.01 |y|/|y'|``, one trial Euler step of that size to
    estimate ``|y''|``, then ``h₁ = (0.01 / max(|y'|, |y''|))^(1/(q+1))`` (``q`` the order
    of the error estimate), ``h = min(100 h₀, h₁)``. One penalty call (none when the trial
    point is not admissible: then ``h₀``)."""
    sc = atol + rtol * np.abs(y)
    f0 = np.stack([y[1], a])
    d0 = float(np.max(np.abs(y) / sc))
    d1 = float(np.max(np.abs(f0) / sc))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, time)
    y1 = y + h0 * f0
    a1 = _acceleration(field, y1)
    if a1 is None:
        return h0
    d2 = float(np.max(np.abs(np.stack([y1[1], a1]) - f0) / sc)) / h0
    if not np.isfinite(d2):
        return h0
    if max(d1, d2) <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** rk.exponent
    return min(100.0 * h0, h1)


def _continuous_extension(field: SecondOrderField, rk: _Pair, k, y, y_new, h: float, theta):
    """``(Q, V)`` at the step fractions ``theta`` from the pair's continuous extension
    (:func:`~.tableaus.dense_polynomial`), or None when one of its extra stages is not
    admissible (the caller then interpolates by Hermite)."""
    S = len(rk.b)
    kx = np.empty((S + 1 + len(rk.dense_c),) + y.shape)
    kx[:S + 1] = k[:S + 1]
    for i, row in enumerate(rk.dense_a):
        s = S + 1 + i
        ys = y + h * _combine(row[:s], kx)
        if not field.checks_areas and not field.admissible(ys[0]):
            return None
        acc = _acceleration(field, ys)
        if acc is None or not np.isfinite(acc).all():
            return None
        kx[s, 0], kx[s, 1] = ys[1], acc
    out = dense_evaluate(dense_polynomial(rk, kx, y, y_new, h), y, theta)
    return out[:, 0], out[:, 1]


def dopri5(field: SecondOrderField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with the Dormand–Prince 5(4) pair (6 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="dopri5", **kwargs)


def dop853(field: SecondOrderField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with Hairer's DOP853 pair (12 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="dop853", **kwargs)


def bs3(field: SecondOrderField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with the Bogacki–Shampine 3(2) pair (3 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="bs3", **kwargs)


@dataclass(frozen=True)
class StepControl:
    """How :func:`runge_kutta` caps, rejects and shrinks steps beyond its error estimate.

    Attributes
    ----------
    max_steps : cap on accepted + rejected steps
    energy_rtol : a step is also rejected when it changes the energy ``e = (V, V)_g`` by
        more than ``energy_rtol · e(0)`` (None: ``10·rtol``; ``inf`` disables it; the
        gradient at the new point comes for free from the last stage, so this costs
        nothing). Without it the ``(∇f·V)²`` part of the energy, which amplifies errors in
        V by ``|∇f|``, can drift far on stiff penalties while the position error is
        controlled.
    project_energy : after each accepted step rescale the velocity to the initial energy,
        ``V ← V·sqrt(e(0)/e)`` (a projection onto the invariant ``(V, V)_g = e(0)``,
        Hairer, Lubich & Wanner, *Geometric Numerical Integration*, IV.4; it keeps the
        order of the method). The acceleration is quadratic in V, so the first stage of
        the next step is rescaled by ``e(0)/e`` at no cost. At loose tolerances this keeps
        the bound ``|f(γ(t)) − f(γ(0))| ≤ √e(0)·t`` that prevents the discrete path from
        running into a degenerate mesh.
    exit_shrink : factor applied to the step size after a step is rejected because a
        stage or its end is not admissible.
    """

    max_steps: int = 100_000
    energy_rtol: float | None = None
    project_energy: bool = False
    exit_shrink: float = 0.25


def runge_kutta(
    field: SecondOrderField,
    Q0: FloatArray,
    V0: FloatArray,
    t_out: FloatArray,
    *,
    rtol: float,
    atol: float,
    pair: str = "dopri5",
    h0: float | None = None,
    dense: bool = True,
    control: StepControl | Mapping | None = None,
    partial: bool = False,
    progress=None,
) -> IntegrationOutput:
    """Integrate (5.35) from ``(Q0, V0)`` at t = 0 with an explicit embedded RK pair.

    The derivative at the accepted point is the first stage of the next step
    (first-same-as-last), so a step costs ``s`` penalty calls (3 for bs3, 6 for dopri5,
    12 for dop853).

    Parameters
    ----------
    field : SecondOrderField
    Q0, V0 : (N, 2) initial position (admissible) and velocity
    t_out : (K,) strictly increasing positive output times
    rtol, atol : local error tolerance per component of ``(Q, V)`` in the max-norm,
        ``|err| ≤ atol + rtol·|y|``
    pair : "dopri5", "dop853" or "bs3"
    h0 : initial step (default: Hairer's heuristic from ``|y|`` and ``|y'|``)
    dense : bool
        True (default): steps are chosen by the error control alone (the last one lands on
        ``t_out[-1]``) and outputs inside a step come from DOP853's own 7th-order
        continuous extension of ``(Q, V)`` (3 more penalty calls in a step holding
        outputs; positions and velocities as accurate as the steps, so the energy at an
        output is too), or, for the other pairs, from the quintic Hermite interpolant of
        ``(Q, Q', Q'')`` at both ends (error O(h⁶) in Q and O(h⁵) in V, no extra call); an
        interpolated configuration that is not admissible makes the step be redone so
        that it lands exactly on that output. False: every output is a step end.
        Many outputs (e.g. the backtracking times ``τ^k`` of a line search) then cost
        nothing extra.
    control : :class:`StepControl` (or a mapping of its fields; None: the defaults):
        the step cap, the energy test and projection, the shrink after an inadmissible
        stage
    partial : bool
        False (default): a failure raises. True: a failure (step size underflow, too many
        steps) ends the integration; the outputs reached so far are returned and
        ``n_reached``/``failure`` say where and why it stopped.
    progress : callable, optional
        ``progress(t / t_end)`` after each accepted step (for a progress bar).

    Returns
    -------
    IntegrationOutput

    Raises
    ------
    IntegrationError
        Step size underflow, too many steps (unless ``partial``), or a non-finite
        right-hand side at the initial mesh.
    """
    c = options_of(StepControl, control, {}, error=TypeError, what="step control setting(s)")
    max_steps, energy_rtol, exit_shrink = c.max_steps, c.energy_rtol, c.exit_shrink
    rk = rk_pair(pair)
    S = len(rk.b)
    t_out = np.asarray(t_out, dtype=float)
    K = len(t_out)
    y = np.empty((2,) + np.shape(Q0))  # the state (Q, V)
    y[0], y[1] = Q0, V0
    a, grad = field.acceleration(y[0], y[1])
    if not (np.isfinite(a).all() and np.isfinite(grad).all()):
        raise IntegrationError("the geodesic right-hand side is not finite at the initial mesh")
    e0 = e_prev = energy(grad, y[1])
    energy_rtol = 10.0 * rtol if energy_rtol is None else energy_rtol
    out_q = np.empty((K,) + y.shape[1:])
    out_v = np.empty((K,) + y.shape[1:])
    out_e = np.empty(K)
    t_end = float(t_out[-1])
    project = bool(c.project_energy) and e0 > 0

    if h0 is None:
        h0 = _initial_step(field, y, a, rk, rtol, atol, t_end)
    h = min(float(h0), t_end)
    h_min = 1e-10 * max(t_end, 1.0)
    k = np.empty((S + 1,) + y.shape)  # stage derivatives (V, A) of the state
    t = 0.0
    k_out = 0
    land = False  # True: the next step must land on t_out[k_out]
    n_steps = n_rej = n_left = 0
    max_drift = 0.0
    failure = ""

    def stop(msg: str) -> None:
        if not partial:
            raise IntegrationError(msg)
        nonlocal failure
        failure = msg

    while k_out < K:
        if n_steps + n_rej >= max_steps:
            stop(f"geodesic needed more than {max_steps} steps before t = {t_end:g} "
                 f"(reached t = {t:.6g}); loosen rtol/atol or raise max_steps")
            break
        target = float(t_out[k_out]) if (land or not dense) else t_end
        hit = t + h >= target * (1 - 1e-14)
        h_step = target - t if hit else h
        k[0, 0], k[0, 1] = y[1], a
        why = ""
        for s in range(1, S + 1):
            ys = y + h_step * _combine(rk.a[s, :s] if s < S else rk.b, k)
            if not field.checks_areas and not field.admissible(ys[0]):
                why = "a triangle inverts"
                break
            k[s, 0] = ys[1]
            try:
                k[s, 1], g_s = field.acceleration(ys[0], ys[1])
            except NotAdmissibleError as exc:  # a triangle inverts, or the boundary touches
                why = str(exc).split(": ", 2)[-1]
                break
            if not np.isfinite(k[s, 1]).all():
                why = "the right-hand side is not finite"
                break
        else:
            y_new, grad_new = ys, g_s
            why = field.boundary_problem(y_new[0]) or ""
        if why:
            n_rej += 1
            n_left += 1
            h = exit_shrink * h_step
            if h < h_min:
                stop(f"geodesic step size underflow at t = {t:.6g}: every step leaves the "
                     f"admissible set ({why}). A penalty without its boundary term (α2 or "
                     "β3 = 0) cannot prevent boundary self-intersections; to put boundary "
                     "vertices at prescribed positions, use `meshopt move` (mt.move)")
                break
            continue
        err = _error_norm(rk, h_step, k, y, y_new, rtol, atol)
        e_new = energy(grad_new, y_new[1])
        if e0 > 0:  # the energy change of one step is a local error as well
            err = max(err, abs(e_new - e_prev) / (energy_rtol * e0))
        if not np.isfinite(err):
            err = np.inf
        factor = 5.0 if err == 0 else min(5.0, max(0.2, 0.9 * err ** -rk.exponent))
        if err > 1.0:
            n_rej += 1
            h = h_step * min(factor, 0.5)
            if h < h_min:
                stop(f"geodesic step size underflow at t = {t:.6g}")
                break
            continue
        t_new = target if hit else t + h_step
        a_new = k[S, 1]
        if project:
            ratio = e0 / e_new
            y_new[1] *= np.sqrt(ratio)
            a_new = a_new * ratio
        # outputs strictly inside the step: interpolate (all at once), and redo the step
        # if one of them is not admissible (then it lands exactly on that output)
        j = k_out
        while j < K and t_out[j] < t_new * (1 - 1e-14):
            j += 1
        if j > k_out:
            interpolated = None
            if rk.dense_d is not None and not project:
                interpolated = _continuous_extension(field, rk, k, y, y_new, h_step,
                                                     (t_out[k_out:j] - t) / h_step)
            if interpolated is None:
                interpolated = _hermite_many(y[0], y[1], a, y_new[0], y_new[1], a_new, t,
                                             t_new, t_out[k_out:j])
            qi, vi = interpolated
            if not field.admissible_many(qi, base=y[0]):
                n_rej += 1
                land = True
                h = h_step
                continue
            out_q[k_out:j], out_v[k_out:j], out_e[k_out:j] = qi, vi, np.nan
            k_out = j
        # accept (first-same-as-last: the last stage is the first stage of the next step)
        n_steps += 1
        t = t_new
        y, a = y_new, a_new.copy()
        if progress is not None:
            progress(t / t_end)
        if e0 > 0:
            max_drift = max(max_drift, abs(e_new - e0) / e0)
        e = e_prev = e0 if project else e_new
        h_next = h_step * factor
        if k_out < K and t_out[k_out] <= t * (1 + 1e-14):
            out_q[k_out], out_v[k_out], out_e[k_out] = y[0], y[1], e
            k_out += 1
        if hit:
            land = False
            h = max(h, h_next)  # a step shortened to land on an output keeps the old size
        else:
            h = h_next
    return IntegrationOutput(out_q[:k_out], out_v[:k_out], out_e[:k_out], n_steps, n_rej,
                             n_left, max_drift, n_reached=k_out, failure=failure, h_last=h,
                             initial_energy=e0)


# --------------------------------------------------------------------------------------
# Störmer–Verlet, thesis algorithm 1
