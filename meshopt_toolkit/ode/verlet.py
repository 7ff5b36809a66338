"""Störmer–Verlet for the geodesic equation in Hamiltonian form (see the package
docstring)."""

from __future__ import annotations


import numpy as np

from .._linalg import dot as _dot
from .._typing import FloatArray
from ..errors import IntegrationError
from .base import IntegrationOutput, SecondOrderField, energy


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
    tolerance: float = 1e-8,
    max_iterations: int = 10,
) -> IntegrationOutput:
    """The thesis' Störmer–Verlet scheme (algorithm 1) for (5.40).

    One step of size Δt (P = momentum, F(Q, P) = (∇f·V)∇²f V, V = V(Q, P)):

    1. ``P½ = P_n + (Δt/2) F(Q_n, P½)``                 (implicit, fixed point from P_n)
    2. ``Q_{n+1} = Q_n + (Δt/2)(V(Q_n, P½) + V(Q_{n+1}, P½))``  (implicit, from Q_n)
    3. ``P_{n+1} = P½ + (Δt/2) F(Q_{n+1}, P½)``          (explicit)

    Fixed points stop when ``max|x_{k+1} − x_k| ≤ tolerance·(1 + max|x_{k+1}|)``.

    Parameters
    ----------
    field : SecondOrderField
    Q0, V0 : (N, 2)
    t_out : (K,) strictly increasing positive output times; ``steps`` uniform steps are
        spread over ``[0, t_out[-1]]``, each interval between outputs getting
        ``max(1, round(steps · length / t_end))`` of them (exactly Δt = t_end/steps when
        the outputs lie on that grid)
    steps : number of steps on ``[0, t_out[-1]]`` (the thesis used 1024)
    tolerance, max_iterations : fixed-point tolerance and iteration cap (thesis: 1e-8, 10)

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

    def kick(p0, q, grad, p_half, dt: float, t: float, what: str) -> FloatArray:
        """The momentum half-step ``p0 + dt/2 · F(q, p_half)``; non-finite is ``what``."""
        with np.errstate(over="ignore", invalid="ignore"):
            new = p0 + 0.5 * dt * _force(field, q, grad, p_half)
        if not np.isfinite(new).all():
            raise fail(what, t)
        return new

    for k, t_next in enumerate(t_out):
        n_sub = max(1, round(steps * (t_next - t_prev) / t_end))
        dt = (t_next - t_prev) / n_sub
        for j in range(n_sub):
            t_here = t_prev + j * dt
            # 1. implicit momentum half-step at Q_n (∇f(Q_n) is fixed during the iteration)
            p_half = p
            for _ in range(max_iterations):
                new = kick(p, q, grad, p_half, dt, t_here, "the momentum fixed point diverged")
                done = _converged(new, p_half, tolerance)
                p_half = new
                if done:
                    break
            else:
                raise fail("the momentum fixed point did not converge", t_here)
            # 2. implicit position step
            v_n = _velocity(grad, p_half)
            q_new, grad_new = q, grad
            for _ in range(max_iterations):
                with np.errstate(over="ignore", invalid="ignore"):
                    cand = q + 0.5 * dt * (v_n + _velocity(grad_new, p_half))
                if not field.admissible(cand):
                    raise fail("the position iterate left the admissible set", t_here)
                done = _converged(cand, q_new, tolerance)
                q_new = cand
                grad_new = field.gradient(q_new)
                if done:
                    break
            else:
                raise fail("the position fixed point did not converge", t_here)
            # 3. explicit momentum half-step at Q_{n+1}
            p = kick(p_half, q_new, grad_new, p_half, dt, t_here, "the momentum became non-finite")
            q, grad = q_new, grad_new
            n_steps += 1
            if e0 > 0:
                e = _dot(p, _velocity(grad, p))
                max_drift = max(max_drift, abs(e - e0) / e0)
        v = _velocity(grad, p)
        out_q[k], out_v[k], out_e[k] = q, v, energy(grad, v)
        t_prev = float(t_next)
    return IntegrationOutput(out_q, out_v, out_e, n_steps, 0, 0, max_drift)
