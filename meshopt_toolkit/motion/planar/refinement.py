"""Meshes made by uniform refinement: recognizing the coarser mesh, refining paths.

A pair made by :meth:`~meshopt_toolkit.mesh.PlanarMesh.refine` (every triangle split into
four at its edge midpoints, new vertices appended) can be morphed coarse-to-fine: the
coarser pair's path, refined by the same midpoint rule, is an admissible start for the
finer one (every child of a positive triangle is a half-size similar copy of it, and a
boundary split at its midpoints is the same polyline) on which the finer geodesic's
iterations are cheaper than from the as-rigid-as-possible interpolation (measured in
:data:`~.morph.COARSE_MIN_TRIANGLES`).
"""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray, IntArray
from ...mesh import PlanarMesh


def unrefined(points: FloatArray, triangles: IntArray) -> PlanarMesh | None:
    """The mesh whose :meth:`~meshopt_toolkit.mesh.PlanarMesh.refine` has exactly these
    triangles (its vertices: the first ``n`` of ``points``), or None.

    ``refine`` writes the four children of coarse triangle ``t = (a, b, c)`` as rows
    ``4t … 4t+3``: ``(a, m_ab, m_ca)``, ``(m_ab, b, m_bc)``, ``(m_ca, m_bc, c)``,
    ``(m_ab, m_bc, m_ca)``; the candidate read off that layout is accepted only if
    refining it reproduces ``triangles`` and the vertex count exactly.
    """
    tri = np.asarray(triangles)
    if len(tri) == 0 or len(tri) % 4:
        return None
    c0, c1, c2, c3 = tri[0::4], tri[1::4], tri[2::4], tri[3::4]
    if not (np.array_equal(c0[:, 1], c3[:, 0]) and np.array_equal(c1[:, 2], c3[:, 1])
            and np.array_equal(c2[:, 0], c3[:, 2])):
        return None
    coarse = np.stack([c0[:, 0], c1[:, 1], c2[:, 2]], axis=1)
    n = int(coarse.max()) + 1
    if n >= len(points) or not np.array_equal(np.unique(coarse), np.arange(n)):
        return None
    mesh = PlanarMesh(np.asarray(points, dtype=float)[:n], coarse)
    refined = mesh.refine()
    if refined.n_vertices != len(points) or not np.array_equal(refined.triangles, tri):
        return None
    return mesh


def refine_frames(frames: FloatArray, coarse: PlanarMesh) -> FloatArray:
    """Frames ``(F, n, 2)`` of ``coarse`` carried to its refinement ``(F, N, 2)``: the new
    vertices at the edge midpoints, in :meth:`~meshopt_toolkit.mesh.PlanarMesh.refine`'s
    order."""
    frames = np.asarray(frames, dtype=float)
    e = coarse.edges
    return np.concatenate([frames, 0.5 * (frames[:, e[:, 0]] + frames[:, e[:, 1]])], axis=1)
