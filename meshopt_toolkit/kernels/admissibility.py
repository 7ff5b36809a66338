"""Admissibility of node positions (SPEC §1): every signed area > 0, every coordinate
finite, and a boundary that neither folds onto, touches nor crosses itself.

The one owner of these tests and of their messages: the penalties, the geodesic
integrators' boundary guard, the Poisson objective and ``mesh.checks`` (a mesh read from
a file) all use them.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np

from .._typing import FloatArray, IntArray
from .boundary import boundary_self_intersections
from .triangles import areas_from_edges, edges_xy

__all__ = ["BoundaryCheck", "area_message", "area_problem"]


def area_problem(Q: FloatArray, tri_t: IntArray) -> str | None:
    """A message naming a non-finite vertex or a non-positive triangle, or None.

    ``Q`` is ``(N, 2)``, ``tri_t`` the triangles as a ``(3, T)`` array.
    """
    if not np.isfinite(Q).all():
        v = int(np.flatnonzero(~np.isfinite(Q).all(axis=1))[0])
        return f"vertex {v} has a non-finite coordinate"
    with np.errstate(all="ignore"):
        area = areas_from_edges(*edges_xy(Q[:, 0], Q[:, 1], tri_t))
    return area_message(area, tri_t)


def area_message(area: FloatArray, tri_t: IntArray) -> str | None:
    """A message naming the first non-positive triangle of signed areas ``area`` ``(T,)``
    (and how many there are), or None; ``tri_t`` the triangles as a ``(3, T)`` array."""
    bad = np.flatnonzero(~(area > 0))
    if not bad.size:
        return None
    k = int(bad[0])
    kind = "zero-area" if area[k] == 0 else "inverted"
    more = f" ({bad.size} non-positive triangles)" if bad.size > 1 else ""
    return f"triangle {k} {tri_t[:, k].tolist()} is {kind} (signed area {area[k]:.3g}){more}"


class BoundaryCheck:
    """The exact test that a boundary is simple, remembering configurations found simple.

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
    and Hessian products at each frame; half its penalty time was this test) pay for it
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
        self._simple_boundaries: OrderedDict[bytes, None] = OrderedDict()

    def problem(self, Q: FloatArray, test=None) -> str | None:
        """A message naming boundary edges that fold onto, touch or cross each other.

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

    def test(self, Q: FloatArray) -> str | None:
        """:meth:`problem` without the cache."""
        a, b, c = self._fold
        if len(a):
            u = Q[a] - Q[b]
            v = Q[c] - Q[b]
            cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
            dot = np.einsum("kd,kd->k", u, v)
            folded = np.flatnonzero((cross == 0) & (dot > 0))
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
        return None
