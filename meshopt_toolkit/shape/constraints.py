"""Enclosed measure and barycenter of a body as exact constraints, in 2D and 3D.

A closed oriented boundary — directed edges ``(F, 2)`` of a planar domain, outward
triangles ``(F, 3)`` of a tetrahedral one — encloses the measure (divergence theorem)

    ``V = (1/d!) Σ_f D_f``,  ``D_f = det[q_0, …, q_{d−1}]``

(2D: the shoelace area ``½ Σ q_a × q_b``; 3D: ``(1/6) Σ (a × b)·c``) and the first moments

    ``M = ∫ x dV = Σ_f D_f (q_0 + … + q_{d−1}) / (d! (d+1))``,

each facet adding the cone from the origin (exact for a closed boundary, whatever the
origin: the sums are evaluated about the mean facet corner). The barycenter is
``b = M / V``. :class:`ExactConstraints` keeps ``c(Q) = c(Q0)`` for ``c`` the measure
and/or the ``d`` barycenter coordinates: directions are projected
G-orthogonally onto ``{V : ∇c·V = 0}`` with the ``m × m`` Gram matrix of ``N = G⁻¹∇c``, and
trial points are restored by Newton's method along ``span N``. Vertices fixed by the
metric (where ``N`` vanishes) are never moved. The single area constraint of the planar
optimizer, restored by the root of a quadratic, is :class:`~.area.AreaConstraint`; the 2D
measure here is its shoelace form.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InvalidMeshError, OptionError
from .._typing import FloatArray, IntArray
from ..kernels.cell_maps import scatter_corners
from .area import restored_curve, shoelace_area, shoelace_gradient


def _determinants(Q: FloatArray, facets: IntArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(D (F,), ∂D/∂q (F, d, d), corners (F, d, d))``: the facet determinants, their
    cofactors per local vertex and the corner positions."""
    p = np.asarray(Q, dtype=float)[np.asarray(facets)]
    if p.shape[1] == 2:
        a, b = p[:, 0], p[:, 1]
        D = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        cof = np.stack([np.column_stack([b[:, 1], -b[:, 0]]),
                        np.column_stack([-a[:, 1], a[:, 0]])], axis=1)
    else:
        a, b, c = p[:, 0], p[:, 1], p[:, 2]
        bc = np.cross(b, c)
        D = np.einsum("fk,fk->f", a, bc)
        cof = np.stack([bc, np.cross(c, a), np.cross(a, b)], axis=1)
    return D, cof, p


def _centred(Q: FloatArray, facets: IntArray) -> tuple[FloatArray, FloatArray]:
    """``(Q − o, o)`` with ``o`` the mean facet corner: every form below is the same about
    any origin for a closed boundary, and about ``o`` it does not cancel digits far from
    the origin. ``o`` is a constant for the derivatives (they do not depend on it)."""
    d = np.shape(Q)[1]
    if d not in (2, 3) or np.shape(facets)[1] != d:
        raise InvalidMeshError(f"facets {np.shape(facets)} do not bound a region of points "
                               f"{np.shape(Q)}")
    Q = np.asarray(Q, dtype=float)
    o = Q[np.asarray(facets)].reshape(-1, d).mean(axis=0)
    return Q - o, o


def _measure(Qc: FloatArray, facets: IntArray) -> float:
    if Qc.shape[1] == 2:
        return shoelace_area(Qc, np.asarray(facets))
    return float(np.sum(_determinants(Qc, facets)[0])) / 6.0


def _measure_gradient(Qc: FloatArray, facets: IntArray) -> FloatArray:
    if Qc.shape[1] == 2:
        return shoelace_gradient(Qc, np.asarray(facets))
    return scatter_corners(facets, _determinants(Qc, facets)[1], len(Qc)) / 6.0


def _moments(Qc: FloatArray, facets: IntArray) -> FloatArray:
    d = Qc.shape[1]
    D, _, p = _determinants(Qc, facets)
    return D @ p.sum(axis=1) / (math.factorial(d) * (d + 1))


