"""What :func:`~.checks.check_mesh` does with a mesh that is not clean: view a
3D mesh on any plane as planar, orient each component, and sort the remaining problems
into real non-manifold ones and those that only keep it from being admissible."""

from __future__ import annotations

import logging

import numpy as np

from ..errors import InvalidMeshError
from ..orientation import coincident_vertices, n_components, orient_components
from .core import PlanarMesh, TriangleMesh
from .topology import _fans_per_vertex

logger = logging.getLogger(__name__)


def planar_view(mesh: TriangleMesh) -> tuple[PlanarMesh | None, str]:
    """``(PlanarMesh, "")`` for a mesh whose points lie on one plane, else ``(None, why)``.

    A 3D mesh on a plane other than z = 0 becomes a :class:`~meshopt_toolkit.mesh.PlanarMesh`
    in the plane's coordinates with ``embedding`` (a :class:`PlaneEmbedding`) set, which
    :func:`meshopt_toolkit.io.save` uses to write the points back in 3D.
    """
    try:
        return mesh.as_planar(), ""
    except InvalidMeshError as exc:
        why = str(exc)
        return None, why[len(f"{mesh.source}: "):] if mesh.source and why.startswith(
            f"{mesh.source}: ") else why


def with_embedding_of(new: PlanarMesh, old: PlanarMesh) -> PlanarMesh:
    """``new`` with ``old``'s plane embedding (if any)."""
    emb = old.__dict__.get("embedding")
    if emb is not None:
        new.__dict__["embedding"] = emb
    return new


def unused_vertex_problem(mesh: TriangleMesh) -> str | None:
    """The first vertex no triangle uses, in words (None: every vertex is used)."""
    used = np.zeros(mesh.n_vertices, bool)
    used[mesh.triangles.ravel()] = True
    v = np.flatnonzero(~used)
    return f"vertex {v[0]} is not used by any triangle ({v.size} unused)" if v.size else None


def repeated_vertex_problem(mesh: TriangleMesh) -> str | None:
    """The first triangle that repeats a vertex, in words (None: there is none)."""
    tri = mesh.triangles
    bad = np.flatnonzero((tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2])
                         | (tri[:, 0] == tri[:, 2]))
    return f"triangle {bad[0]} {tri[bad[0]].tolist()} repeats a vertex" if bad.size else None


def shared_edge_problem(mesh: TriangleMesh) -> str | None:
    """The first edge in three or more triangles, in words (None: the mesh is
    edge-manifold)."""
    counts = mesh.edge_triangle_counts
    over = np.flatnonzero(counts > 2)
    if not over.size:
        return None
    e = mesh.edges[over[0]]
    return (f"edge ({e[0]}, {e[1]}) is shared by {counts[over[0]]} triangles "
            "(not edge-manifold)")


def diagnose(pm: PlanarMesh) -> tuple[PlanarMesh, int, list[str], list[str]]:
    """Topology of a planar mesh that is not clean: orient it, then sort its problems.

    Returns
    -------
    mesh : PlanarMesh
        Each component oriented counter-clockwise (the input if nothing was flipped).
    n_flipped : int
    hard : list of str
        Real non-manifold problems: a triangle repeating a vertex, an edge in three or
        more triangles, a non-orientable component, a bow-tie vertex.
    soft : list of str
        Problems of a manifold mesh that still keep it from being admissible:
        coincident vertices, unused vertices, several pieces.
    """
    tri = pm.triangles
    n = pm.n_vertices
    hard: list[str] = []
    soft: list[str] = []
    same = coincident_vertices(pm.points, tri.ravel())
    if same.size:
        soft.append(f"{same.size} coincident vertices (vertex {same[0]} and others share "
                    "a position; merge them with --merge-tolerance)")
    soft += filter(None, [unused_vertex_problem(pm)])
    hard += filter(None, [repeated_vertex_problem(pm)])
    if hard:
        return pm, 0, hard, soft
    hard += filter(None, [shared_edge_problem(pm)])
    oriented, n_flipped, orientable = orient_components(tri, n, pm.points)
    if n_flipped:
        pm = with_embedding_of(PlanarMesh(pm.points, oriented, **pm._tag_kwargs()), pm)
        logger.info("%s: reoriented %d triangles", pm.source or "mesh", n_flipped)
    if not orientable:
        hard.append("mesh is not orientable (a component is a Möbius strip)")
    pieces = n_components(pm.triangles, n)
    if pieces > 1:
        soft.append(f"mesh has {pieces} pieces not connected through edges")
    if not hard:
        fans = _fans_per_vertex(pm)
        bow = np.flatnonzero(fans > 1)
        if bow.size:
            hard.append(f"vertex {bow[0]} is a bow-tie: its triangles form "
                        f"{fans[bow[0]]} separate fans")
    return pm, n_flipped, hard, soft
