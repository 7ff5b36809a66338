"""Admissibility of node positions (SPEC §1): every coordinate finite, every signed area
> 0, a boundary that neither folds onto, touches nor crosses itself, and boundary loops
that bound an embedded region (each loop counter-clockwise at even nesting depth,
clockwise at odd depth: :func:`loop_message`). Every sign is exact (:mod:`.predicates`).

The one owner of these tests and of their messages: the penalties, the geodesic
integrators' boundary guard, the Poisson objective and ``mesh.checks`` (a mesh read from
a file) all use them.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np

from .._typing import FloatArray, IntArray
from .boundary import BoundaryLoops, boundary_self_intersections, loop_orientations
from .predicates import dot_sign_xy, exactly_scaled, orient2d_xy, triangle_orientations

__all__ = ["BoundaryCheck", "area_message", "area_problem", "area_signs", "loop_message",
           "first_non_finite_row", "non_finite_problem", "target_loop_problem"]


#: a boundary loop's orientation in words, by its sign
_RUNS = {1: "counter-clockwise", -1: "clockwise", 0: "nowhere"}


def _first_true(mask: np.ndarray) -> int | None:
    """The first index where the 1D boolean ``mask`` holds, or None."""
    bad = np.flatnonzero(mask)
    return int(bad[0]) if bad.size else None


def first_non_finite_row(points: FloatArray) -> int | None:
    """The first row of ``points`` ``(N, d)`` with a non-finite entry, or None."""
    return _first_true(~np.isfinite(points).all(axis=1))


def non_finite_problem(points: FloatArray, *, show: bool = False) -> str | None:
    """The first vertex with a non-finite coordinate, in words (with its coordinates
    where ``show``), or None when every coordinate is finite. ``points`` is ``(N, d)``."""
    points = np.asarray(points)
    v = first_non_finite_row(points)
    if v is None:
        return None
    return f"vertex {v} has a non-finite coordinate" + (f" {points[v].tolist()}" if show else "")


def area_problem(Q: FloatArray, tri_t: IntArray) -> str | None:
    """A message naming a non-finite vertex or a non-positive triangle, or None.

    ``Q`` is ``(N, 2)``, ``tri_t`` the triangles as a ``(3, T)`` array.
    """
    if not np.isfinite(Q).all():
        return non_finite_problem(Q)
    return area_message(*area_signs(Q, tri_t), tri_t)


def area_signs(Q: FloatArray, tri_t: IntArray) -> tuple[FloatArray, np.ndarray | None, int]:
    """``(area, sign, k)``: the signed areas ``(T,)`` of ``Q / 2**k`` in floating point,
    their exact signs (int8; None when all are positive) and ``k``: ``Q`` at an extreme
    size is scaled by the power of two that puts it near unit size where that is exact
    (so neither the areas nor the filter overflow or underflow at 1e±300); the areas at
    ``Q``'s scale are ``area * 4**k``.

    ``Q`` must be finite.
    """
    S, k = exactly_scaled(Q, extreme_only=True)
    det, sign = triangle_orientations(S[:, 0], S[:, 1], tri_t, lazy=True)
    det *= 0.5
    return det, sign, k


def area_message(area: FloatArray, sign: np.ndarray | None, exponent: int,
                 tri_t: IntArray) -> str | None:
    """A message naming the first non-positive triangle (and how many there are), or None.

    ``area`` are signed areas ``(T,)`` in units of ``4**exponent``, ``sign`` their exact
    signs (:func:`area_signs`; None: all positive), ``tri_t`` the triangles as a
    ``(3, T)`` array.
    """
    if sign is None:
        return None
    bad = np.flatnonzero(sign <= 0)
    if not bad.size:
        return None
    k = int(bad[0])
    kind = "zero-area" if sign[k] == 0 else "inverted"
    more = f" ({bad.size} non-positive triangles)" if bad.size > 1 else ""
    with np.errstate(all="ignore"):
        value = float(np.ldexp(area[k], 2 * exponent))
    return f"triangle {k} {tri_t[:, k].tolist()} is {kind} (signed area {value:.3g}){more}"


class BoundaryCheck:
    """The exact test that a boundary is simple and its loops nest as the boundary of an
    embedded region (:func:`loop_message`), remembering configurations that pass.

    Parameters
    ----------
    boundary_edges : (E, 2) int array
        Directed boundary edges (interior on the left).
    boundary_vertices : (V,) int array
        Sorted boundary vertices (the positions the cache key is made of).
    cache_size : int
        How many simple configurations to remember.

    The test depends on the boundary positions only; the 128-bit digests of the last
    ``cache_size`` boundaries found simple are remembered, so iterative methods that come
    back to the same configurations (the morph's path energy evaluates value, gradient
    and Hessian products at each frame) pay for it
    once per configuration.
    """

    def __init__(self, boundary_edges: IntArray, boundary_vertices: IntArray,
                 cache_size: int = 64) -> None:
        self._boundary_edges = boundary_edges
        self._boundary_vertices = boundary_vertices
        self.cache_size = cache_size
        # consecutive boundary edges (a, b), (b, c) for the fold test
        be = boundary_edges
        order = np.argsort(be[:, 0], kind="stable")
        pos = np.searchsorted(be[order, 0], be[:, 1])
        pos = np.clip(pos, 0, max(len(be) - 1, 0))
        nxt = order[pos] if len(be) else pos
        ok = be[nxt, 0] == be[:, 1] if len(be) else np.zeros(0, bool)
        self._fold = (be[ok, 0], be[ok, 1], be[nxt[ok], 1])
        # their positions among the sorted boundary vertices
        self._fold_at = [np.searchsorted(boundary_vertices, x) for x in self._fold]
        self._simple_boundaries: OrderedDict[bytes, None] = OrderedDict()
        self._loops: BoundaryLoops | None = None

    def problem(self, Q: FloatArray, test=None) -> str | None:
        """A message naming boundary edges that fold onto, touch or cross each other, or a
        loop of the wrong orientation for its nesting depth.

        ``test`` replaces :meth:`test` for a configuration not in the cache."""
        key = hashlib.blake2b(Q[self._boundary_vertices].tobytes(), digest_size=16).digest()
        if key in self._simple_boundaries:
            try:
                self._simple_boundaries.move_to_end(key)
            except KeyError:  # evicted meanwhile by another thread: still simple
                pass
            return None
        problem = (test or self.test)(Q)
        if problem is None:
            self._simple_boundaries[key] = None
            if len(self._simple_boundaries) > self.cache_size:
                self._simple_boundaries.popitem(last=False)
        return problem

    def test(self, Q: FloatArray, nesting: bool = True) -> str | None:
        """:meth:`problem` without the cache; ``nesting=False`` leaves out the loops'
        nesting rule (which presumes positive triangles)."""
        a, b, c = self._fold
        if len(a):
            S, _ = exactly_scaled(Q[self._boundary_vertices], extreme_only=True)
            ia, ib, ic = self._fold_at
            args = (S[ia, 0], S[ia, 1], S[ib, 0], S[ib, 1], S[ic, 0], S[ic, 1])
            straight = np.flatnonzero(orient2d_xy(*args) == 0)
            folded = straight[dot_sign_xy(*(x[straight] for x in args)) > 0]
            if folded.size:
                i = folded[0]
                return (
                    f"boundary folds onto itself at vertex {b[i]}: edges ({a[i]}, {b[i]}) and "
                    f"({b[i]}, {c[i]}) overlap"
                )
        hits = boundary_self_intersections(Q, self._boundary_edges)
        if len(hits):
            e1 = self._boundary_edges[hits[0, 0]]
            e2 = self._boundary_edges[hits[0, 1]]
            return (
                f"boundary self-intersects: edges ({e1[0]}, {e1[1]}) and "
                f"({e2[0]}, {e2[1]}) touch or cross"
            )
        if not nesting:
            return None
        if self._loops is None:
            self._loops = BoundaryLoops(self._boundary_edges)
        return loop_message(Q, self._boundary_edges, self._loops)


def loop_message(Q: FloatArray, boundary_edges: IntArray,
                 loops: BoundaryLoops | IntArray | None = None) -> str | None:
    """A message naming the first boundary loop whose orientation breaks the nesting rule,
    or None: a simple boundary bounds an embedded mesh iff every loop runs
    counter-clockwise at even nesting depth and clockwise at odd depth.

    Parameters
    ----------
    Q : (N, 2) positions (finite; the boundary simple, the signed areas > 0)
    boundary_edges : (E, 2) directed boundary edges (interior on the left)
    loops : the prepared :class:`~.boundary.BoundaryLoops`, or their ``(E,)`` labels
        (:func:`~.boundary.boundary_loops`); computed when None

    Notes
    -----
    Why the rule is exact. Let every triangle be positive and the boundary simple. For a
    point ``y`` on no edge, a positive triangle's boundary winds once around ``y`` if ``y``
    is inside it and not at all otherwise, and the interior edges cancel in the sum of the
    triangles' boundaries (each is traversed once in each direction), so

        #{triangles containing y} = Σ_t wind(∂t, y) = Σ_loops wind(loop, y).

    The mesh map is injective iff this count is 0 or 1 everywhere. (⇒ clear. ⇐: two
    overlapping triangles, or a vertex mapped into another triangle's closure, or a branch
    vertex, make the count ≥ 2 on an open set, since positive triangles cover a
    neighbourhood of every interior point and the boundary meets itself nowhere.) The loops
    are disjoint Jordan curves, so those enclosing ``y`` form a chain ``L_0 ⊃ … ⊃ L_k`` and
    ``L_i`` has nesting depth ``i``; ``wind(L, y) = s_L`` (±1, the loop's orientation)
    inside ``L``. If ``s_L = (−1)^depth(L)`` the count is ``Σ_{i≤k} (−1)^i ∈ {0, 1}``.
    Conversely, by induction on the depth: just outside a loop ``L`` of depth ``d`` the
    count is ``Σ_{i<d} (−1)^i`` (0 for even ``d``, 1 for odd), just inside it is that plus
    ``s_L``, and staying in {0, 1} forces ``s_L = (−1)^d``. (The sum of the signed triangle
    areas equals the sum of the loops' signed areas for any mesh: comparing those totals
    decides nothing; the enclosed area is ``Σ_L (−1)^depth(L) |area(L)|``.)
    """
    if not isinstance(loops, BoundaryLoops):
        loops = BoundaryLoops(boundary_edges, loops)
    if not loops.n_loops:
        return None
    sign, depth, vertex = loops.nesting(Q)
    want = np.where(depth % 2 == 0, 1, -1)
    bad = np.flatnonzero(sign != want)
    if not bad.size:
        return None
    i = int(bad[0])
    v = int(vertex[i])
    d = int(depth[i])
    where = "an outer boundary" if d == 0 else (
        f"a hole (inside {d} other loop{'s' if d > 1 else ''})" if d % 2 else
        f"an island (inside {d} other loops)")
    more = f" ({bad.size} loops break the rule)" if bad.size > 1 else ""
    return (f"boundary loop {i} (through vertex {v}) is {where} but runs "
            f"{_RUNS[int(sign[i])]} (it must run {_RUNS[int(want[i])]}): the mesh covers part "
            f"of the plane twice, no embedding{more}")


def target_loop_problem(P0: FloatArray, P1: FloatArray, boundary_edges: IntArray,
                        handles: IntArray) -> str | None:
    """Why no motion from ``P0`` can end at ``P1`` on the loops that are all ``handles``.

    A motion through admissible meshes keeps every boundary loop a simple polygon (the
    loops stay disjoint) and so keeps its orientation (a continuous ±1). For the loops
    whose vertices are all handles, ``P1`` fixes them: they must neither fold, touch nor
    cross (themselves or each other) and each must keep its orientation at ``P0``
    (mirroring a hole reverses it). A message naming the first loop that fails, or None.
    """
    be = np.asarray(boundary_edges)
    if not len(be):
        return None
    loops = BoundaryLoops(be).loops
    fixed = np.zeros(max(len(P0), int(be.max()) + 1), bool)
    fixed[np.asarray(handles)] = True
    free_edges = np.bincount(loops, weights=~fixed[be[:, 0]], minlength=int(loops.max()) + 1)
    full = np.flatnonzero(free_edges == 0)
    if not full.size:
        return None
    sub = np.isin(loops, full)
    edges = be[sub]
    check = BoundaryCheck(edges, np.unique(edges))
    if message := check.test(P1, nesting=False):
        return f"make the boundary fold or cross itself: {message}"
    labels = np.searchsorted(full, loops[sub])
    before, vertex = loop_orientations(P0, edges, labels)
    after, _ = loop_orientations(P1, edges, labels)
    if (i := _first_true(before != after)) is None:
        return None
    return (f"reverse boundary loop {int(full[i])} (through vertex {int(vertex[i])}): it runs "
            f"{_RUNS[int(before[i])]} and would run {_RUNS[int(after[i])]}, which no motion "
            "without folds reaches (the result would cover part of the plane twice)")
