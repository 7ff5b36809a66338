"""Retractions of the complete metric: the curves a line search moves along.

A retraction ``R`` maps a tangent vector ``V`` at ``Q`` to a configuration with
``R_Q(0) = Q`` and ``d/dt R_Q(tV)|₀ = V``; Riemannian descent methods converge with any
(Absil, Mahony & Sepulchre 2008, §4.1). Two are offered for the complete metric
``g = I + ∇f∇fᵀ``; both are called as ``retraction(Q, V, times)`` and return the points
``R_Q(tV)`` and velocities ``d/dt R_Q(tV)`` for each ``t``, None where the point is not
admissible (or was not reached):

* :class:`ExponentialRetraction`: the exponential map (6.19), one geodesic integration
  through all the requested times (thesis Algorithm 2);
* :class:`SecondOrderRetraction`: ``R_Q(tV) = Q + tV + ½t² A(Q, V)`` with the geodesic
  acceleration ``A = −∇f (Vᵀ∇²f V)/(1 + |∇f|²)`` (5.35): the exponential map's Taylor
  polynomial of degree two, so a second-order retraction (it agrees with the geodesic up
  to ``O(t³)`` and has zero covariant acceleration at ``t = 0``). It costs one gradient
  and one Hessian-vector product of ``f`` per ``(Q, V)``, shared by every ``t``, against
  tens of penalty evaluations per geodesic whose step count grows with the stiffness of
  the smallest triangles. Admissibility is not built in as it is for the
  geodesic: every point is checked exactly (signed areas, simple boundary) and refused
  when it fails, as the line search refuses a point where ``f = +∞``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from .._typing import FloatArray
from ..errors import IntegrationError, NotAdmissibleError
from .field import GeodesicField
from .geodesic_options import GeodesicOptions
from .geodesics import free_vertex_mask, geodesic, penalty_of, triangles_of

logger = logging.getLogger(__name__)

__all__ = ["ExponentialRetraction", "Retraction", "RetractionPoints", "SecondOrderRetraction"]

#: points and velocities of a retraction at the requested times (None: not admissible)
RetractionPoints = tuple[list[FloatArray | None], list[FloatArray | None]]


class Retraction(Protocol):
    """``retraction(Q, V, times)``: the points ``R_Q(tV)`` and their velocities."""

    def __call__(self, Q: FloatArray, V: FloatArray,
                 times: Sequence[float]) -> RetractionPoints: ...


class ExponentialRetraction:
    """The exponential map of ``metric`` (a geodesic through all times at once).

    Parameters
    ----------
    metric : CompleteMetric or penalty
    options : GeodesicOptions
        How the geodesic is integrated.
    free : (N,) bool mask or indices, optional
        The vertices that may move (see :func:`~.geodesics.geodesic`).
    """

    def __init__(self, metric, options: GeodesicOptions, free=None) -> None:
        self.metric = metric
        self.options = options
        self.free = free

    def __call__(self, Q: FloatArray, V: FloatArray, times: Sequence[float]) -> RetractionPoints:
        times = np.asarray(times, dtype=float)
        ascending = np.unique(times)
        reached = {}
        try:
            geo = geodesic(self.metric, Q, V, float(ascending[-1]), times=ascending,
                           options=self.options, free=self.free)
            part = geo
        except (IntegrationError, NotAdmissibleError) as exc:
            # e.g. with β3 = 0 the geodesic runs the boundary into itself: the times it
            # did reach are valid points, the later ones are not
            logger.info("exponential map stopped early: %s", exc)
            part = getattr(exc, "partial", None)
        if part is not None:
            reached = {float(t): (p, v) for t, p, v in
                       zip(part.times, part.points, part.velocities)}
        found = [reached.get(float(t), (None, None)) for t in times]
        return [p for p, _ in found], [v for _, v in found]


class SecondOrderRetraction:
    """``R_Q(tV) = Q + tV + ½t² A(Q, V)``, ``A`` the geodesic acceleration (5.35).

    Parameters
    ----------
    metric : CompleteMetric or penalty
    free : (N,) bool mask or indices, optional
        The vertices that may move: the acceleration of the metric restricted to them
        (fixed vertices stay put).

    Notes
    -----
    The acceleration of the last ``(Q, V)`` is kept (by identity of the arrays, which
    the retraction holds on to), so a line search asking for one ``t`` at a time pays
    for it once.
    """

    def __init__(self, metric, free=None) -> None:
        self.metric = metric
        self.free = free
        self._field: GeodesicField | None = None
        self._last: tuple[FloatArray, FloatArray, FloatArray] | None = None

    def _acceleration(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        if self._last is not None and self._last[0] is Q and self._last[1] is V:
            return self._last[2]
        if self._field is None:
            pen = penalty_of(self.metric)
            self._field = GeodesicField(pen, triangles_of(pen),
                                        free=free_vertex_mask(self.free, len(Q)))
        A = self._field.acceleration(Q, V)[0]
        self._last = (Q, V, A)
        return A

    def __call__(self, Q: FloatArray, V: FloatArray, times: Sequence[float]) -> RetractionPoints:
        A = self._acceleration(Q, V)
        points: list[FloatArray | None] = []
        velocities: list[FloatArray | None] = []
        for t in np.asarray(times, dtype=float):
            P = Q + t * V + (0.5 * t * t) * A
            if self._field.admissible(P) and self._field.boundary_problem(P) is None:
                points.append(P)
                velocities.append(V + t * A)
            else:
                logger.debug("second-order retraction: t = %.3g leaves M+", t)
                points.append(None)
                velocities.append(None)
        return points, velocities
