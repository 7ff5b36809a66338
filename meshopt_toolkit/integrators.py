"""Integrators for the geodesic equation of a complete metric ``g = I + ∇f ∇fᵀ`` (SPEC §5).

Two integrators work on a :class:`GeodesicField`, the closed-form right-hand side

    Q'' = − ∇f(Q) · (Q'ᵀ ∇²f(Q) Q') / (1 + |∇f(Q)|²)                       (5.35)

which costs one call of ``penalty.gradient_and_curvature(Q, V)`` per evaluation (no linear
solve: the inverse metric is a Sherman–Morrison rank-one update, (5.45)).

- :func:`dopri5`: the fast default. An explicit, adaptive, error-controlled Dormand–Prince
  5(4) pair (first-same-as-last, 6 evaluations per accepted step) on the first-order system
  ``(Q, V)' = (V, A(Q, V))``. Steps land exactly on every requested output time, so outputs
  carry no interpolation error. A step whose stage leaves M+ (a signed area ≤ 0) is rejected
  and retried with a quarter of the step size.
- :func:`stormer_verlet`: the thesis' algorithm 1 in Hamiltonian form (5.39–5.40), momentum
  ``P = g V``, ``V(Q, P) = P − ∇f (∇f·P)/(1+|∇f|²)``, ``P' = (∇f·V) ∇²f V``, with the two
  implicit half-steps solved by fixed-point iteration (tolerance 1e-8, at most 10
  iterations). It is second-order, symplectic, and slow: the reference.

Both return arrays over the output times and never return a configuration with a
non-positive signed area: they raise :class:`~meshopt_toolkit.errors.IntegrationError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._typing import FloatArray, IntArray
from .errors import IntegrationError, NotAdmissibleError
from .geometry import signed_areas

__all__ = [
    "BS3_TABLEAU",
    "DOPRI5_TABLEAU",
    "GeodesicField",
    "IntegrationOutput",
    "PAIRS",
    "bs3",
    "dop853",
    "dopri5",
    "rk_pair",
    "runge_kutta",
    "stormer_verlet",
]


class GeodesicField:
    """The geodesic right-hand side of the complete metric built from ``penalty``.

    Parameters
    ----------
    penalty : object
        Provides ``gradient_and_curvature(Q, V) -> ((N, 2), float)``, ``gradient(Q)``,
        ``hvp(Q, V)`` and ``value(Q)`` (the penalty protocol of
        :mod:`meshopt_toolkit.penalties`).
    triangles : (T, 3) int array, optional
        Connectivity used to test ``min signed area > 0``. Without it the penalty's
        ``is_admissible(Q)`` is used.

    Notes
    -----
    Admissibility (SPEC §1: positive signed areas and a boundary that does not touch
    itself) is checked in two places:

    - every right-hand-side evaluation needs positive areas (:meth:`admissible`; a
      :class:`~meshopt_toolkit.penalties.Penalty` checks them itself in the same pass and
      raises :class:`~meshopt_toolkit.errors.NotAdmissibleError`, so the integrator does
      not repeat the test, see :attr:`checks_areas`);
    - the boundary is checked exactly at every accepted step end and every returned
      output (:meth:`boundary_problem`), not at the intermediate stages, whose positions
      are auxiliary. With a ``Penalty`` the exact test is skipped when a cheap
      certificate proves it: at each exactly checked configuration (the *anchor*) the
      smallest Euclidean distance ``δ`` between a boundary vertex and a boundary edge not
      incident to it is computed; a configuration whose boundary vertices all lie within
      ``δ/2`` of the anchor's cannot have a touching or crossing boundary (along the
      straight path from the anchor every such distance shrinks by less than ``δ``, and
      two boundary segments can only start to meet where a vertex touches a segment).
      For other penalties the penalty's own evaluation (which may check the boundary) and
      ``is_admissible`` are used.

    Attributes
    ----------
    n_evaluations : int
        Number of penalty calls (gradient, curvature, hvp or value) made so far.
    n_boundary_checks : int
        Exact boundary tests made (certified configurations excluded).
    checks_areas : bool
        True when :meth:`acceleration` itself raises ``NotAdmissibleError`` at a
        non-positive signed area (the penalty is a ``Penalty``).
    """

    #: certificates are computed when the boundary has at most this many (vertex, edge)
    #: pairs (beyond, every check is exact: the per-call penalty cost dominates there)
    CERTIFICATE_PAIRS = 60_000

    def __init__(self, penalty, triangles: IntArray | None = None) -> None:
        from .penalties import Penalty

        self.penalty = penalty
        self.triangles = None if triangles is None else np.asarray(triangles)
        self.n_evaluations = 0
        self.n_boundary_checks = 0
        self.checks_areas = isinstance(penalty, Penalty)
        self._pairs = None
        self._bv = None
        self._anchor = None
        self._radius = 0.0
        if self.checks_areas:
            bv = penalty.boundary_vertices
            be = penalty.boundary_edges
            if len(bv) * len(be) <= self.CERTIFICATE_PAIRS:
                from .distance import boundary_pairs

                self._bv = bv
                self._pairs = boundary_pairs(bv, be)

    def admissible(self, Q: FloatArray) -> bool:
        """True if every triangle of ``Q`` has positive signed area (and ``Q`` is finite)."""
        if not np.isfinite(Q).all():
            return False
        if self.triangles is not None:
            return bool(signed_areas(Q, self.triangles).min() > 0.0)
        return bool(self.penalty.is_admissible(Q))

    def boundary_problem(self, Q: FloatArray) -> str | None:
        """None if the boundary of ``Q`` does not touch itself, else a description.

        Exact (see the class notes for the certificate that often makes it free); for a
        penalty that is not a ``Penalty`` this is ``penalty.is_admissible`` when it has one
        (else None: its evaluations are trusted to raise).
        """
        if not self.checks_areas:
            check = getattr(self.penalty, "is_admissible", None)
            if check is None or check(Q):
                return None
            return "the boundary self-intersects"
        if self._anchor is not None:
            move = Q[self._bv] - self._anchor
            if float(np.einsum("ij,ij->i", move, move).max()) < self._radius * self._radius:
                return None
        self.n_boundary_checks += 1
        problem = self.penalty.boundary_problem(Q)
        if problem is None and self._pairs is not None and len(self._pairs):
            from .distance import segment_distance

            delta = float(segment_distance(Q, self._pairs).min())
            if delta > 0:
                self._anchor = Q[self._bv].copy()
                self._radius = 0.5 * delta
        return problem

    def acceleration(self, Q: FloatArray, V: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Geodesic acceleration ``A = −∇f (Vᵀ∇²f V)/(1 + |∇f|²)``, (5.35).

        With a ``Penalty`` the boundary is not tested here (see the class notes).

        Returns
        -------
        A : (N, 2) acceleration
        grad : (N, 2) ∇f(Q), returned for the energy monitor
        """
        self.n_evaluations += 1
        if self.checks_areas:
            grad, curv = self.penalty.gradient_and_curvature(Q, V, check_boundary=False)
        else:
            grad, curv = self.penalty.gradient_and_curvature(Q, V)
        grad = np.asarray(grad, dtype=float)
        return (-float(curv) / (1.0 + _dot(grad, grad))) * grad, grad

    def gradient(self, Q: FloatArray) -> FloatArray:
        """∇f(Q), (N, 2)."""
        self.n_evaluations += 1
        return np.asarray(self.penalty.gradient(Q), dtype=float)

    def hvp(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """∇²f(Q) V, (N, 2)."""
        self.n_evaluations += 1
        return np.asarray(self.penalty.hvp(Q, V), dtype=float)

    def value(self, Q: FloatArray) -> float:
        """f(Q)."""
        self.n_evaluations += 1
        return float(self.penalty.value(Q))

    def value_and_gradient(self, Q: FloatArray) -> tuple[float, FloatArray]:
        """``(f(Q), ∇f(Q))`` in one penalty call when the penalty offers it."""
        self.n_evaluations += 1
        both = getattr(self.penalty, "value_and_gradient", None)
        if both is None:
            self.n_evaluations += 1
            return float(self.penalty.value(Q)), np.asarray(self.penalty.gradient(Q), float)
        f, g = both(Q)
        return float(f), np.asarray(g, dtype=float)


def _dot(a: FloatArray, b: FloatArray) -> float:
    """Euclidean inner product of two (N, 2) arrays.

    ``np.einsum`` rather than ``np.vdot``/BLAS: on small arrays and busy machines a
    threaded BLAS call costs milliseconds (measured: 17 ms per call at N ≈ 8600 with the
    CPU oversubscribed), far more than the arithmetic.
    """
    return float(np.einsum("ij,ij->", a, b))


def _combine(w: FloatArray, k: FloatArray) -> FloatArray:
    """``Σ_j w_j k_j`` over stages ``k`` of shape (s, N, 2) (no BLAS, see :func:`_dot`)."""
    return np.einsum("s,sij->ij", w, k)


def energy(grad: FloatArray, V: FloatArray) -> float:
    """Squared speed ``e = |V|² + (∇f·V)² = (V, V)_g``, constant along a geodesic."""
    s = _dot(grad, V)
    return _dot(V, V) + s * s


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


def _error_norm(pair: _Pair, h, kq, kv, q0, v0, q1, v1, rtol, atol) -> float:
    """Scaled max-norm of the local error estimate (DOP853: Hairer's combined 5/3 form)."""
    e5 = max(_scaled_max(h * _combine(pair.e5, kq), q0, q1, rtol, atol),
             _scaled_max(h * _combine(pair.e5, kv), v0, v1, rtol, atol))
    if pair.e3 is None:
        return e5
    e3 = max(_scaled_max(h * _combine(pair.e3, kq), q0, q1, rtol, atol),
             _scaled_max(h * _combine(pair.e3, kv), v0, v1, rtol, atol))
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return e5 * e5 / np.sqrt(e5 * e5 + 0.01 * e3 * e3)


def _hermite(q0, v0, a0, q1, v1, a1, t0: float, t1: float, t: float):
    """Quintic Hermite interpolant of a C² path from (Q, Q', Q'') at ``t0`` and ``t1``.

    Returns ``(Q(t), Q'(t))``, each (N, 2); the position error is O((t1 − t0)⁶).
    """
    h = t1 - t0
    s = (t - t0) / h
    s2, s3 = s * s, s * s * s
    s4, s5 = s3 * s, s3 * s2
    # basis of q0, h v0, h² a0, q1, h v1, h² a1 and their s-derivatives
    b = (1 - 10 * s3 + 15 * s4 - 6 * s5, s - 6 * s3 + 8 * s4 - 3 * s5,
         0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5, 10 * s3 - 15 * s4 + 6 * s5,
         -4 * s3 + 7 * s4 - 3 * s5, 0.5 * s3 - s4 + 0.5 * s5)
    d = (-30 * s2 + 60 * s3 - 30 * s4, 1 - 18 * s2 + 32 * s3 - 15 * s4,
         s - 4.5 * s2 + 6 * s3 - 2.5 * s4, 30 * s2 - 60 * s3 + 30 * s4,
         -12 * s2 + 28 * s3 - 15 * s4, 1.5 * s2 - 4 * s3 + 2.5 * s4)
    terms = (q0, h * v0, h * h * a0, q1, h * v1, h * h * a1)
    q = sum(c * x for c, x in zip(b, terms))
    v = sum(c * x for c, x in zip(d, terms)) / h
    return q, v


def dopri5(field: GeodesicField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with the Dormand–Prince 5(4) pair (6 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="dopri5", **kwargs)


def dop853(field: GeodesicField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with Hairer's DOP853 pair (12 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="dop853", **kwargs)


def bs3(field: GeodesicField, Q0, V0, t_out, **kwargs) -> IntegrationOutput:
    """:func:`runge_kutta` with the Bogacki–Shampine 3(2) pair (3 calls per step)."""
    return runge_kutta(field, Q0, V0, t_out, pair="bs3", **kwargs)


def runge_kutta(
    field: GeodesicField,
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
) -> IntegrationOutput:
    """Integrate (5.35) from ``(Q0, V0)`` at t = 0 with an explicit embedded RK pair.

    The derivative at the accepted point is the first stage of the next step
    (first-same-as-last), so a step costs ``s`` penalty calls (3 for bs3, 6 for dopri5,
    12 for dop853).

    Parameters
    ----------
    field : GeodesicField
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
    q = np.array(Q0, dtype=float)
    v = np.array(V0, dtype=float)
    a, grad = field.acceleration(q, v)
    if not (np.isfinite(a).all() and np.isfinite(grad).all()):
        raise IntegrationError("the geodesic right-hand side is not finite at the initial mesh")
    e0 = e_prev = energy(grad, v)
    energy_rtol = 10.0 * rtol if energy_rtol is None else energy_rtol
    out_q = np.empty((K,) + q.shape)
    out_v = np.empty((K,) + q.shape)
    out_e = np.empty(K)
    t_end = float(t_out[-1])
    project = bool(project_energy) and e0 > 0

    if h0 is None:
        # Hairer, Nørsett, Wanner I, II.4: h such that h·|y'| ≈ 1% of |y|
        d0 = max(np.max(np.abs(q)), np.max(np.abs(v)))
        d1 = max(np.max(np.abs(v)), np.max(np.abs(a)))
        h0 = 0.01 * d0 / d1 if d1 > 0 and d0 > 0 else 1e-3
    h = min(float(h0), t_end)
    h_min = 1e-10 * max(t_end, 1.0)
    kq = np.empty((S + 1,) + q.shape)  # stage velocities (derivative of Q)
    kv = np.empty((S + 1,) + q.shape)  # stage accelerations (derivative of V)
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
        kq[0], kv[0] = v, a
        why = ""
        for s in range(1, S + 1):
            w = rk.a[s, :s] if s < S else rk.b
            qs = q + h_step * _combine(w, kq[:s])
            vs = v + h_step * _combine(w, kv[:s])
            if not field.checks_areas and not field.admissible(qs):
                why = "a triangle inverts"
                break
            kq[s] = vs
            try:
                kv[s], g_s = field.acceleration(qs, vs)
            except NotAdmissibleError as exc:  # a triangle inverts, or the boundary touches
                why = str(exc).split(": ", 2)[-1]
                break
            if not np.isfinite(kv[s]).all():
                why = "the right-hand side is not finite"
                break
        else:
            q_new, v_new, grad_new = qs, vs, g_s
            why = field.boundary_problem(q_new) or ""
        if why:
            n_rej += 1
            n_left += 1
            h = exit_shrink * h_step
            if h < h_min:
                stop(f"geodesic step size underflow at t = {t:.6g}: every step leaves the "
                     f"admissible set ({why}). A penalty without its boundary term (α2 or "
                     "β3 = 0) cannot prevent boundary self-intersections")
                break
            continue
        err = _error_norm(rk, h_step, kq, kv, q, v, q_new, v_new, rtol, atol)
        e_new = energy(grad_new, v_new)
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
        a_new = kv[S]
        if project:
            ratio = e0 / e_new
            v_new = v_new * np.sqrt(ratio)
            a_new = a_new * ratio
        # outputs strictly inside the step: interpolate, and redo the step if one of them
        # is not admissible (then it lands exactly on that output)
        inner = []
        j = k_out
        while j < K and t_out[j] < t_new * (1 - 1e-14):
            inner.append(_hermite(q, v, a, q_new, v_new, a_new, t, t_new, float(t_out[j])))
            j += 1
        if any(not field.admissible(qi) or field.boundary_problem(qi) for qi, _ in inner):
            n_rej += 1
            land = True
            h = h_step
            continue
        # accept (first-same-as-last: the last stage is the first stage of the next step)
        n_steps += 1
        for qi, vi in inner:
            out_q[k_out], out_v[k_out], out_e[k_out] = qi, vi, np.nan
            k_out += 1
        t = t_new
        q, v, a = q_new, v_new, a_new.copy()
        if e0 > 0:
            max_drift = max(max_drift, abs(e_new - e0) / e0)
        e = e_prev = e0 if project else e_new
        h_next = h_step * factor
        if k_out < K and t_out[k_out] <= t * (1 + 1e-14):
            out_q[k_out], out_v[k_out], out_e[k_out] = q, v, e
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


def _force(field: GeodesicField, Q, grad, P) -> FloatArray:
    """``P' = −∂H/∂Q = (∇f·V) ∇²f V`` with ``V = V(Q, P)``, (5.40a)."""
    V = _velocity(grad, P)
    return _dot(grad, V) * field.hvp(Q, V)


def _converged(new, old, tol) -> bool:
    return float(np.max(np.abs(new - old))) <= tol * (1.0 + float(np.max(np.abs(new))))


def stormer_verlet(
    field: GeodesicField,
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
    field : GeodesicField
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
        out_q[k], out_v[k], out_e[k] = q, v, energy(grad, v)
        t_prev = float(t_next)
    return IntegrationOutput(out_q, out_v, out_e, n_steps, 0, 0, max_drift)
