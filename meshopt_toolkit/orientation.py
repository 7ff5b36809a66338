"""Consistent orientation, planes in 3D, coincident vertices: what meshes from FEM codes
need before the planar-manifold checks. Functions of point and index arrays;
what :func:`~meshopt_toolkit.mesh.check_mesh` does with them is in :mod:`.mesh.diagnosis`.

* :func:`orient_components`: orient each connected component (triangles sharing an edge)
  by propagation across its interior edges, then turn each planar component
  counter-clockwise (positive total area). Vectorized: the parity constraints of all
  edges are solved at once as connected components of a doubled graph.
* :func:`plane_of` / :class:`PlaneEmbedding`: points that all lie on one plane (any
  plane) are mapped to 2D by a rigid transform and back; axis-parallel planes exactly.
* :func:`coincident_vertices`: vertices sharing their position with another one.
* :func:`merge_vertices`: merge vertices closer than a tolerance.
* :func:`component_labels`: connected components in pure numpy (no scipy import).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._typing import FloatArray, IntArray
from .scaling import UnitScale, unit_scale

__all__ = [
    "PLANE_RTOL",
    "PlaneEmbedding",
    "coincident_vertices",
    "component_labels",
    "merge_vertices",
    "orient_components",
    "plane_embedding",
    "plane_of",
]

#: THE planarity tolerance of the package: points are on a plane when each is within this
#: fraction of their bounding-box diagonal from it (meshes, workpieces, MeshLab checks)
PLANE_RTOL = 1e-10
#: offsets from the plane below this many units in the last place of the largest
#: coordinate are rounding, whatever the mesh's size
ROUNDING_ULPS = 64
#: the former name of :data:`PLANE_RTOL`
PLANE_TOLERANCE = PLANE_RTOL


def orientation_labels(n_triangles: int, t1: IntArray, t2: IntArray,
                       same: np.ndarray) -> IntArray:
    """The parity constraints of shared edges as components of the doubled graph.

    Node ``k`` is triangle ``k`` as it is, node ``T + k`` triangle ``k`` flipped; the
    triangles ``t1[i]`` and ``t2[i]`` share an edge, run the same way in both where
    ``same[i]`` (then one of them must flip). Returns :func:`component_labels` of the
    ``2T`` nodes: a component is not orientable where ``k`` and ``T + k`` share a label.
    """
    nt = n_triangles
    a = np.concatenate([t1, t1 + nt])
    b = np.concatenate([np.where(same, t2 + nt, t2), np.where(same, t2, t2 + nt)])
    return component_labels(2 * nt, a, b)


def component_labels(n: int, a: IntArray, b: IntArray) -> IntArray:
    """Connected components of the graph with ``n`` nodes and edges ``(a[i], b[i])``.

    Returns the smallest node of each node's component, ``(n,)``. Min-label hooking of
    roots and full path compression: a few passes over the edge arrays.
    """
    label = np.arange(n, dtype=np.int64)
    a = np.asarray(a, np.int64)
    b = np.asarray(b, np.int64)
    while True:
        la, lb = label[a], label[b]
        differ = la != lb
        if not differ.any():
            return label
        la, lb = la[differ], lb[differ]
        m = np.minimum(la, lb)
        np.minimum.at(label, la, m)
        np.minimum.at(label, lb, m)
        while True:
            nxt = label[label]
            if np.array_equal(nxt, label):
                break
            label = nxt
        a, b = a[differ], b[differ]


def half_edge_pairs(triangles: IntArray,
                    n_vertices: int) -> tuple[IntArray, IntArray, np.ndarray]:
    """The half-edges paired across the edges in exactly two triangles.

    Half-edge ``h = l T + t`` is the edge opposite local vertex ``l`` of triangle ``t``,
    from local ``l+1`` to ``l+2`` (its triangle is ``h % T``). Returns ``(h1, h2, same)``,
    ``same`` where the two run the same way (their triangles disagree in orientation).
    """
    tri = np.asarray(triangles, np.int64)
    s = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0]])
    d = np.concatenate([tri[:, 2], tri[:, 0], tri[:, 1]])
    key = np.minimum(s, d) * np.int64(max(n_vertices, 1)) + np.maximum(s, d)
    order = np.argsort(key, kind="stable")
    k = key[order]
    eq = k[1:] == k[:-1]
    prev = np.concatenate([[False], eq[:-1]]) if len(eq) else eq
    nxt = np.concatenate([eq[1:], [False]]) if len(eq) else eq
    first = np.flatnonzero(eq & ~prev & ~nxt)  # groups of exactly two
    h1, h2 = order[first], order[first + 1]
    return h1, h2, s[h1] == s[h2]


def _edge_pairs(triangles: IntArray, n_vertices: int):
    """Interior edges shared by exactly two triangles: ``(t1, t2, same_direction)``."""
    h1, h2, same = half_edge_pairs(triangles, n_vertices)
    nt = len(triangles)
    return h1 % nt, h2 % nt, same


def orient_components(triangles: IntArray, n_vertices: int,
                      points: FloatArray | None = None) -> tuple[IntArray, int, bool]:
    """Orient triangles consistently within each edge-connected component.

    Parameters
    ----------
    triangles : (T, 3) int array
    n_vertices : int
    points : (N, 2) float array, optional
        Planar positions: each component is then turned so that its total signed area is
        positive (counter-clockwise). Without points the orientation of the majority of a
        component's triangles is kept.

    Returns
    -------
    triangles : (T, 3) int array
        Flipped triangles have their vertex order reversed.
    n_flipped : int
    orientable : bool
        False if some component cannot be oriented (a Möbius strip); its triangles are
        left as they are.
    """
    tri = np.asarray(triangles, np.int64)
    nt = len(tri)
    t1, t2, same = _edge_pairs(tri, n_vertices)
    label = orientation_labels(nt, t1, t2, same)
    keep, flip = label[:nt], label[nt:]
    bad = keep == flip
    flipped = (keep > flip) & ~bad
    comp = np.minimum(keep, flip)
    ids, comp = np.unique(comp, return_inverse=True)
    if points is not None:
        p = np.asarray(points, np.float64)
        e1 = p[tri[:, 1]] - p[tri[:, 0]]
        e2 = p[tri[:, 2]] - p[tri[:, 0]]
        area = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        area = np.where(flipped, -area, area)
        total = np.bincount(comp, weights=area, minlength=len(ids))
        turn = total < 0
    else:
        nflip = np.bincount(comp, weights=flipped, minlength=len(ids))
        turn = nflip > np.bincount(comp, minlength=len(ids)) / 2
    turn_t = turn[comp] & ~bad
    flipped ^= turn_t
    out = np.where(flipped[:, None], tri[:, ::-1], tri)
    return out, int(flipped.sum()), not bad.any()


def n_components(triangles: IntArray, n_vertices: int) -> int:
    """Number of edge-connected components of the triangles (numpy only)."""
    nt = len(triangles)
    t1, t2, _ = _edge_pairs(triangles, n_vertices)
    return int(len(np.unique(component_labels(nt, t1, t2))))


@dataclass(frozen=True)
class PlaneEmbedding:
    """A plane in 3D with an orthonormal frame: ``x3 = origin + x2 @ basis``.

    Attributes
    ----------
    origin : (3,) float array
    basis : (2, 3) float array
        Orthonormal rows ``e1, e2``; ``e1 × e2`` is the plane's normal.
    """

    origin: np.ndarray
    basis: np.ndarray

    def to_2d(self, points: FloatArray) -> FloatArray:
        """Plane coordinates ``(N, 2)`` of points ``(N, 3)`` (projection onto the plane)."""
        return (np.asarray(points, np.float64) - self.origin) @ self.basis.T

    def to_3d(self, points: FloatArray) -> FloatArray:
        """Points ``(N, 3)`` of plane coordinates ``(N, 2)``."""
        return self.origin + np.asarray(points, np.float64) @ self.basis


def plane_of(points: FloatArray, triangles: IntArray | None = None,
             tol: float = PLANE_RTOL) -> tuple[PlaneEmbedding | None, float]:
    """The plane of 3D ``points`` if they all lie on one, else None.

    A plane ``x_i = c`` is exact (its frame is a permutation of the axes and the 2D
    coordinates are the other two coordinates, unchanged). Otherwise the least-squares
    plane through the centroid is used and every point must be within ``tol`` times the
    bounding-box diagonal of it. The frame's normal is chosen along the triangles' total
    area vector when triangles are given (so a consistently oriented mesh stays CCW).

    Returns
    -------
    (embedding or None, largest distance to the plane relative to the diagonal)
    """
    if len(points) == 0:
        return None, 0.0
    # measured at unit size (an exact power of two): no square under- or overflows at 1e±300
    scale = unit_scale(points, columns=3) if np.isfinite(points).all() else UnitScale(0)
    user = np.asarray(points, np.float64)
    p = scale.down(user)
    lo, hi = p.min(axis=0), p.max(axis=0)
    diag = float(np.linalg.norm(hi - lo)) or 1.0
    normal_hint = None
    if triangles is not None and len(triangles):
        t = np.asarray(triangles)
        normal_hint = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]).sum(axis=0)
    flat = np.flatnonzero(hi == lo)
    if flat.size:
        axis = int(flat[-1])
        others = [i for i in range(3) if i != axis]
        basis = np.zeros((2, 3))
        basis[0, others[0]] = 1.0
        basis[1, others[1]] = 1.0
        normal = np.cross(basis[0], basis[1])
        if normal_hint is not None and normal_hint @ normal < 0:
            basis[1] *= -1.0
        origin = np.zeros(3)
        origin[axis] = user[0, axis]
        return PlaneEmbedding(origin, basis), 0.0
    centre = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - centre, full_matrices=False)
    normal = vt[2]
    offset = float(np.abs((p - centre) @ normal).max())
    dist = offset / diag
    # an offset within the rounding of the coordinates themselves (a small mesh far from
    # the origin) is no departure from the plane
    if offset > tol * diag + ROUNDING_ULPS * np.finfo(float).eps * float(np.abs(p).max()):
        return None, dist
    if normal_hint is not None and normal_hint @ normal < 0:
        normal = -normal
    e1 = vt[0] - (vt[0] @ normal) * normal
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    return PlaneEmbedding(scale.up(centre), np.stack([e1, e2])), dist


def plane_embedding(points: FloatArray, triangles: IntArray,
                    source: str | None = None) -> PlaneEmbedding:
    """The plane of a triangle mesh's points (:func:`plane_of` of the vertices used by
    ``triangles``, oriented by them; unused vertices must be on it too).

    Raises
    ------
    InvalidMeshError
        The points are not on one plane within :data:`PLANE_RTOL` (naming ``source``).
    """
    from .errors import InvalidMeshError

    p = np.asarray(points, np.float64)
    used = np.unique(triangles)
    every = len(used) == len(p)
    emb, dist = plane_of(p[used], triangles if every else None)
    where = f"{source}: " if source else ""
    if emb is None:
        raise InvalidMeshError(
            f"{where}not planar: the points are not on one plane (a point is {dist:.3g} × "
            f"the diameter away from the best-fitting plane; tolerance {PLANE_RTOL:g})")
    if not every:  # unused vertices must be on the plane too
        off = np.abs((p - emb.origin) @ np.cross(*emb.basis))
        if off.max() > PLANE_RTOL * (np.ptp(p, axis=0).max() or 1.0):
            raise InvalidMeshError(f"{where}not planar: an unused vertex is off the plane "
                                   "of the triangles")
    return emb


def coincident_vertices(points: FloatArray, used: IntArray | None = None) -> IntArray:
    """Indices of the vertices whose position equals another vertex's, sorted.

    Parameters
    ----------
    points : (N, d) float array
    used : int array, optional
        Only these vertices are compared (e.g. those of some triangle).
    """
    p = np.asarray(points, np.float64)
    idx = np.arange(len(p)) if used is None else np.unique(used)
    if len(idx) < 2:
        return np.zeros(0, np.int64)
    _, inverse, counts = np.unique(p[idx], axis=0, return_inverse=True, return_counts=True)
    return idx[counts[inverse.reshape(-1)] > 1]


def merge_groups(points: FloatArray, tol: float) -> IntArray:
    """Representative (smallest index) of each vertex after merging vertices closer than
    ``tol`` (transitively; ``tol = 0``: equal positions only), ``(N,)``."""
    p = np.asarray(points, np.float64)
    n = len(p)
    if n == 0:
        return np.zeros(0, np.int64)
    if tol <= 0:
        _, inverse = np.unique(p, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        first = np.full(inverse.max() + 1, n, np.int64)
        np.minimum.at(first, inverse, np.arange(n))
        return first[inverse]
    from scipy.spatial import cKDTree

    pairs = cKDTree(p).query_pairs(tol, output_type="ndarray")
    return component_labels(n, pairs[:, 0], pairs[:, 1])


def merge_vertices(points: FloatArray, cells: list[tuple[str, IntArray]], tol: float):
    """Merge vertices closer than ``tol``; the first of each group stays, in order.

    Returns
    -------
    keep : (M,) int array
        The kept vertices (old indices, increasing): new points are ``points[keep]``.
    cells : list of (type, array)
        The cells renumbered.
    n_merged : int
        Vertices removed.
    """
    rep = merge_groups(points, tol)
    keep = np.flatnonzero(rep == np.arange(len(rep)))
    new_index = np.full(len(rep), -1, np.int64)
    new_index[keep] = np.arange(len(keep))
    mapping = new_index[rep]
    out = [(t, mapping[np.asarray(c, np.int64)]) for t, c in cells]
    return keep, out, int(len(rep) - len(keep))
