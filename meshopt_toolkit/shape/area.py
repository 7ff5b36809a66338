"""The domain's area as an exact constraint: ``A(Q) = A(Q0)``.

``A(Q) = ½ Σ_{(a,b)∈E∂} q_a × q_b`` (shoelace over the oriented boundary) is a quadratic
form, so along a line ``A(X + μ n) = A(X) + μ ∇A(X)·n + μ² A(n)`` exactly and the point of
the constraint on that line is a root of a quadratic. Directions are projected onto the
tangent space ``{V : ∇A·V = 0}`` orthogonally in the gradient metric ``G`` (the
correction is along ``n = G⁻¹∇A``), and every trial point ``X(t)`` of a line search is
moved back onto the constraint along ``n``: fixed vertices, where ``n`` and the
direction vanish, are never changed.
"""

from __future__ import annotations

import math

import numpy as np

from .._linalg import dot
from .._typing import FloatArray


def shoelace_area(Q: FloatArray, edges: np.ndarray) -> float:
    """``½ Σ q_a × q_b`` over the directed boundary edges ``(E, 2)``."""
    a, b = Q[edges[:, 0]], Q[edges[:, 1]]
    return 0.5 * float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))


def shoelace_gradient(Q: FloatArray, edges: np.ndarray) -> FloatArray:
    """``∇A`` ``(N, 2)``: edge ``(a, b)`` adds ``½(y_b, −x_b)`` at ``a``, ``½(−y_a, x_a)`` at ``b``."""
    a, b = edges[:, 0], edges[:, 1]
    n = len(Q)
    gx = np.bincount(a, Q[b, 1], n) - np.bincount(b, Q[a, 1], n)
    gy = np.bincount(b, Q[a, 0], n) - np.bincount(a, Q[b, 0], n)
    return 0.5 * np.column_stack([gx, gy])


class AreaConstraint:
    """``A(Q) = target`` with its metric projection and restoration.

    Parameters
    ----------
    edges : (E, 2) directed boundary edges
    target : the area to keep
    riesz : ``(Q, P) -> G_Q⁻¹ P`` restricted to the free vertices
    """

    def __init__(self, edges: np.ndarray, target: float, riesz) -> None:
        self.edges = np.asarray(edges)
        self.target = float(target)
        self._riesz = riesz
        self._at: FloatArray | None = None
        self._normal: tuple[FloatArray, FloatArray, float] | None = None

    def normal(self, Q: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        """``(∇A, n = G⁻¹∇A, ∇A·n)`` at ``Q`` (cached for the last ``Q``)."""
        if self._at is None or not np.array_equal(self._at, Q):
            a = shoelace_gradient(Q, self.edges)
            n = self._riesz(Q, a)
            self._at, self._normal = np.array(Q, dtype=float), (a, n, dot(a, n))
        return self._normal

    def project(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """``V − (∇A·V / ∇A·n) n``: the G-orthogonal projection onto the tangent space."""
        a, n, an = self.normal(Q)
        return V - (dot(a, V) / an) * n if an > 0 else V

    def restore(self, X: FloatArray, n: FloatArray) -> FloatArray | None:
        """``X + μ n`` with ``A = target`` (the root of smaller ``|μ|``), None if none."""
        c = shoelace_area(X, self.edges) - self.target
        b = dot(shoelace_gradient(X, self.edges), n)
        a = shoelace_area(n, self.edges)
        disc = b * b - 4.0 * a * c
        if disc < 0 or (a == 0 and b == 0):
            return None
        if a == 0:
            mu = -c / b
        else:
            q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
            roots = [r for r in ((q / a) if a else math.inf, (c / q) if q else math.inf)
                     if math.isfinite(r)]
            if not roots:
                return None
            mu = min(roots, key=abs)
        return X + mu * n

    def curve(self, Q: FloatArray, base=None):
        """The retraction ``t ↦ restore(R(t))`` with ``R`` the straight line (``base``
        None) or ``base``, as ``(Q, d, ts) -> (points, velocities)``; the velocity is
        ``R'(t) + μ'(t) n`` with ``μ' = −∇A·R' / ∇A·n`` at the restored point."""
        _, n, _ = self.normal(Q)

        def velocity(R, V):
            aR = shoelace_gradient(R, self.edges)
            an = dot(aR, n)
            return V - (dot(aR, V) / an) * n if an != 0 else V

        return restored_curve(base, lambda X: self.restore(X, n), velocity)


def restored_curve(base, restore, velocity):
    """``(Q, d, ts) -> (points, velocities)``: the points of the straight line ``Q + t d``
    (``base`` None) or of ``base`` passed through ``restore(X)`` (None: no point), their
    velocities ``V`` through ``velocity(R, V)`` at the restored point ``R``."""

    def retract(Q0, d, ts):
        if base is None:
            pts, vel = [Q0 + t * d for t in ts], [d] * len(ts)
        else:
            pts, vel = base(Q0, d, ts)
        out_p, out_v = [], []
        for X, V in zip(pts, vel):
            R = None if X is None else restore(X)
            out_p.append(R)
            out_v.append(None if R is None else velocity(R, V))
        return out_p, out_v

    return retract
