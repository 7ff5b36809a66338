"""Integrators of second-order systems ``Q'' = A(Q, Q')`` on an open set: explicit
embedded Runge–Kutta pairs with step control, dense output and admissibility guards
(:func:`runge_kutta`: :func:`dop853`, :func:`dopri5`, :func:`bs3`), and the symplectic
Störmer–Verlet scheme (:func:`stormer_verlet`), both behind the declared interface
:class:`SecondOrderField`. The geodesic field of a complete metric
(:class:`~meshopt_toolkit.integrators.GeodesicField`) is the one the library integrates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ._linalg import dot as _dot
from ._typing import FloatArray
from .errors import IntegrationError, NotAdmissibleError


class SecondOrderField(Protocol):
    """What the integrators need from a field ``Q'' = A(Q, Q')`` whose configurations must
    stay in an open admissible set (:class:`~meshopt_toolkit.integrators.GeodesicField`).
    """

    checks_areas: bool

    def gradient(self, Q: FloatArray) -> FloatArray:
        """The gradient of the barrier at ``Q`` (the geodesic field's ``∇f``)."""

    def hvp(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """Hessian of the barrier times ``V`` (Störmer–Verlet's force)."""

    def acceleration(self, Q: FloatArray, V: FloatArray):
        """``(A(Q, V), gradient)``; may raise ``NotAdmissibleError`` outside the set."""

    def admissible(self, Q: FloatArray) -> bool:
        """Every element of ``Q`` admissible (e.g. positive signed areas)."""

    def admissible_many(self, Qs: FloatArray, base: FloatArray | None = None) -> bool:
        """All of ``Qs`` admissible, tested together."""

    def boundary_problem(self, Q: FloatArray) -> str | None:
        """Why ``Q`` is not admissible on its boundary, or None."""

    def energy(self, grad: FloatArray, V: FloatArray) -> float:
        """The conserved quantity ``(V, V)_g`` reported as the energy drift."""


def _combine(w: FloatArray, k: FloatArray) -> FloatArray:
    """``Σ_j w_j k_j`` over the leading (stage) axis of ``k`` (s, ...) (no BLAS, see
    :func:`_dot`); only the first ``len(w)`` stages are used."""
    n = len(w)
    return np.einsum("s,sm->m", w, k[:n].reshape(n, -1)).reshape(k.shape[1:])


@dataclass
class IntegrationOutput:
    """Raw integrator output at the output times (sorted, starting after 0).

    Attributes
    ----------
    points, velocities : (K, N, 2)
    energy : (K,) ``(V, V)_g`` at each output time
    n_steps, n_rejected : accepted and rejected steps (rejected: error or left M+)
    n_left_manifold : rejections because a stage or a step end was not admissible
    max_energy_drift : max over accepted steps of ``|e − e0| / e0`` (before the energy
        projection, when it is used)
    n_reached : outputs computed (``< K`` only after a failure with ``partial=True``)
    failure : why the integration stopped early ("" when it did not)
    h_last : the step size the integrator would have tried next (a good ``h0`` for a
        similar geodesic)
    initial_energy : ``e(0) = (V0, V0)_g``
    """

    points: FloatArray
    velocities: FloatArray
    energy: FloatArray
    n_steps: int
    n_rejected: int
    n_left_manifold: int
    max_energy_drift: float
    n_reached: int = -1
    failure: str = ""
    h_last: float = float("nan")
    initial_energy: float = float("nan")

    def __post_init__(self) -> None:
        if self.n_reached < 0:
            self.n_reached = len(self.points)


# --------------------------------------------------------------------------------------
# Explicit embedded Runge–Kutta pairs
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Pair:
    """An embedded pair: ``s`` stages from ``a``, solution weights ``b``, error weights over
    the ``s`` stages plus the derivative at the new point (index ``s``)."""

    name: str
    a: np.ndarray  # (s, s) strictly lower triangular
    b: np.ndarray  # (s,)
    e5: np.ndarray  # (s + 1,) main error estimate
    e3: np.ndarray | None  # (s + 1,) DOP853's secondary estimate, or None
    exponent: float  # step control exponent 1/(q + 1)


# Dormand–Prince 5(4), Dormand & Prince (1980); Hairer, Nørsett, Wanner I, table II.5.2
_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
_A = [
    np.array([]),
    np.array([1 / 5]),
    np.array([3 / 40, 9 / 40]),
    np.array([44 / 45, -56 / 15, 32 / 9]),
    np.array([19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]),
    np.array([9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]),
    np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]),
]
_B = np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0])
_B_HAT = np.array([5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40])
_E = _B - _B_HAT

