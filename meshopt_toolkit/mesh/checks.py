"""The checks of SPEC §1: :func:`check_mesh` (a :class:`MeshReport`), boundary
self-intersections, and :func:`require_admissible`."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError, NotAdmissibleError
from .core import PlanarMesh, TriangleMesh, _frozen
from .topology import _boundary_edges_of

logger = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------------
# checks
# ---------------------------------------------------------------------------------------


@dataclass
class MeshReport:
    """Outcome of :func:`check_mesh`.

    Attributes
    ----------
    planar : bool
        2D points (or z ≡ 0).
    manifold : bool
        Every planar-manifold condition of SPEC §1 holds (planarity included).
    admissible : bool
        ``manifold`` and every signed area > 0 and no boundary self-intersection.
    reoriented : bool
        Some triangles were flipped (each component is oriented by propagation across its
        edges, then counter-clockwise); :attr:`mesh` is the oriented version.
    problems : list of str
        Human-readable reasons, each naming a vertex/triangle/edge.
    mesh : TriangleMesh
        The checked mesh (re-oriented to CCW when ``reoriented``; in plane coordinates,
        with ``embedding`` set, when the input lies on a plane other than z = 0).
    n_reoriented : int
        Number of triangles flipped.
    """

    planar: bool
    manifold: bool
    admissible: bool
    reoriented: bool = False
    problems: list[str] = field(default_factory=list)
    mesh: TriangleMesh | None = None
    n_reoriented: int = 0


#: at most this many boundary edges are intersected pairwise (no scipy import)
_NUMPY_PAIRS = 600


def boundary_self_intersections(points: FloatArray, boundary_edges: IntArray) -> IntArray:
    """Pairs of non-adjacent boundary edges that intersect, ``(K, 2)`` indices.

    A broad phase with a k-d tree on edge midpoints (two segments can only meet when their
    midpoints are closer than the longest edge) followed by exact orientation tests.
    """
    if len(boundary_edges) < 3:
        return np.zeros((0, 2), np.int64)
    a = points[boundary_edges[:, 0]]
    b = points[boundary_edges[:, 1]]
    if len(boundary_edges) > _NUMPY_PAIRS:
        from scipy.spatial import cKDTree
    mid = 0.5 * (a + b)
    reach = float(np.linalg.norm(b - a, axis=1).max())
    if len(boundary_edges) <= _NUMPY_PAIRS:  # the same pairs as the k-d tree, no scipy
        pairs = np.stack(np.triu_indices(len(boundary_edges), 1), axis=1)
        gap = np.linalg.norm(mid[pairs[:, 0]] - mid[pairs[:, 1]], axis=1)
        pairs = pairs[gap <= reach * (1 + 1e-9)]
    else:
        pairs = cKDTree(mid).query_pairs(reach * (1 + 1e-9), output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), np.int64)
    i, j = pairs[:, 0], pairs[:, 1]
    e = boundary_edges
    share = (
        (e[i, 0] == e[j, 0]) | (e[i, 0] == e[j, 1]) | (e[i, 1] == e[j, 0]) | (e[i, 1] == e[j, 1])
    )
    i, j = i[~share], j[~share]

    def orient(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    d1 = orient(a[i], b[i], a[j])
    d2 = orient(a[i], b[i], b[j])
    d3 = orient(a[j], b[j], a[i])
    d4 = orient(a[j], b[j], b[i])
    hit = (d1 * d2 <= 0) & (d3 * d4 <= 0)
    # collinear but disjoint segments satisfy the sign test; exclude them by projection
    col = hit & (d1 == 0) & (d2 == 0)
    if col.any():
        k = np.flatnonzero(col)
        dvec = b[i[k]] - a[i[k]]
        t0 = np.einsum("kd,kd->k", a[j[k]] - a[i[k]], dvec)
        t1 = np.einsum("kd,kd->k", b[j[k]] - a[i[k]], dvec)
        L = np.einsum("kd,kd->k", dvec, dvec)
        overlap = (np.maximum(t0, t1) >= 0) & (np.minimum(t0, t1) <= L)
        hit[k] = overlap
    return np.stack([i[hit], j[hit]], 1)


def check_mesh(mesh: TriangleMesh) -> MeshReport:
    """Run every check of SPEC §1 and report (never raises for a readable mesh).

    A planar-manifold mesh whose triangles are all clockwise is re-oriented to CCW; the
    report says so and carries the re-oriented mesh.
    """
    return _check_mesh(mesh)


def _check_mesh(mesh: TriangleMesh, positive_areas: bool = False) -> MeshReport:
    """:func:`check_mesh`; ``positive_areas=True`` is the caller's promise that every
    signed area of ``mesh`` is > 0 (e.g. from a quality summary), which skips that pass.

    A clean mesh is recognised by :func:`_clean_manifold`; only a mesh with a problem pays
    for the edge list and the description of the problem (:func:`_manifold_problems`).
    """
    from ..orientation import diagnose, planar_view, with_embedding_of  # issue 12 hooks

    pm, why = planar_view(mesh)
    if pm is None:
        return MeshReport(False, False, False, problems=[why], mesh=mesh)
    corners = pm._clean_corners
    n_flipped, soft = 0, []
    if corners is None:
        pm, n_flipped, hard, soft = diagnose(pm)
        if hard:
            return MeshReport(True, False, False, n_flipped > 0, hard + soft, pm, n_flipped)
        corners = pm._clean_corners
    if corners is not None and "boundary_edges" not in pm.__dict__:
        pm.__dict__["boundary_edges"] = _frozen(_boundary_edges_of(pm.triangles, corners))
    reoriented = False
    area = None if positive_areas else pm.signed_areas()
    if area is not None and area.sum() < 0 and corners is not None:
        pm = with_embedding_of(pm.flipped(), pm)
        area = -area
        reoriented = True
        n_flipped = pm.n_triangles
        if corners is not None:
            # corner 3k + l of the flipped mesh is corner 3k + 2 - l of the original
            flip = np.sort(corners - 2 * (corners % 3) + 2)
            pm.__dict__["boundary_edges"] = _frozen(_boundary_edges_of(pm.triangles, flip))
        logger.info("%s: re-oriented from clockwise to counter-clockwise", pm.source or "mesh")
    problems = list(soft)
    reoriented = reoriented or n_flipped > 0
    nonpos = np.flatnonzero(area <= 0) if area is not None else ()
    if len(nonpos):
        k = nonpos[0]
        kind = "zero-area" if area[k] == 0 else "inverted"
        problems.append(
            f"triangle {k} {pm.triangles[k].tolist()} is {kind} (signed area {area[k]:.3g})"
            + (f"; {len(nonpos)} non-positive triangles" if len(nonpos) > 1 else "")
        )
    hits = boundary_self_intersections(pm.points, pm.boundary_edges)
    if len(hits):
        e1, e2 = pm.boundary_edges[hits[0, 0]], pm.boundary_edges[hits[0, 1]]
        problems.append(
            f"boundary self-intersects: edges ({e1[0]}, {e1[1]}) and ({e2[0]}, {e2[1]}) cross"
        )
    return MeshReport(True, True, not problems, reoriented, problems, pm, n_flipped)


def require_admissible(mesh: TriangleMesh, what: str = "this operation") -> PlanarMesh:
    """Return the (CCW-oriented) planar mesh, or raise a clear error naming the problem.

    Raises
    ------
    InvalidMeshError
        Not planar or not a planar manifold.
    NotAdmissibleError
        Planar manifold but with an inverted/zero-area triangle or boundary crossing.
    """
    report = check_mesh(mesh)
    where = f"{mesh.source}: " if mesh.source else ""
    if not report.manifold:
        raise InvalidMeshError(f"{where}{what} needs a planar manifold mesh: {report.problems[0]}")
    if not report.admissible:
        raise NotAdmissibleError(f"{where}{what} needs an admissible mesh: {report.problems[0]}")
    if report.reoriented:
        logger.warning("%sreoriented %d triangles", where, report.n_reoriented)
    return report.mesh  # type: ignore[return-value]
