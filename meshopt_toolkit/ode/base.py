"""Integrators for the geodesic equation of a complete metric ``g = I + ∇f ∇fᵀ`` (SPEC §5).

The integrators work on any :class:`SecondOrderField` (a declared Protocol: the
acceleration ``A(Q, V)`` with ``∇f(Q)``, and the admissibility tests);
:class:`meshopt_toolkit.riemannian.field.GeodesicField` is the one the library uses, the
closed-form right-hand side (5.35) of the complete metric ``g = I + ∇f ∇fᵀ``. The energy
monitor (:func:`energy`) and Störmer–Verlet's Hamiltonian form assume that metric.

- :func:`runge_kutta` (:func:`dop853`, :func:`dopri5`, :func:`bs3`): explicit, adaptive,
  error-controlled embedded pairs (first-same-as-last) on the first-order system
  ``(Q, V)' = (V, A(Q, V))``, with dense output for many output times (DOP853's own
  7th-order continuous extension, quintic Hermite for the other pairs),
  optional energy projection (line searches), and admissibility guards: a step with a
  stage outside M+ (a signed area ≤ 0) or a step end whose boundary touches itself is
  rejected and retried smaller; outputs are checked too (``field.boundary_problem``).
- :func:`stormer_verlet`: the thesis' algorithm 1 in Hamiltonian form (5.39–5.40), momentum
  ``P = g V``, ``V(Q, P) = P − ∇f (∇f·P)/(1+|∇f|²)``, ``P' = (∇f·V) ∇²f V``, with the two
  implicit half-steps solved by fixed-point iteration (tolerance 1e-8, at most 10
  iterations). It is second-order, symplectic, and slow: the reference.

Both return arrays over the output times and never return a configuration with a
non-positive signed area: they raise :class:`~meshopt_toolkit.errors.IntegrationError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .._linalg import dot as _dot
from .._typing import FloatArray

__all__ = ["IntegrationOutput", "SecondOrderField", "energy"]


class SecondOrderField(Protocol):
    """What the integrators need of ``Q'' = A(Q, Q')`` on node positions ``(N, 2)``.

    ``gradient`` is the ``∇f`` of the complete metric ``g = I + ∇f ∇fᵀ``, used by the
    energy monitor and by :func:`stormer_verlet`'s momentum.
    """

    #: True when :meth:`acceleration` itself raises ``NotAdmissibleError`` at a
    #: non-positive signed area (the integrator then skips its own area test)
    checks_areas: bool

    def acceleration(self, Q: FloatArray, V: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(A(Q, V), ∇f(Q))``, each ``(N, 2)``."""
        ...

    def gradient(self, Q: FloatArray) -> FloatArray: ...

    def hvp(self, Q: FloatArray, V: FloatArray) -> FloatArray: ...

    def admissible(self, Q: FloatArray) -> bool: ...

    def admissible_many(self, Qs: FloatArray, base: FloatArray | None = None) -> bool: ...

    def boundary_problem(self, Q: FloatArray) -> str | None: ...


def _combine(w: FloatArray, k: FloatArray) -> FloatArray:
    """``Σ_j w_j k_j`` over the leading (stage) axis of ``k`` (s, ...) (no BLAS, see
    :func:`_dot`); only the first ``len(w)`` stages are used."""
    n = len(w)
    return np.einsum("s,sm->m", w, k[:n].reshape(n, -1)).reshape(k.shape[1:])


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
