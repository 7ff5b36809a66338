"""Integrators for the geodesic equation of a complete metric ``g = I + ∇f ∇fᵀ`` (SPEC §5).

The integrators work on a :class:`GeodesicField`, the closed-form right-hand side

    Q'' = − ∇f(Q) · (Q'ᵀ ∇²f(Q) Q') / (1 + |∇f(Q)|²)                       (5.35)

which costs one call of ``penalty.gradient_and_curvature(Q, V)`` per evaluation (no linear
solve: the inverse metric is a Sherman–Morrison rank-one update, (5.45)).

- :func:`runge_kutta` (:func:`dop853`, :func:`dopri5`, :func:`bs3`): explicit, adaptive,
  error-controlled embedded pairs (first-same-as-last) on the first-order system
  ``(Q, V)' = (V, A(Q, V))``, with dense output (quintic Hermite) for many output times,
  optional energy projection (line searches), and admissibility guards: a step with a
  stage outside M+ (a signed area ≤ 0) or a step end whose boundary touches itself is
  rejected and retried smaller; outputs are checked too (:class:`BoundaryGuard`).
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

from ._linalg import dot as _dot
from ._typing import FloatArray, IntArray
from .errors import IntegrationError, NotAdmissibleError
from .geometry import signed_areas

__all__ = [
    "BS3_TABLEAU",
    "DOPRI5_TABLEAU",
    "PAIRS",
    "BoundaryGuard",
    "GeodesicField",
    "IntegrationOutput",
    "bs3",
    "dop853",
    "dopri5",
    "rk_pair",
    "runge_kutta",
    "stormer_verlet",
]


def _as_complex(Q: FloatArray) -> np.ndarray:
    """``(..., N, 2)`` float positions as ``(..., N)`` complex numbers ``x + iy`` (a view
    when ``Q`` is C-contiguous)."""
    return np.ascontiguousarray(Q, dtype=np.float64).view(np.complex128)[..., 0]


def _abs2(z: np.ndarray) -> np.ndarray:
    """``|z|²`` of a complex array (no square root)."""
    return z.real * z.real + z.imag * z.imag


class BoundaryGuard:
    """Exact test that the boundary of a configuration is simple, made cheap by a
    displacement certificate (used by :class:`GeodesicField`).

    :meth:`problem` answers exactly what ``penalty.boundary_problem`` answers (no boundary
    vertex on a non-incident boundary edge, no two boundary edges crossing or folding
    onto each other). Most calls cost one O(#V∂) comparison:

    *Certificate.* At each exactly checked configuration with a simple boundary (the
    *anchor*) every boundary vertex ``k`` gets a radius ``r_k``: half the smallest
    Euclidean distance between a boundary vertex and a boundary edge not incident to it,
    over the (vertex, edge) pairs that involve ``k`` as the vertex or as an edge end
    (pairs farther apart than a search radius ``R`` count as ``R``). If every boundary
    vertex lies within ``r_k`` of its anchor position, the boundary is simple: along the
    straight path from the anchor the distance of a pair changes by less than
    ``r_i + max(r_j0, r_j1)``, at most its anchor distance, so no vertex ever touches a
    non-incident edge, and boundary edges can only start to meet (cross, or overlap when
    adjacent) where a vertex touches an edge. When that fails, the pairwise form is
    tried (dense mode): every pair's distance changes by at most
    ``max(|Δ_b − Δ_a0|, |Δ_b − Δ_a1|)``, which ignores a common translation (tested pair
    by pair for the pairs closer than a few edge lengths, by ``2 max|Δ|`` for the rest).

    *Exact test.* For at most :data:`DENSE_PAIRS` (vertex, edge) pairs one dense pass
    computes the orientation of every boundary vertex against every boundary edge
    (the same expression as :func:`meshopt_toolkit.mesh.boundary_self_intersections`),
    the segment-pair crossing test (``o1·o2 ≤ 0`` and ``o3·o4 ≤ 0``), the fold test of
    adjacent edges and the distances for the next certificate; only a suspected problem
    is confirmed (and described) by ``penalty.boundary_problem``. Larger boundaries use
    ``penalty.boundary_problem`` and a k-d tree search for the certificate's pairs.

    Parameters
    ----------
    penalty : :class:`~meshopt_toolkit.penalties.Penalty`

    Attributes
    ----------
    n_exact : int
        Exact tests made (certified configurations excluded).
    """

    #: boundaries with at most this many (vertex, edge) pairs use the dense exact test
    DENSE_PAIRS = 60_000

    def __init__(self, penalty) -> None:
        self.penalty = penalty
        self.n_exact = 0
        bv = self._bv = np.asarray(penalty.boundary_vertices)
        be = self._be = np.asarray(penalty.boundary_edges)
        E = len(be)
        self._ea = np.searchsorted(bv, be[:, 0])
        self._eb = np.searchsorted(bv, be[:, 1])
        self._anchor = None
        self._radius2 = None
        self._near = None
        self.dense = len(bv) * E <= self.DENSE_PAIRS
        if self.dense:
            rows = np.arange(E)
            self._incident = np.zeros((E, len(bv)), dtype=bool)
            self._incident[rows, self._ea] = True
            self._incident[rows, self._eb] = True
            # edge pairs (e, f), e < f, without a shared vertex
            share = self._incident[:, self._ea] | self._incident[:, self._eb]
            self._crossable = np.triu(~share, 1)
            # consecutive edges (a, b), (b, c): the fold test
            nxt = np.full(len(bv), -1)
            nxt[self._ea] = rows
            follow = nxt[self._eb]
            ok = follow >= 0
            self._fold = (rows[ok], follow[ok])
        else:
            n = int(max(be.max(initial=0), bv.max(initial=0))) + 1
            keys = be[:, 0].astype(np.int64) * n + be[:, 1]
            self._key_n = n
            self._edge_order = np.argsort(keys)
            self._edge_keys = keys[self._edge_order]

    # -- certificate ------------------------------------------------------------------
    def certified(self, Qs: FloatArray) -> np.ndarray:
        """For configurations ``Qs (m, N, 2)``: which are certified by the anchor, (m,)."""
        if self._anchor is None:
            return np.zeros(len(Qs), dtype=bool)
        move = _as_complex(Qs)[:, self._bv] - self._anchor_z  # (m, B)
        return np.all(_abs2(move) < self._radius2, axis=1)

    #: the pairwise certificate keeps the pairs closer than this many mean boundary edge
    #: lengths at the anchor; farther pairs are covered while no vertex moved half of it
    NEAR_EDGES = 8.0

    def _set_anchor(self, P: FloatArray, r2: FloatArray, d2: FloatArray | None = None,
                    edge_length: float = 0.0) -> None:
        if len(r2) and r2.min() > 0:  # (a vertex in no pair keeps r = inf)
            self._anchor = P.copy()
            self._anchor_z = _as_complex(self._anchor)
            self._radius2 = 0.25 * r2
            self._near = None
            if d2 is not None:
                cap2 = (self.NEAR_EDGES * edge_length) ** 2
                e, b = np.nonzero(d2 < cap2)
                self._near = (b, self._ea[e], self._eb[e], d2[e, b], cap2)
        else:
            self._anchor = None

    def _relative_certified(self, Q: FloatArray) -> bool:
        """The pairwise, translation-invariant form of the certificate (dense mode): the
        distance of vertex ``b`` to edge ``e = [a0, a1]`` changes along the straight path
        by at most ``max(|Δ_b − Δ_a0|, |Δ_b − Δ_a1|)`` (a point of the edge moves by a
        convex combination of its ends' displacements), so the boundary stays simple if
        that is below the pair's anchor distance for every pair. Only the pairs closer
        than ``R`` (:data:`NEAR_EDGES` edge lengths) are tested one by one; for the others
        ``2 max|Δ| < R`` suffices."""
        if self._anchor is None or self._near is None:
            return False
        # complex views: 1-D gathers (row gathers of (k, 2) arrays are several times slower)
        move = _as_complex(Q)[self._bv] - self._anchor_z  # (B,)
        b, a0, a1, d2, cap2 = self._near
        if 4.0 * float(_abs2(move).max()) >= cap2:
            return False
        mb = move[b]
        worst = np.maximum(_abs2(mb - move[a0]), _abs2(mb - move[a1]))
        return bool(np.all(worst < d2))

    # -- exact test ---------------------------------------------------------------------
    def _dense_test(self, Q: FloatArray) -> bool:
        """True if the boundary of ``Q`` may touch itself (then confirm exactly); else
        False, and ``Q`` becomes the anchor. ``Q`` has positive areas (no empty edge)."""
        P = Q[self._bv]  # (B, 2)
        px, py = P[:, 0], P[:, 1]
        ax, ay = px[self._ea], py[self._ea]
        bx, by = px[self._eb], py[self._eb]
        dx, dy = bx - ax, by - ay  # (E,) edge vectors
        rx = px[None, :] - ax[:, None]  # (E, B): vertex b relative to the start of edge e
        ry = py[None, :] - ay[:, None]
        # orientation of vertex b against edge e, as mesh.boundary_self_intersections
        o = dx[:, None] * ry - dy[:, None] * rx
        oa, ob = o[:, self._ea], o[:, self._eb]  # (E, E): edge f's ends against e's line
        s = oa * ob
        hit = (s <= 0) & (s.T <= 0) & self._crossable
        if hit.any():
            e, f = np.nonzero(hit)
            # collinear but disjoint segments pass the sign test: keep overlapping ones
            if not ((oa[e, f] == 0) & (ob[e, f] == 0)).all():
                return True
            t0 = (ax[f] - ax[e]) * dx[e] + (ay[f] - ay[e]) * dy[e]
            t1 = (bx[f] - ax[e]) * dx[e] + (by[f] - ay[e]) * dy[e]
            L = dx[e] * dx[e] + dy[e] * dy[e]
            if np.any((np.maximum(t0, t1) >= 0) & (np.minimum(t0, t1) <= L)):
                return True
        e, f = self._fold
        if len(e):  # at the shared vertex: u towards a (−d_e), v towards c (d_f)
            cross = dx[e] * dy[f] - dy[e] * dx[f]
            if np.any((cross == 0) & (dx[e] * dx[f] + dy[e] * dy[f] < 0)):
                return True
        # distances for the certificate: vertex b to segment e
        L2 = dx * dx + dy * dy
        t = (rx * dx[:, None] + ry * dy[:, None]) / L2[:, None]
        np.clip(t, 0.0, 1.0, out=t)
        rx -= t * dx[:, None]
        ry -= t * dy[:, None]
        d2 = rx * rx
        d2 += ry * ry
        d2[self._incident] = np.inf
        r2 = d2.min(axis=0)
        per_edge = d2.min(axis=1)
        np.minimum.at(r2, self._ea, per_edge)
        np.minimum.at(r2, self._eb, per_edge)
        self._set_anchor(P, r2, d2, float(np.sqrt(L2).mean()))
        return False

    def _pairs_anchor(self, Q: FloatArray) -> None:
        """Certificate of a large boundary from the pairs closer than ``R``."""
        from .distance import boundary_pairs, segment_distance

        bv, be = self._bv, self._be
        edge = Q[be[:, 1]] - Q[be[:, 0]]
        reach = 4.0 * float(np.sqrt(np.einsum("ij,ij->i", edge, edge)).mean())
        pairs = boundary_pairs(bv, be, points=Q, radius=reach)
        r2 = np.full(len(bv), reach * reach)
        per_edge = np.full(len(be), reach * reach)
        if len(pairs):
            d2 = segment_distance(Q, pairs) ** 2
            np.minimum.at(r2, np.searchsorted(bv, pairs[:, 0]), d2)
            key = pairs[:, 1] * self._key_n + pairs[:, 2]
            np.minimum.at(per_edge, self._edge_order[np.searchsorted(self._edge_keys, key)], d2)
        np.minimum.at(r2, self._ea, per_edge)
        np.minimum.at(r2, self._eb, per_edge)
        self._set_anchor(Q[bv], r2)

    def problem(self, Q: FloatArray, certified: bool | None = None) -> str | None:
        """None if the boundary of ``Q (N, 2)`` is simple, else a description (exact).
        ``certified``: the result of :meth:`certified` for ``Q`` if already known."""
        if len(self._be) < 3:
            return None
        if certified is None:
            certified = bool(self.certified(Q[None])[0])
        if certified or (self.dense and self._relative_certified(Q)):
            return None
        self.n_exact += 1
        if self.dense and not self._dense_test(Q):
            return None
        problem = self.penalty.boundary_problem(Q)
        if problem is None and not self.dense:
            self._pairs_anchor(Q)
        return problem


class GeodesicField:
    """The geodesic right-hand side of the complete metric built from ``penalty``.

    Parameters
    ----------
    penalty : object
        Provides ``gradient_and_curvature(Q, V) -> ((N, 2), float)``, ``gradient(Q)``,
        ``hvp(Q, V)`` and ``value(Q)`` (the penalty protocol of
        :mod:`meshopt_toolkit.penalties`).
    triangles : (T, 3) int array, optional
        Connectivity used to test ``min signed area > 0`` (a ``Penalty`` brings its own).
        Without it the penalty's ``is_admissible(Q)`` is used.
    free : (N,) bool array, optional
        Vertices allowed to move. With fixed vertices the field is that of the metric
        restricted to the affine subspace ``{Q : Q_fixed = const}`` (as
        ``CompleteMetric.riesz(..., free=...)``): ``g = I + ∇_F f ∇_F fᵀ`` with ``∇_F f``
        the gradient with the fixed rows zeroed, so (5.35) holds with ``∇_F f`` in place
        of ``∇f`` (the curvature ``V·∇²f·V`` is unchanged for ``V`` vanishing on the
        fixed vertices) and fixed vertices never move.

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
      are auxiliary (with ``β3 = 0`` nothing in ``f`` prevents a crossing, and the
      formulas are finite on both sides of one). With a ``Penalty`` this is a
      :class:`BoundaryGuard` (exact, mostly certified at the cost of one comparison);
      for other penalties the penalty's own evaluation (which may check the boundary)
      and ``is_admissible`` are used.

    Attributes
    ----------
    n_evaluations : int
        Number of penalty calls (gradient, curvature, hvp or value) made so far.
    n_boundary_checks : int
        Exact boundary tests made (certified configurations excluded).
    checks_areas : bool
        True when :meth:`acceleration` itself raises ``NotAdmissibleError`` at a
        non-positive signed area (the penalty declares ``checks_areas``, as
        :class:`~meshopt_toolkit.penalties.Penalty` does).
    """

    def __init__(
        self, penalty, triangles: IntArray | None = None, free: np.ndarray | None = None
    ) -> None:
        self.penalty = penalty
        self.checks_areas = bool(getattr(penalty, "checks_areas", False))
        if triangles is None and self.checks_areas:
            triangles = penalty.mesh.triangles
        self.triangles = None if triangles is None else np.asarray(triangles)
        self.n_evaluations = 0
        self._guard = BoundaryGuard(penalty) if self.checks_areas else None
        if self.triangles is not None:
            self._tri_t = np.ascontiguousarray(self.triangles.T)
        self._fixed = None
        if free is not None:
            free = np.asarray(free, dtype=bool)
            if not free.all():
                self._fixed = np.flatnonzero(~free)

    def _restrict(self, grad: FloatArray) -> FloatArray:
        """``∇f`` restricted to the free vertices (rows of fixed vertices zeroed)."""
        if self._fixed is not None:
            grad = np.array(grad, dtype=float)
            grad[self._fixed] = 0.0
        return grad

    @property
    def n_boundary_checks(self) -> int:
        """Exact boundary tests made so far."""
        return 0 if self._guard is None else self._guard.n_exact

    def admissible(self, Q: FloatArray) -> bool:
        """True if every triangle of ``Q`` has positive signed area (and ``Q`` is finite)."""
        if not np.isfinite(Q).all():
            return False
        if self.triangles is not None:
            return bool(signed_areas(Q, self.triangles).min() > 0.0)
        return bool(self.penalty.is_admissible(Q))

    def admissible_many(self, Qs: FloatArray, base: FloatArray | None = None) -> bool:
        """True if every configuration of ``Qs (m, N, 2)`` is admissible (areas and
        boundary), tested together: one vectorized area pass, then the boundary.

        ``base`` (N, 2), an admissible configuration near them (the start of the step
        they interpolate), lets configurations close to it skip the area pass: moving
        every vertex by at most ``δ`` changes a signed area by at most ``δ L + 2δ²``
        (``L`` the perimeter; ``A = ½ e1 × e2`` with ``e1, e2`` changing by ≤ 2δ each), so
        ``δ < min_k A_k / (2 L_k)`` keeps every area positive.
        """
        if len(Qs) == 0:
            return True
        if not np.isfinite(Qs).all():
            return False
        if self.triangles is None:
            return all(self.penalty.is_admissible(q) for q in Qs)
        check = Qs
        if base is not None and len(Qs) > 2:
            move = (Qs - base).reshape(len(Qs), -1, 2)
            delta2 = np.einsum("mij,mij->mi", move, move).max(axis=1)
            zb = base.view(np.complex128)[:, 0][self._tri_t]  # (3, T)
            e1, e2, e3 = zb[1] - zb[0], zb[2] - zb[0], zb[2] - zb[1]
            area = 0.5 * (e1.conj() * e2).imag
            perimeter = np.abs(e1) + np.abs(e2) + np.abs(e3)
            bound = float((area / (2.0 * perimeter)).min())
            check = Qs[~(delta2 < bound * bound)]
        if len(check):
            z = np.ascontiguousarray(check).view(np.complex128)[..., 0][:, self._tri_t]
            z1 = z[:, 1] - z[:, 0]  # (m, T)
            z2 = z[:, 2] - z[:, 0]
            area2 = (z1.conj() * z2).imag  # 2A = (q1 − q0) × (q2 − q0)
            if not area2.min() > 0.0:
                return False
        if self._guard is None:
            return all(self.boundary_problem(q) is None for q in Qs)
        cert = self._guard.certified(Qs)
        return all(self._guard.problem(q, bool(c)) is None for q, c in zip(Qs, cert))

    def boundary_problem(self, Q: FloatArray) -> str | None:
        """None if the boundary of ``Q`` does not touch itself, else a description.

        Exact (a :class:`BoundaryGuard` for a ``Penalty``); for other penalties this is
        ``penalty.is_admissible`` when it has one (else None: its evaluations are trusted
        to raise).
        """
        if self._guard is not None:
            return self._guard.problem(Q)
        check = getattr(self.penalty, "is_admissible", None)
        if check is None or check(Q):
            return None
        return "the boundary self-intersects"

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
        grad = self._restrict(np.asarray(grad, dtype=float))
        return (-float(curv) / (1.0 + _dot(grad, grad))) * grad, grad

    def gradient(self, Q: FloatArray) -> FloatArray:
        """∇f(Q), (N, 2) (restricted to the free vertices, if any are fixed)."""
        self.n_evaluations += 1
        return self._restrict(np.asarray(self.penalty.gradient(Q), dtype=float))

    def hvp(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """∇²f(Q) V, (N, 2) (restricted to the free vertices, if any are fixed)."""
        self.n_evaluations += 1
        return self._restrict(np.asarray(self.penalty.hvp(Q, V), dtype=float))

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


def _initial_step(field: GeodesicField, y, a, rk: _Pair, rtol, atol, t_end: float) -> float:
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
    progress=None,
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
    e0 = e_prev = energy(grad, y[1])
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
        e_new = energy(grad_new, y_new[1])
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
