"""The penalized shape problem ``F = j + f2`` on ``M+`` as the descent methods see it.

:class:`ShapeProblem` bundles the objective, the penalty, the gradient metric, the fixed
vertices and the admissibility test, and turns every way of leaving ``M+`` into
``F = +∞``: a trial configuration with a non-positive signed area, a boundary that touches
itself, a non-finite value, or an objective that refuses it (``NotAdmissibleError``) is
*rejected*, never fatal. :func:`max_travel_step` is steepest descent's guard (6.23) on
straight-line steps; the other methods cap theirs by
:func:`~meshopt_toolkit.kernels.triangles.segment_limit`.
"""

from __future__ import annotations

import time

import numpy as np

from .._linalg import dot
from .._typing import FloatArray
from ..errors import NotAdmissibleError
from ..kernels.triangles import aspect_ratios, heights, quality_summary, segment_limit, signed_areas
from ..mesh import boundary_self_intersections


def max_travel_step(Q: FloatArray, triangles: np.ndarray, d: FloatArray) -> float:
    """Largest step allowed by the node-travel safeguard (6.23) of steepest descent.

    A trial step ``s`` is refused when ``s |d_i| ≥ ½ h_l`` for a vertex ``i`` at local
    position ``l`` of any triangle, ``h_l`` that triangle's height from ``i``. Returns
    ``min ½ h_l / |d_i|`` (inf when ``d`` vanishes).
    """
    h = heights(Q, triangles)  # (T, 3), height from local vertex l onto the opposite edge
    speed = np.linalg.norm(d, axis=1)[triangles]  # (T, 3)
    with np.errstate(divide="ignore"):
        limit = np.where(speed > 0, 0.5 * h / speed, np.inf)
    return float(limit.min())