def _moments_gradient(Qc: FloatArray, facets: IntArray) -> FloatArray:
    d = Qc.shape[1]
    D, cof, p = _determinants(Qc, facets)
    S = p.sum(axis=1)
    out = np.empty((d, len(Qc), d))
    for i in range(d):
        per = cof * S[:, None, i, None]
        per[:, :, i] += D[:, None]
        out[i] = scatter_corners(facets, per, len(Qc))
    return out / (math.factorial(d) * (d + 1))


def enclosed_measure(Q: FloatArray, facets: IntArray) -> float:
    """Signed area (``Q (N, 2)``, edges ``(F, 2)``) or volume (``Q (N, 3)``, triangles
    ``(F, 3)``) enclosed by the oriented boundary; positive for outward orientation."""
    return _measure(_centred(Q, facets)[0], facets)


def measure_gradient(Q: FloatArray, facets: IntArray) -> FloatArray:
    """``∇V`` ``(N, d)``: facet ``f`` adds ``∂D_f/∂q_k / d!`` at its ``k``-th vertex."""
    return _measure_gradient(_centred(Q, facets)[0], facets)


def first_moments(Q: FloatArray, facets: IntArray) -> FloatArray:
    """``∫ x dV`` ``(d,)`` over the region the oriented boundary encloses."""
    Qc, o = _centred(Q, facets)
    return _moments(Qc, facets) + o * _measure(Qc, facets)


def moments_gradient(Q: FloatArray, facets: IntArray) -> FloatArray:
    """``∇M_i`` ``(d, N, d)``: per facet ``∂M_i/∂q_k = (∂D/∂q_k S_i + D e_i) / (d!(d+1))``,
    ``S`` the sum of its corners."""
    Qc, o = _centred(Q, facets)
    return _moments_gradient(Qc, facets) + o[:, None, None] * _measure_gradient(Qc, facets)


def barycenter(Q: FloatArray, facets: IntArray) -> FloatArray:
    """``M / V`` ``(d,)``: the centroid of the enclosed region."""
    Qc, o = _centred(Q, facets)
    return _moments(Qc, facets) / _measure(Qc, facets) + o


def barycenter_gradient(Q: FloatArray, facets: IntArray) -> FloatArray:
    """``∇b_i = (∇M_i − b_i ∇V) / V`` ``(d, N, d)`` (about ``o``, where ``b`` is small)."""
    Qc, _ = _centred(Q, facets)
    V = _measure(Qc, facets)
    b = _moments(Qc, facets) / V
    return (_moments_gradient(Qc, facets) - b[:, None, None] * _measure_gradient(Qc, facets)) / V


def body_facets(Q: FloatArray, facets: IntArray, vertices: IntArray) -> IntArray:
    """The facets with every vertex in ``vertices`` (one body's boundary, e.g. a physical
    group's vertices), oriented so the region they enclose has positive measure: a hole's
    boundary, oriented outward from the domain, is flipped."""
    facets = np.asarray(facets)
    inside = np.zeros(len(Q), bool)
    inside[np.asarray(vertices)] = True
    own = facets[inside[facets].all(axis=1)]
    if not len(own):
        raise InvalidMeshError("no boundary facet has all its vertices in the body")
    return own[:, ::-1].copy() if enclosed_measure(Q, own) < 0 else own


