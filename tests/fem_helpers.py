"""Shared by the tests of the simplex finite elements (tests/fem/test_fem_tets.py,
test_elasticity_objective.py, test_stokes.py): unit-box meshes from scikit-fem,
positively oriented, optionally jittered inside."""

from __future__ import annotations

import numpy as np

from meshopt_toolkit.kernels.tetrahedra import signed_volumes
from meshopt_toolkit.kernels.triangles import signed_areas


def box_mesh(d: int, n: int, jitter: float = 0.0, seed: int = 0, lengths=None):
    """Points ``(N, d)``, positive simplices and the boundary vertices of ``[0, L]^d``
    (``L`` = ``lengths``, default 1) with ``n`` intervals per side (scikit-fem's
    ``init_tensor``); interior nodes moved by ``jitter · h`` at random."""
    import skfem

    lengths = np.ones(d) if lengths is None else np.asarray(lengths, dtype=float)
    axes = [np.linspace(0.0, L, n + 1) for L in lengths]
    m = (skfem.MeshTri if d == 2 else skfem.MeshTet).init_tensor(*axes)
    P, T = m.p.T.copy(), m.t.T.copy()
    neg = (signed_areas(P, T) if d == 2 else signed_volumes(P, T)) < 0
    T[neg, :2] = T[neg, 1::-1]
    boundary = np.asarray(m.boundary_nodes())
    if jitter:
        inner = np.ones(len(P), bool)
        inner[boundary] = False
        rng = np.random.default_rng(seed)
        P[inner] += jitter / n * rng.uniform(-1, 1, (inner.sum(), d)) * lengths
    return P, T, boundary


def random_direction(P: np.ndarray, seed: int = 1) -> np.ndarray:
    """A random displacement of every node, scaled to the mesh size."""
    return np.random.default_rng(seed).standard_normal(P.shape) / np.sqrt(len(P))