#: the tableau (c, a rows, b, b̂) — exposed so the tests can check the order conditions
DOPRI5_TABLEAU = {"c": _C, "a": _A, "b": _B, "b_hat": _B_HAT}


def _dopri5_pair() -> _Pair:
    a = np.zeros((6, 6))
    for i in range(6):
        a[i, :i] = _A[i]
    return _Pair("dopri5", a, _B[:6].copy(), _E.copy(), None, 1 / 5)


def _dop853_pair() -> _Pair:
    """Hairer's DOP853 (8th order, error estimators of orders 5 and 3).

    Its ~200 rational coefficients are taken from scipy's table
    (``scipy.integrate._ivp.dop853_coefficients``) rather than retyped; the stepping, error
    control and admissibility guards are ours.
    """
    try:
        from scipy.integrate._ivp import dop853_coefficients as dc
    except ImportError as exc:  # pragma: no cover - depends on scipy's layout
        raise IntegrationError("method 'dop853' needs scipy's DOP853 coefficient table") from exc
    s = dc.N_STAGES
    return _Pair("dop853", np.array(dc.A[:s, :s]), np.array(dc.B), np.array(dc.E5),
                 np.array(dc.E3), 1 / 8)


#: Bogacki–Shampine 3(2), Bogacki & Shampine (1989): c = (0, 1/2, 3/4), FSAL
BS3_TABLEAU = {
    "c": np.array([0.0, 0.5, 0.75, 1.0]),
    "a": [np.array([]), np.array([0.5]), np.array([0.0, 0.75]), np.array([2 / 9, 1 / 3, 4 / 9])],
    "b": np.array([2 / 9, 1 / 3, 4 / 9, 0.0]),
    "b_hat": np.array([7 / 24, 1 / 4, 1 / 3, 1 / 8]),
}


def _bs3_pair() -> _Pair:
    """Bogacki–Shampine 3(2): 3 calls per step (first-same-as-last), for loose tolerances."""
    t = BS3_TABLEAU
    a = np.zeros((3, 3))
    for i in range(3):
        a[i, :i] = t["a"][i]
    return _Pair("bs3", a, t["b"][:3].copy(), t["b"] - t["b_hat"], None, 1 / 3)


_PAIR_CACHE: dict[str, _Pair] = {}

#: the embedded pairs :func:`runge_kutta` knows
PAIRS = ("dopri5", "dop853", "bs3")


def rk_pair(name: str) -> _Pair:
    """The embedded pair ``"dopri5"``, ``"dop853"`` or ``"bs3"`` (built once)."""
    if name not in _PAIR_CACHE:
        builders = {"dopri5": _dopri5_pair, "dop853": _dop853_pair, "bs3": _bs3_pair}
        if name not in builders:
            raise IntegrationError(f"unknown Runge–Kutta pair {name!r}; choose one of {PAIRS}")
        _PAIR_CACHE[name] = builders[name]()
    return _PAIR_CACHE[name]


def _scaled_max(err, y0, y1, rtol, atol) -> float:
    return float(np.max(np.abs(err) / (atol + rtol * np.maximum(np.abs(y0), np.abs(y1)))))


def _error_norm(pair: _Pair, h, k, y0, y1, rtol, atol) -> float:
    """Scaled max-norm of the local error estimate (DOP853: Hairer's combined 5/3 form).

    ``k`` : (s + 1, 2, N, 2) stage derivatives of the state ``y = (Q, V)``.
    """
    e5 = _scaled_max(h * _combine(pair.e5, k), y0, y1, rtol, atol)
    if pair.e3 is None:
        return e5
    e3 = _scaled_max(h * _combine(pair.e3, k), y0, y1, rtol, atol)
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return e5 * e5 / np.sqrt(e5 * e5 + 0.01 * e3 * e3)


