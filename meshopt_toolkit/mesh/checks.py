"""The planar-manifold checks and admissibility of SPEC §1.

:func:`check_mesh` reports (a :class:`MeshReport`), :func:`require_admissible` enforces.
A clean mesh is recognised by :func:`~.topology._clean_manifold`; only a mesh with a
problem pays for the edge list and the description of its first problem
(:func:`_manifold_problems`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from .._lazy import lazy_module
from ..errors import InvalidMeshError, NotAdmissibleError
from ..kernels.admissibility import BoundaryCheck, area_message, area_signs, non_finite_problem
from .core import PlanarMesh, TriangleMesh
from .diagnosis import (diagnose, planar_view, repeated_vertex_problem, shared_edge_problem,
                        unused_vertex_problem, with_embedding_of)
from .topology import _boundary_edges_of, _fans_per_vertex, _frozen

sp = lazy_module("scipy.sparse")
_csgraph = lazy_module("scipy.sparse.csgraph")

logger = logging.getLogger(__name__)

__all__ = ["MeshReport", "check_mesh", "require_admissible"]


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
        ``manifold``, every signed area > 0, no boundary self-intersection and boundary
        loops nested as the boundary of an embedded region (no point covered twice); all
        judged exactly and at any scale (:mod:`meshopt_toolkit.kernels.admissibility`).
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


def _manifold_problems(mesh: TriangleMesh) -> list[str]:
    problems = list(filter(None, [unused_vertex_problem(mesh)]))
    for first_problem in (repeated_vertex_problem, shared_edge_problem):
        problem = first_problem(mesh)
        if problem:  # the checks below need a mesh without it
            return problems + [problem]
    tri = mesh.triangles
    counts = mesh.edge_triangle_counts
    # consistent orientation: an interior edge appears once in each direction
    directed = np.stack([np.roll(tri, -1, axis=1), np.roll(tri, -2, axis=1)], axis=-1).reshape(-1, 2)
    forward = directed[:, 0] < directed[:, 1]
    te = mesh.triangle_edges.ravel()
    fwd_count = np.bincount(te, weights=forward, minlength=len(counts))
    bad = np.flatnonzero((counts == 2) & (fwd_count != 1))
    if bad.size:
        e = mesh.edges[bad[0]]
        problems.append(
            f"triangles sharing edge ({e[0]}, {e[1]}) have inconsistent orientation"
        )
    # 2-path connectivity: components of the graph "triangles sharing an edge", each
    # interior edge entered once (connected_components symmetrizes it)
    c = mesh._edge_corners
    c = c[c[:, 1] >= 0] // 3
    nt = len(tri)
    shared = sp.coo_matrix((np.ones(len(c), dtype=bool), (c[:, 0], c[:, 1])), shape=(nt, nt))
    ncomp, _ = _csgraph.connected_components(shared, directed=False)
    if ncomp > 1:
        problems.append(f"mesh has {ncomp} pieces not connected through edges")
    # bow-ties: the triangles around each vertex must form one fan
    if not bad.size:
        fans = _fans_per_vertex(mesh)
        bow = np.flatnonzero(fans > 1)
        if bow.size:
            problems.append(
                f"vertex {bow[0]} is a bow-tie: its triangles form {fans[bow[0]]} separate fans"
            )
    return problems




def check_mesh(mesh: TriangleMesh, *, positive_areas: bool = False) -> MeshReport:
    """Run every check of SPEC §1 and report (never raises for a readable mesh).

    A planar-manifold mesh whose triangles are all clockwise is re-oriented to CCW; the
    report says so and carries the re-oriented mesh. ``positive_areas=True`` says the
    caller's rounded areas are all > 0 (e.g. from a quality summary): no re-orientation
    is considered; the exact signs are judged anyway (a rounded area may have the wrong
    sign).

    A clean mesh is recognised by :func:`_clean_manifold`; only a mesh with a problem pays
    for the edge list and the description of the problem (:func:`_manifold_problems`).
    """
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
    # exact signs, judged at unit scale (scale-free: no overflow or underflow at 1e±300)
    finite = bool(np.isfinite(pm.points).all())
    area, sign, exponent = (area_signs(pm.points, pm._triangle_columns) if finite
                            else (None, None, 0))
    if (not positive_areas and area is not None and area.sum() < 0
            and corners is not None):
        pm = with_embedding_of(pm.flipped(), pm)
        area, sign = -area, (None if sign is None else -sign)
        reoriented = True
        n_flipped = pm.n_triangles
        if corners is not None:
            # corner 3k + l of the flipped mesh is corner 3k + 2 - l of the original
            flip = np.sort(corners - 2 * (corners % 3) + 2)
            pm.__dict__["boundary_edges"] = _frozen(_boundary_edges_of(pm.triangles, flip))
        logger.info("%s: re-oriented from clockwise to counter-clockwise", pm.source or "mesh")
    problems = list(soft)
    reoriented = reoriented or n_flipped > 0
    if not finite:
        problems.append(non_finite_problem(pm.points))
    else:
        # the loops' nesting rule presumes positive triangles: judged only then
        message = area_message(area, sign, exponent, pm._triangle_columns)
        if message:
            problems.append(message)
        check = BoundaryCheck(pm.boundary_edges, pm.boundary_vertices)
        if message := check.test(pm.points, nesting=message is None):
            problems.append(message)
    return MeshReport(True, True, not problems, reoriented, problems, pm, n_flipped)


def require_admissible(mesh: TriangleMesh, what: str = "this operation") -> PlanarMesh:
    """Return the (CCW-oriented) planar mesh, or raise a clear error naming the problem.

    Raises
    ------
    InvalidMeshError
        Not planar or not a planar manifold.
    NotAdmissibleError
        Planar manifold but with an inverted/zero-area triangle, a boundary crossing, or
        a boundary loop of the wrong orientation for its nesting (a double cover).
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
