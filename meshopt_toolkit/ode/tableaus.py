"""The embedded Runge–Kutta pairs (Dormand–Prince 5(4) and 8(5,3), Bogacki–Shampine
3(2)), their error norms, and the quintic Hermite dense output."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._options import check_choice
from .._typing import FloatArray
from ..errors import IntegrationError
from .base import _combine


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
    #: DOP853's continuous extension: rows of the 3 extra stages' a (3, s + 4), their c
    #: (3,), and the interpolation weights d (4, s + 4) over all s + 4 stages; None: the
    #: pair has none (outputs inside a step use the quintic Hermite interpolant)
    dense_a: np.ndarray | None = None
    dense_c: np.ndarray | None = None
    dense_d: np.ndarray | None = None


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
                 np.array(dc.E3), 1 / 8, dense_a=np.array(dc.A[s + 1:]),
                 dense_c=np.array(dc.C[s + 1:]), dense_d=np.array(dc.D))


def dense_polynomial(pair: _Pair, k: FloatArray, y0: FloatArray, y1: FloatArray, h: float):
    """The coefficients ``F`` (7, ...) of DOP853's 7th-order continuous extension
    (Hairer, Nørsett & Wanner I, §II.6; the form of scipy's ``Dop853DenseOutput``):
    ``y(t0 + θh) = y0 + θ(F0 + (1−θ)(F1 + θ(F2 + (1−θ)(F3 + θ(F4 + (1−θ)(F5 + θF6))))))``.

    ``k`` : (s + 4, ...) all stage derivatives — the ``s`` of the step, the derivative at
    ``y1`` and the 3 extra stages.
    """
    dy = y1 - y0
    F = np.empty((7,) + dy.shape)
    F[0] = dy
    F[1] = h * k[0] - dy
    F[2] = 2 * dy - h * (k[len(pair.b)] + k[0])
    for i, w in enumerate(pair.dense_d):
        F[3 + i] = h * _combine(w, k)
    return F


def dense_evaluate(F: FloatArray, y0: FloatArray, theta: FloatArray) -> FloatArray:
    """:func:`dense_polynomial`'s interpolant at the step fractions ``theta`` (m,): (m, ...)."""
    x = np.asarray(theta, dtype=float).reshape((-1,) + (1,) * y0.ndim)
    y = np.zeros((len(x),) + y0.shape)
    for i, f in enumerate(F[::-1]):
        y += f
        y *= x if i % 2 == 0 else 1 - x
    return y + y0


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
        check_choice(name, PAIRS, "Runge–Kutta pair", error=IntegrationError)
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
