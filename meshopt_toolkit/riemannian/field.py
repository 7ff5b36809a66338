"""The geodesic right-hand side of a complete metric ``g = I + ∇f ∇fᵀ`` (SPEC §5).

:class:`GeodesicField` is the closed-form right-hand side

    Q'' = − ∇f(Q) · (Q'ᵀ ∇²f(Q) Q') / (1 + |∇f(Q)|²)                       (5.35)

which costs one call of ``penalty.gradient_and_curvature(Q, V)`` per evaluation (no linear
solve: the inverse metric is a Sherman–Morrison rank-one update, (5.45)), with the
admissibility tests the integrators of :mod:`meshopt_toolkit.ode` call
(:class:`~meshopt_toolkit.ode.SecondOrderField`). :class:`BoundaryGuard` makes the exact
boundary test cheap by a displacement certificate.
"""

from __future__ import annotations

import numpy as np

from .._linalg import dot as _dot
from .._typing import FloatArray, IntArray
from ..kernels.triangles import doubled_areas_of_frames, signed_areas

__all__ = ["BoundaryGuard", "GeodesicField"]


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
    (the same expression as :func:`meshopt_toolkit.kernels.boundary.boundary_self_intersections`),
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
        from ..kernels.distance import boundary_pairs, segment_distance

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
            if not doubled_areas_of_frames(check, self._tri_t).min() > 0.0:
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