class ExactConstraints:
    """``c(Q) = c(Q0)`` for the enclosed measure and/or the barycenter of a body.

    Parameters
    ----------
    facets : (F, d) oriented boundary facets of the body
    Q0 : (N, d) node positions giving the targets
    riesz : ``(Q, P) -> G_Q⁻¹ P``, zero on fixed vertices
    measure, barycenter : which constraints (``m = measure + d·barycenter``)
    """

    def __init__(self, facets: IntArray, Q0: FloatArray, riesz, *, measure: bool = True,
                 barycenter: bool = False) -> None:
        if not (measure or barycenter):
            raise OptionError("no constraint selected: measure or barycenter")
        self.facets = np.asarray(facets)
        self.measure, self.barycenter = bool(measure), bool(barycenter)
        self._riesz = riesz
        V0 = abs(enclosed_measure(Q0, self.facets))
        if not V0 > 0:
            raise InvalidMeshError("the boundary encloses no area or volume")
        length = V0 ** (1.0 / np.shape(Q0)[1])
        # the relative scale of each constraint: the measure, a length for coordinates
        self.scale = np.array(([V0] if measure else []) + ([length] * np.shape(Q0)[1]
                                                           if barycenter else []))
        self.target = self.values(Q0)
        self._at: FloatArray | None = None
        self._normals = None

    def values(self, Q: FloatArray) -> FloatArray:
        """``c(Q)`` ``(m,)``."""
        parts = []
        if self.measure:
            parts.append([enclosed_measure(Q, self.facets)])
        if self.barycenter:
            parts.append(barycenter(Q, self.facets))
        return np.concatenate(parts)

    def jacobian(self, Q: FloatArray) -> FloatArray:
        """``∇c`` ``(m, N, d)``."""
        parts = []
        if self.measure:
            parts.append(measure_gradient(Q, self.facets)[None])
        if self.barycenter:
            parts.append(barycenter_gradient(Q, self.facets))
        return np.concatenate(parts)

    def normals(self, Q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(∇c, N = G⁻¹∇c, Gram = ∇c·N)`` at ``Q`` (cached for the last ``Q``)."""
        if self._at is None or not np.array_equal(self._at, Q):
            J = self.jacobian(Q)
            N = np.stack([self._riesz(Q, g) for g in J])
            gram = np.einsum("inx,jnx->ij", J, N)
            self._at, self._normals = np.array(Q, dtype=float), (J, N, gram)
        return self._normals

    def project(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """``V − N Gram⁻¹ (∇c·V)``: the G-orthogonal projection onto the tangent space."""
        J, N, gram = self.normals(Q)
        lam = np.linalg.solve(gram, np.einsum("inx,nx->i", J, V))
        return V - np.einsum("i,inx->nx", lam, N)

    def restore(self, X: FloatArray, N: FloatArray, *, tolerance: float = 1e-12,
                max_iterations: int = 20) -> FloatArray | None:
        """``X + Σ μ_j N_j`` with ``c = c(Q0)`` to ``tolerance`` relative to ``scale``, by
        Newton's method on ``μ`` from 0; None if it does not converge."""
        mu = np.zeros(len(N))
        for _ in range(max_iterations + 1):
            R = X + np.einsum("i,inx->nx", mu, N)
            r = self.values(R) - self.target
            if not np.all(np.isfinite(r)):
                return None
            if np.all(np.abs(r) <= tolerance * self.scale):
                return R
            A = np.einsum("inx,jnx->ij", self.jacobian(R), N)
            try:
                mu -= np.linalg.solve(A, r)
            except np.linalg.LinAlgError:
                return None
        return None

    def curve(self, Q: FloatArray, base=None):
        """The retraction ``t ↦ restore(R(t))`` with ``R`` the straight line (``base``
        None) or ``base``, as ``(Q, d, ts) -> (points, velocities)`` (the protocol of
        :meth:`~.area.AreaConstraint.curve`); the velocity is ``R'(t) + N μ'(t)`` with
        ``(∇c·N) μ' = −∇c·R'`` at the restored point, so it is tangent there."""
        N = self.normals(Q)[1]

        def velocity(R, V):
            J = self.jacobian(R)
            dmu = np.linalg.solve(np.einsum("inx,jnx->ij", J, N), -np.einsum("inx,nx->i", J, V))
            return V + np.einsum("i,inx->nx", dmu, N)

        return restored_curve(base, lambda X: self.restore(X, N), velocity)
