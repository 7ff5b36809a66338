"""The one-configuration cache the shape objectives of ``fem/`` share.

An objective solves its state once per configuration ``Q`` and keeps it until a
different ``Q`` comes: :class:`CachedObjective` holds that cache and ``value``;
:class:`CachedPoisson` adds the Poisson state ``y`` and its adjoint ``p`` (solved on
demand, with the state's solver); :func:`poisson_value` is the Poisson objectives' ``j``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .._typing import FloatArray
from .simplex import Geometry, same_configuration


@dataclass
class SimplexState:
    """What the cached state of an objective on simplices starts with: the positions
    ``Q`` it was computed at and their :class:`~.simplex.Geometry`."""

    Q: FloatArray
    geo: Geometry


def poisson_value(m: FloatArray, y: FloatArray, target: FloatArray | None) -> float:
    """``j = mᵀy`` (``target`` None) or the tracking ``½ Σ_a m_a (y_a − y_d,a)²`` of the
    nodal target ``y_d``, with the lumped mass weights ``m``."""
    if target is None:
        return float(m @ y)
    return float(m @ tracking_terms(m, y, target)[0])


def tracking_terms(m: FloatArray, y: FloatArray,
                   target: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The tracking objective's two nodal pieces of ``dj/dQ``: the mass-derivative weights
    ``½ (y − y_d)²`` and the factor ``m (y − y_d)`` of ``−∇y_d`` (also ``∂j/∂y``)."""
    misfit = y - target
    return 0.5 * misfit * misfit, m * misfit


class CachedObjective:
    """An objective whose ``_compute(Q)`` returns a state with the positions ``.Q`` it
    was computed at and the objective's ``.value``; the last one is kept."""

    _cache: Any = None

    def _compute(self, Q) -> Any:
        raise NotImplementedError

    def _state(self, Q) -> Any:
        if not same_configuration(self._cache, Q):
            self._cache = self._compute(Q)
        return self._cache

    def value(self, Q: FloatArray) -> float:
        """The objective at the positions ``Q`` (its formula in the class docstring)."""
        return self._state(Q).value


class CachedPoisson(CachedObjective):
    """A Poisson objective: its state has the nodal state ``.y``, the mass weights ``.m``,
    the ``.solver`` of the stiffness matrix and the adjoint ``.p`` (None until asked)."""

    def _target(self, Q: FloatArray) -> FloatArray | None:
        """The tracking target ``y_d`` at the nodes ``(N,)``; None for ``j = ∫y``."""
        raise NotImplementedError

    def _adjoint_load(self, s) -> FloatArray:
        """``∂j/∂y`` at the state ``s``: ``m`` for ``∫y``, ``m (y − y_d)`` for tracking."""
        yd = self._target(s.Q)
        return s.m if yd is None else tracking_terms(s.m, s.y, yd)[1]

    def _adjoint(self, s) -> FloatArray:
        if s.p is None:
            s.p = s.solver.solve(-self._adjoint_load(s))
        return s.p

    def state(self, Q: FloatArray) -> FloatArray:
        """Nodal values ``(N,)`` of the P1 state ``y`` (``g_D`` on Dirichlet nodes)."""
        return self._state(Q).y.copy()

    def adjoint(self, Q: FloatArray) -> FloatArray:
        """Nodal values ``(N,)`` of the adjoint ``p``: ``K p = −∂j/∂y`` (``−m`` for ``∫y``),
        0 on Dirichlet nodes."""
        return self._adjoint(self._state(Q)).copy()