#: quintic Hermite basis (rows: data q0, h v0, h² a0, q1, h v1, h² a1) in powers s⁰…s⁵
_HERMITE = np.array([
    [1, 0, 0, -10, 15, -6],
    [0, 1, 0, -6, 8, -3],
    [0, 0, 0.5, -1.5, 1.5, -0.5],
    [0, 0, 0, 10, -15, 6],
    [0, 0, 0, -4, 7, -3],
    [0, 0, 0, 0.5, -1, 0.5],
], dtype=float).T  # (power, datum)
_HERMITE_D = np.arange(1, 6)[:, None] * _HERMITE[1:]  # s-derivative, powers s⁰…s⁴


def _hermite_basis(s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Quintic Hermite basis at ``s ∈ [0, 1]`` (m,) and its s-derivative, each (m, 6), for
    the data ``q0, h v0, h² a0, q1, h v1, h² a1``."""
    powers = np.asarray(s, dtype=float)[:, None] ** np.arange(6)
    return powers @ _HERMITE, powers[:, :5] @ _HERMITE_D


def _hermite_many(q0, v0, a0, q1, v1, a1, t0: float, t1: float, ts: FloatArray):
    """Quintic Hermite interpolant of a C² path from (Q, Q', Q'') at ``t0`` and ``t1``,
    evaluated at the times ``ts`` (m,) at once: ``(Q, Q')``, each (m, N, 2); the position
    error is O((t1 − t0)⁶)."""
    h = t1 - t0
    b, d = _hermite_basis((np.asarray(ts, dtype=float) - t0) / h)
    terms = np.stack([q0, h * v0, h * h * a0, q1, h * v1, h * h * a1])  # (6, N, 2)
    flat = terms.reshape(6, -1)
    shape = (len(b),) + np.shape(q0)
    q = np.einsum("mk,kn->mn", b, flat).reshape(shape)
    v = np.einsum("mk,kn->mn", d, flat).reshape(shape) / h
    return q, v


def _hermite(q0, v0, a0, q1, v1, a1, t0: float, t1: float, t: float):
    """:func:`_hermite_many` at one time ``t``: ``(Q(t), Q'(t))``, each (N, 2)."""
    q, v = _hermite_many(q0, v0, a0, q1, v1, a1, t0, t1, np.array([t], dtype=float))
    return q[0], v[0]


def _initial_step(field: SecondOrderField, y, a, rk: _Pair, rtol, atol, t_end: float) -> float:
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
    h0 = min(h0, t_end)
    y1 = y + h0 * f0
    try:
        a1, _ = field.acceleration(y1[0], y1[1])
    except NotAdmissibleError:
        return h0
    d2 = float(np.max(np.abs(np.stack([y1[1], a1]) - f0) / sc)) / h0
    if not np.isfinite(d2):
        return h0
    if max(d1, d2) <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** rk.exponent
    return min(100.0 * h0, h1)


def dopri5(field: SecondOrderField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with the Dormand–Prince 5(4) pair (6 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="dopri5", **kwargs)


def dop853(field: SecondOrderField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with Hairer's DOP853 pair (12 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="dop853", **kwargs)


def bs3(field: SecondOrderField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with the Bogacki–Shampine 3(2) pair (3 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="bs3", **kwargs)


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
    max_steps: int = 100_000,
    energy_rtol: float | None = None,
    dense: bool = True,
    project_energy: bool = False,
    exit_shrink: float = 0.25,
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
    max_steps : cap on accepted + rejected steps
    energy_rtol : a step is also rejected when it changes the energy ``e = (V, V)_g`` by
        more than ``energy_rtol · e(0)`` (default ``10·rtol``; ``inf`` disables it; the
        gradient at the new point comes for free from the last stage, so this costs
        nothing). Without it the ``(∇f·V)²`` part of the energy, which amplifies errors in
        V by ``|∇f|``, can drift far on stiff penalties while the position error is
        controlled.
    dense : bool
        True (default): steps are chosen by the error control alone (the last one lands on
        ``t_out[-1]``) and outputs inside a step come from the quintic Hermite interpolant
        of ``(Q, Q', Q'')`` at both ends (error O(h⁶), no extra penalty call); an
        interpolated configuration that is not admissible makes the step be redone so
        that it lands exactly on that output. False: every output is a step end.
        Many outputs (e.g. the backtracking times ``τ^k`` of a line search) then cost
        nothing extra.
    project_energy : bool
        After each accepted step rescale the velocity to the initial energy,
        ``V ← V·sqrt(e(0)/e)`` (a projection onto the invariant ``(V, V)_g = e(0)``, Hairer,
        Lubich & Wanner, *Geometric Numerical Integration*, IV.4; it keeps the order of
        the method). The acceleration is quadratic in V, so the first stage of the next
        step is rescaled by ``e(0)/e`` at no cost. At loose tolerances this keeps the
        bound ``|f(γ(t)) − f(γ(0))| ≤ √e(0)·t`` that prevents the discrete path from
        running into a degenerate mesh.
    exit_shrink : factor applied to the step size after a step is rejected because a
        stage or its end is not admissible.
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
    rk = rk_pair(pair)
    S = len(rk.b)
    t_out = np.asarray(t_out, dtype=float)
    K = len(t_out)
    y = np.empty((2,) + np.shape(Q0))  # the state (Q, V)
    y[0], y[1] = Q0, V0
    a, grad = field.acceleration(y[0], y[1])
    if not (np.isfinite(a).all() and np.isfinite(grad).all()):
        raise IntegrationError("the geodesic right-hand side is not finite at the initial mesh")
    e0 = e_prev = field.energy(grad, y[1])
    energy_rtol = 10.0 * rtol if energy_rtol is None else energy_rtol
    out_q = np.empty((K,) + y.shape[1:])
    out_v = np.empty((K,) + y.shape[1:])
    out_e = np.empty(K)
    t_end = float(t_out[-1])
    project = bool(project_energy) and e0 > 0

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
        e_new = field.energy(grad_new, y_new[1])
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
            qi, vi = _hermite_many(y[0], y[1], a, y_new[0], y_new[1], a_new, t, t_new,
                                   t_out[k_out:j])
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
# --------------------------------------------------------------------------------------
def _velocity(grad: FloatArray, P: FloatArray) -> FloatArray:
    """``V = g⁻¹ P = P − ∇f (∇f·P)/(1 + |∇f|²)`` (Sherman–Morrison, (5.45))."""
    return P - grad * (_dot(grad, P) / (1.0 + _dot(grad, grad)))


def _momentum(grad: FloatArray, V: FloatArray) -> FloatArray:
    """``P = g V = V + ∇f (∇f·V)``."""
    return V + grad * _dot(grad, V)


def _force(field: SecondOrderField, Q, grad, P) -> FloatArray:
    """``P' = −∂H/∂Q = (∇f·V) ∇²f V`` with ``V = V(Q, P)``, (5.40a)."""
    V = _velocity(grad, P)
    return _dot(grad, V) * field.hvp(Q, V)


def _converged(new, old, tol) -> bool:
    return float(np.max(np.abs(new - old))) <= tol * (1.0 + float(np.max(np.abs(new))))


def stormer_verlet(
    field: SecondOrderField,
    Q0: FloatArray,
    V0: FloatArray,
    t_out: FloatArray,
    *,
    steps: int,
    tol: float = 1e-8,
    max_iter: int = 10,
) -> IntegrationOutput:
    """The thesis' Störmer–Verlet scheme (algorithm 1) for (5.40).

    One step of size Δt (P = momentum, F(Q, P) = (∇f·V)∇²f V, V = V(Q, P)):

    1. ``P½ = P_n + (Δt/2) F(Q_n, P½)``                 (implicit, fixed point from P_n)
    2. ``Q_{n+1} = Q_n + (Δt/2)(V(Q_n, P½) + V(Q_{n+1}, P½))``  (implicit, from Q_n)
    3. ``P_{n+1} = P½ + (Δt/2) F(Q_{n+1}, P½)``          (explicit)

    Fixed points stop when ``max|x_{k+1} − x_k| ≤ tol·(1 + max|x_{k+1}|)``.

    Parameters
    ----------
    field : SecondOrderField
    Q0, V0 : (N, 2)
    t_out : (K,) strictly increasing positive output times; ``steps`` uniform steps are
        spread over ``[0, t_out[-1]]``, each interval between outputs getting
        ``max(1, round(steps · length / t_end))`` of them (exactly Δt = t_end/steps when
        the outputs lie on that grid)
    steps : number of steps on ``[0, t_out[-1]]`` (the thesis used 1024)
    tol, max_iter : fixed-point tolerance and iteration cap (thesis: 1e-8, 10)

    Raises
    ------
    IntegrationError
        A fixed point does not converge or an iterate leaves M+ ("use more steps").
    """
    if steps < 1:
        raise IntegrationError(f"steps must be a positive integer, got {steps}")
    t_out = np.asarray(t_out, dtype=float)
    t_end = float(t_out[-1])
    K = len(t_out)
    q = np.array(Q0, dtype=float)
    grad = field.gradient(q)
    p = _momentum(grad, np.asarray(V0, dtype=float))
    e0 = _dot(p, _velocity(grad, p))
    out_q = np.empty((K,) + q.shape)
    out_v = np.empty((K,) + q.shape)
    out_e = np.empty(K)
    max_drift = 0.0
    n_steps = 0
    t_prev = 0.0

    def fail(what: str, t: float) -> IntegrationError:
        return IntegrationError(
            f"Störmer–Verlet: {what} at t = {t:.6g} (step {n_steps}); use more steps"
        )

    for k, t_next in enumerate(t_out):
        n_sub = max(1, round(steps * (t_next - t_prev) / t_end))
        dt = (t_next - t_prev) / n_sub
        for j in range(n_sub):
            t_here = t_prev + j * dt
            # 1. implicit momentum half-step at Q_n (∇f(Q_n) is fixed during the iteration)
            p_half = p
            for _ in range(max_iter):
                with np.errstate(over="ignore", invalid="ignore"):
                    new = p + 0.5 * dt * _force(field, q, grad, p_half)
                if not np.isfinite(new).all():
                    raise fail("the momentum fixed point diverged", t_here)
                done = _converged(new, p_half, tol)
                p_half = new
                if done:
                    break
            else:
                raise fail("the momentum fixed point did not converge", t_here)
            # 2. implicit position step
            v_n = _velocity(grad, p_half)
            q_new, grad_new = q, grad
            for _ in range(max_iter):
                with np.errstate(over="ignore", invalid="ignore"):
                    cand = q + 0.5 * dt * (v_n + _velocity(grad_new, p_half))
                if not field.admissible(cand):
                    raise fail("the position iterate left the admissible set", t_here)
                done = _converged(cand, q_new, tol)
                q_new = cand
                grad_new = field.gradient(q_new)
                if done:
                    break
            else:
                raise fail("the position fixed point did not converge", t_here)
            # 3. explicit momentum half-step at Q_{n+1}
            with np.errstate(over="ignore", invalid="ignore"):
                p = p_half + 0.5 * dt * _force(field, q_new, grad_new, p_half)
            if not np.isfinite(p).all():
                raise fail("the momentum became non-finite", t_here)
            q, grad = q_new, grad_new
            n_steps += 1
            if e0 > 0:
                e = _dot(p, _velocity(grad, p))
                max_drift = max(max_drift, abs(e - e0) / e0)
        v = _velocity(grad, p)
        out_q[k], out_v[k], out_e[k] = q, v, field.energy(grad, v)
        t_prev = float(t_next)
    return IntegrationOutput(out_q, out_v, out_e, n_steps, 0, 0, max_drift)
