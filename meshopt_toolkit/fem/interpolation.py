"""As-rigid-as-possible interpolation of two meshes with the same connectivity.

Alexa, Cohen-Or & Levin, *As-rigid-as-possible shape interpolation* (SIGGRAPH 2000), in
the least-squares (Poisson) form: each triangle's affine map ``A_t`` from the source to
the target is split by the polar decomposition ``A_t = R(θ_t) S_t`` (``S_t`` symmetric
positive definite), the rotation angle and the stretch are interpolated separately,

    J_t(s) = R(s θ_t) ((1 − s) I + s S_t),

and the positions at time ``s`` are the least-squares fit of the P1 deformation gradients
to ``J_t(s)`` (area-weighted), i.e. one Poisson problem per coordinate with the source's
stiffness matrix (factorized once for all times). Vertices that do not move (equal in
source and target up to round-off, ``STILL_TOLERANCE``, e.g. a clamped boundary) stay
put; if none, the vertex closest to the centroid follows the straight line. Frame 0 is
the source and frame 1 the target exactly.

The angles ``θ_t`` are unwrapped across triangle neighbours (a tree of the dual graph,
summed level by level), so a disc twisted by 225° is interpolated as a 225° twist and
not as a −135° one. The result is not guaranteed to be admissible (it usually is for
smooth deformations): :func:`meshopt_toolkit.riemannian.initial_path.initial_path` checks it and falls back
to a barrier-sliding flow.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components, shortest_path

from .._typing import FloatArray, IntArray
from ..kernels.cell_maps import scatter_corners
from .elasticity import p1_gradients
from .p1 import p1_stiffness
from ..solvers import factorize_spd

__all__ = ["arap_interpolation", "rotation_angles"]


def _edge_matrices(points: FloatArray, triangles: IntArray) -> FloatArray:
    """(T, 2, 2) matrices with columns ``q1 − q0`` and ``q2 − q0``."""
    p = points[triangles]
    return np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)


def _rotations(theta: FloatArray) -> FloatArray:
    """(T, 2, 2) rotation matrices ``R(θ_t)``."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], 1)


def _dual_graph(triangles: IntArray) -> sp.csr_matrix:
    """Triangle adjacency through shared edges, as a sparse (T, T) matrix."""
    T = len(triangles)
    e = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(T), 3)
    order = np.lexsort((e[:, 1], e[:, 0]))
    e, owner = e[order], owner[order]
    same = np.all(e[1:] == e[:-1], axis=1)
    a, b = owner[:-1][same], owner[1:][same]
    return sp.coo_matrix((np.ones(2 * len(a)), (np.r_[a, b], np.r_[b, a])), shape=(T, T)).tocsr()


def rotation_angles(
    Q0: FloatArray, Q1: FloatArray, triangles: IntArray
) -> tuple[FloatArray, FloatArray]:
    """Unwrapped rotation angles and stretches of the per-triangle maps ``Q0 → Q1``.

    Returns
    -------
    theta : (T,) rotation angle of each triangle's affine map, continuous across edges
        (neighbours differ by less than π); in each connected part the least rotated
        triangle keeps its angle in (−π, π] (on a twist with a clamped boundary: a boundary
        triangle, so the boundary does not spin by a full turn)
    stretch : (T, 2, 2) symmetric factors ``S_t`` with ``A_t = R(θ_t) S_t``
    """
    A = _edge_matrices(Q1, triangles) @ np.linalg.inv(_edge_matrices(Q0, triangles))
    wrapped = np.arctan2(A[:, 1, 0] - A[:, 0, 1], A[:, 0, 0] + A[:, 1, 1])
    stretch = _rotations(wrapped).transpose(0, 2, 1) @ A  # R(θ)ᵀ A
    stretch = 0.5 * (stretch + stretch.transpose(0, 2, 1))
    graph = _dual_graph(triangles)
    theta = wrapped.copy()
    n_parts, labels = connected_components(graph, directed=False)
    for part in range(n_parts):
        members = np.flatnonzero(labels == part)
        root = int(members[np.argmin(np.abs(wrapped[members]))])
        order, parent = breadth_first_order(graph, root, directed=False)
        depth = shortest_path(graph, unweighted=True, indices=root)[order].astype(np.int64)
        for d in range(1, int(depth.max()) + 1):  # a BFS parent is one level up
            nodes = order[depth == d]
            p = parent[nodes]
            step = np.mod(wrapped[nodes] - wrapped[p] + np.pi, 2.0 * np.pi) - np.pi
            theta[nodes] = theta[p] + step
    return theta, stretch


#: a vertex moved by at most this times the source's extent counts as still (pinned): a
#: target computed through a similarity that is the identity up to round-off (the morph's
#: residual target) keeps its clamped boundary. With exact equality, a 2e-16 change of the
#: target's boundary freed it: on the 225° twist of the 27k disc the initial path's energy
#: rose from 52409 to 54181 and the discrete geodesic took 15 iterations instead of 11.
STILL_TOLERANCE = 1e-12


def arap_interpolation(Q0: FloatArray, Q1: FloatArray, triangles: IntArray, times) -> FloatArray:
    """Positions of the as-rigid-as-possible interpolation at ``times`` (module docstring).

    Parameters
    ----------
    Q0, Q1 : (N, 2) source and target positions (positively oriented triangles)
    triangles : (T, 3) connectivity
    times : (K,) interpolation parameters (0 gives Q0, 1 gives Q1)

    Returns
    -------
    (K, N, 2) array
    """
    Q0 = np.asarray(Q0, dtype=np.float64)
    Q1 = np.asarray(Q1, dtype=np.float64)
    triangles = np.asarray(triangles)
    times = np.atleast_1d(np.asarray(times, dtype=np.float64))
    N = len(Q0)
    theta, stretch = rotation_angles(Q0, Q1, triangles)
    grads, area = p1_gradients(Q0, triangles)  # (T, 3, 2) hat-function gradients, areas
    K = p1_stiffness(Q0, triangles).tocsr()
    scale = float(np.ptp(Q0, axis=0).max()) if N else 0.0
    fixed = np.flatnonzero(np.abs(Q1 - Q0).max(axis=1) <= STILL_TOLERANCE * scale)
    pinned_still = fixed.size > 0
    if not pinned_still:
        fixed = np.array([int(np.argmin(np.sum((Q0 - Q0.mean(0)) ** 2, axis=1)))])
    free = np.setdiff1d(np.arange(N), fixed)
    out = np.empty((len(times), N, 2))
    if free.size == 0:
        out[:] = Q0
        return out
    solve = factorize_spd(K[free][:, free])
    coupling = K[free][:, fixed]
    eye = np.eye(2)
    for k, s in enumerate(times):
        J = _rotations(s * theta) @ ((1.0 - s) * eye + s * stretch)  # (T, 2, 2): row i = target gradient of coord i
        # load b_a = Σ_t A_t J_t ∇φ_a (per coordinate)
        contrib = area[:, None, None] * np.einsum("tij,taj->tai", J, grads)  # (T, 3, 2)
        b = scatter_corners(triangles, contrib, N)
        P = np.empty((N, 2))
        P[fixed] = Q0[fixed] if pinned_still else (1.0 - s) * Q0[fixed] + s * Q1[fixed]
        rhs = b[free] - coupling @ P[fixed]
        P[free] = solve(np.ascontiguousarray(rhs))
        out[k] = P
    out[times == 0.0] = Q0  # exact ends (the solves reproduce them to round-off)
    out[times == 1.0] = Q1
    return out
