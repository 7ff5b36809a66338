"""As-rigid-as-possible interpolation of two poses of a triangle surface in R³ (Alexa,
Cohen-Or & Levin 2000), the start of :func:`.surface_morph.morph_surface`.

Each triangle's map from the source to the target (completed by its normal scaled by
``1/√|n|``, as in deformation transfer) is split ``A = R_g R S``: ``R_g`` the best global
rotation of the pair (Umeyama), ``R S`` the polar decomposition of what is left. At time
``t`` the triangle wants ``A(t) = R_g^t R^t ((1 − t) I + t S)`` (rotations in angle);
the vertices are the least-squares fit of these maps (a cotangent-Laplacian system,
factorized once), translated so that the area-weighted centroid moves linearly.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial.transform import Rotation

from .._typing import FloatArray, IntArray
from ..solvers import factorize_spd
from .surface_distortion import SurfaceDistortion
from .similarity_3d import fit_similarity_3d as fit_similarity


def _frames(P: FloatArray) -> FloatArray:
    """Per triangle ``[e1, e2, n/√|n|]`` (T, 3, 3), ``e`` the edges from corner 0."""
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    n = np.cross(e1, e2)
    n /= np.sqrt(np.linalg.norm(n, axis=1))[:, None]
    return np.stack([e1, e2, n], axis=2)


def _polar(A: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``A = R S`` per 3×3 block: R a rotation (det +1), S symmetric."""
    U, s, Vt = np.linalg.svd(A)
    d = np.sign(np.linalg.det(U @ Vt))
    d[d == 0] = 1.0
    U = U.copy()
    U[:, :, 2] *= d[:, None]
    s = s.copy()
    s[:, 2] *= d
    R = U @ Vt
    S = np.swapaxes(Vt, 1, 2) @ (s[:, :, None] * Vt)
    return R, S


def arap_interpolation(source: FloatArray, target: FloatArray, triangles: IntArray,
                       times) -> list:
    """The frames of the as-rigid-as-possible interpolation at ``times`` (module
    docstring); ``source`` at ``t = 0`` and ``target`` at ``t = 1`` exactly.

    Parameters
    ----------
    source, target : (N, 3) float arrays, every vertex in some triangle
    triangles : (T, 3) int array, no degenerate triangle in ``source``
    times : sequence of floats in [0, 1]
    """
    V0, V1 = np.asarray(source, float), np.asarray(target, float)
    F = np.asarray(triangles, np.int64)
    Rg = fit_similarity(V0, V1, scaling=False).rotation
    global_vec = Rotation.from_matrix(Rg).as_rotvec()
    A = _frames(V1[F]) @ np.linalg.inv(_frames(V0[F]))
    R, S = _polar(np.swapaxes(Rg, 0, 1)[None] @ A)
    local_vec = Rotation.from_matrix(R).as_rotvec()
    dist = SurfaceDistortion(V0, F)
    grads = dist.gradients  # (T, 3, 2) barycentric gradients in the rest planes
    A0 = dist.affine_maps(V0)  # (T, 3, 2)
    P = V0[F]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    n = len(V0)
    # L_jk = Σ_t a_t γ_j·γ_k, vertex 0 pinned (its row and column dropped)
    G = area[:, None, None] * np.einsum("tja,tka->tjk", grads, grads)
    rows = np.repeat(F, 3, axis=1).ravel()
    cols = np.tile(F, (1, 3)).ravel()
    L = sp.coo_matrix((G.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    solve = factorize_spd(L[1:, 1:].tocsc())
    mass = np.bincount(F.ravel(), np.repeat(area / 3.0, 3), minlength=n)
    mass /= mass.sum()
    c0, c1 = mass @ V0, mass @ V1
    out = []
    for t in times:
        t = float(t)
        if t == 0.0:
            out.append(V0.copy())
            continue
        if t == 1.0:
            out.append(V1.copy())
            continue
        At = (Rotation.from_rotvec(t * global_vec).as_matrix()[None]
              @ Rotation.from_rotvec(t * local_vec).as_matrix()
              @ ((1.0 - t) * np.eye(3) + t * S))
        D = At @ A0  # (T, 3, 2): each triangle's wanted map from its rest plane
        b = area[:, None, None] * np.einsum("tdb,tjb->tjd", D, grads)  # (T, 3 corners, 3)
        rhs = np.stack([np.bincount(F.ravel(), b[:, :, d].ravel(), minlength=n)
                        for d in range(3)], axis=1)
        X = np.zeros((n, 3))
        X[1:] = solve(rhs[1:])
        X += (1.0 - t) * c0 + t * c1 - mass @ X
        out.append(X)
    return out