class ShapeProblem:
    """``F(Q) = j(Q) + f2(Q)`` with its gradient metric on the free vertices.

    Parameters
    ----------
    objective : object with ``value(Q)`` and ``derivative(Q)`` (the shape functional j)
    penalty : QualityPenalty or None (f2 added to j)
    metric : a metric of :mod:`meshopt_toolkit.riemannian.metrics` (its Riesz map gives gradients)
    triangles : (T, 3) connectivity
    boundary_edges : (E, 2) directed boundary edges (for the boundary self-contact test)
    free : (N,) bool mask of the free vertices, or None (all free)
    constraint : :class:`~.area.AreaConstraint` or None: gradients and directions are
        projected onto its tangent space
    quality_floor : float or None
        A configuration whose worst triangle has an aspect ratio below this is rejected
        like one outside ``M+`` (the iterates keep every triangle at least this healthy).
    """

    def __init__(self, objective, penalty, metric, triangles, boundary_edges, free=None,
                 constraint=None, quality_floor: float | None = None) -> None:
        self.objective = objective
        self.penalty = penalty
        self.metric = metric
        self.triangles = np.asarray(triangles)
        self.boundary_edges = np.asarray(boundary_edges)
        self.free = free
        self.constraint = constraint
        self.quality_floor = quality_floor
        self.n_rejected = 0  # trial configurations outside M+
        # a planar penalty tests the boundary itself (its value is +∞ where the boundary
        # touches itself) and gives its gradient with its value at little more cost: a
        # trial point's boundary is tested once, and the accepted one's gradient kept
        from ..penalties import QualityPenalty  # here: the penalties import scipy

        self._penalty_checks = isinstance(penalty, QualityPenalty)
        self._penalty_gradient: tuple[FloatArray, FloatArray] | None = None

    def admissible(self, Q: FloatArray) -> bool:
        """All coordinates finite, every signed area > 0 (every aspect ratio ≥ the quality
        floor), the boundary simple."""
        return self._cells_admissible(Q) and \
            len(boundary_self_intersections(Q, self.boundary_edges)) == 0

    def _cells_admissible(self, Q: FloatArray) -> bool:
        """:meth:`admissible` without the boundary test."""
        if not np.isfinite(Q).all():
            return False
        if not np.all(signed_areas(Q, self.triangles) > 0):
            return False
        return self._above_floor(Q)

    #: the per-cell quality that :attr:`quality_floor` bounds from below
    floor_quality = staticmethod(aspect_ratios)

    def _above_floor(self, Q: FloatArray) -> bool:
        """No :attr:`floor_quality` below the quality floor (always, without one)."""
        return self.quality_floor is None or \
            self.floor_quality(Q, self.triangles).min() >= self.quality_floor

    def values(self, Q: FloatArray) -> tuple[float, float]:
        """``(F, j)`` at ``Q``; ``(inf, inf)`` outside ``M+`` (counted in ``n_rejected``).
        A planar penalty is evaluated first, with its gradient (kept for
        :meth:`derivative`), and tests the boundary."""
        if not (self._cells_admissible(Q) if self._penalty_checks else self.admissible(Q)):
            self.n_rejected += 1
            return np.inf, np.inf
        try:
            if self._penalty_checks:
                fp, gradient = self.penalty.value_and_gradient(Q)
                self._penalty_gradient = (np.array(Q, dtype=float), gradient)
            else:
                fp = 0.0 if self.penalty is None else float(self.penalty.value(Q))
            J = float(self.objective.value(Q))
        except NotAdmissibleError:
            self.n_rejected += 1
            return np.inf, np.inf
        F = J + fp
        if not np.isfinite(F):
            self.n_rejected += 1
            return np.inf, np.inf
        return F, J

    def derivative(self, Q: FloatArray, timer=None) -> FloatArray:
        """``dF(Q)`` as an (N, 2) array, zero on the fixed vertices; ``timer`` (a
        :class:`~.result.PhaseTimer`) gets j's and f2's times as ``"derivative"`` and
        ``"penalty_derivative"``."""
        t0 = time.perf_counter()
        P = np.asarray(self.objective.derivative(Q), dtype=float)
        if timer is not None:
            t0 = timer.add("derivative", t0)
        if self.penalty is not None:
            kept = self._penalty_gradient
            same = kept is not None and np.array_equal(kept[0], Q)
            P = P + (kept[1] if same else self.penalty.gradient(Q))
            if timer is not None:
                timer.add("penalty_derivative", t0)
        if self.free is not None:
            P = np.where(self.free[:, None], P, 0.0)
        return P

    def riesz(self, Q: FloatArray, P: FloatArray) -> FloatArray:
        """The metric's Riesz map ``g_Q⁻¹ P`` restricted to the free vertices (and
        projected onto the constraint's tangent space)."""
        return self.project(Q, self.metric.riesz(Q, P, free=self.free))

    def project(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """``V`` projected onto the constraint's tangent space (``V`` without one)."""
        return V if self.constraint is None else self.constraint.project(Q, V)

    def quality(self, Q: FloatArray) -> tuple[float, float]:
        """``(mean, worst)`` cell quality at ``Q``: the mean shape quality Λ (6.25) and
        the minimum aspect ratio (5.49)."""
        q = quality_summary(Q, self.triangles)
        return q.mean_shape_quality, q.min_aspect_ratio

    def step_limit(self, Q: FloatArray, d: FloatArray) -> float:
        """The first ``t > 0`` at which a cell of ``Q + t d`` degenerates (inf: none)."""
        return segment_limit(Q, self.triangles, d)

    def travel_limit(self, Q: FloatArray, d: FloatArray) -> float:
        """Steepest descent's guard on ``Q + t d`` (:func:`max_travel_step`)."""
        return max_travel_step(Q, self.triangles, d)

    @staticmethod
    def pair(P: FloatArray, V: FloatArray) -> float:
        """The duality pairing ``P[V] = vec P · vec V`` of a derivative and a vector."""
        return dot(P, V)
