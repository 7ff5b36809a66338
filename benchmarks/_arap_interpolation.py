"""The baseline of ``bench_surface_morph.py``: as-rigid-as-possible shape interpolation
(Alexa, Cohen-Or & Levin 2000) of two poses of a triangle surface, and linear
interpolation.

Per triangle the affine map of the source onto the target, completed by the normals
scaled by ``1/√|n|`` (Sumner & Popović's fourth vertex), is split by the polar
decomposition ``A = R S``; at time t the triangle wants ``A(t) = R^t ((1 − t) I + t S)``
(the rotation's angle interpolated about its axis, S linearly). The vertices solve the
least-squares Poisson system ``Σ_t a_t |∇_t X − A(t) ∇_t X_0|²`` (the cotangent Laplacian)
with vertex 0 pinned to its linear interpolation, as in the paper. numpy/scipy only.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial.transform import Rotation


def linear_interpolation(V0, V1, times) -> list:
    """``(1 − t) V0 + t V1`` at each time."""
    return [(1.0 - t) * V0 + t * V1 for t in times]


def _frames(P):
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    n = np.cross(e1, e2)
    n /= np.sqrt(np.linalg.norm(n, axis=1))[:, None]
    return np.stack([e1, e2, n], axis=2)


def arap_interpolation(V0, V1, F, times) -> list:
    """Alexa et al.'s interpolation at ``times`` (module docstring)."""
    V0, V1, F = np.asarray(V0, float), np.asarray(V1, float), np.asarray(F, np.int64)
    A = _frames(V1[F]) @ np.linalg.inv(_frames(V0[F]))
    U, s, Vt = np.linalg.svd(A)
    flip = np.linalg.det(U @ Vt) < 0  # the polar rotation has det +1
    U[flip, :, 2] *= -1
    s[flip, 2] *= -1
    R = U @ Vt
    S = np.swapaxes(Vt, 1, 2) @ (s[:, :, None] * Vt)
    rotvec = Rotation.from_matrix(R).as_rotvec()
    # the gradient operator per triangle: ∇λ_j (3D vectors in the triangle's plane)
    P = V0[F]
    e = [P[:, 2] - P[:, 1], P[:, 0] - P[:, 2], P[:, 1] - P[:, 0]]  # edge opposite corner j
    n = np.cross(e[2], -e[1])
    area = 0.5 * np.linalg.norm(n, axis=1)
    unit = n / (2.0 * area)[:, None]
    grad = np.stack([np.cross(unit, ej) / (2.0 * area)[:, None] for ej in e], axis=1)
    nv = len(V0)
    W = area[:, None, None] * np.einsum("tja,tka->tjk", grad, grad)
    L = sp.coo_matrix((W.ravel(), (np.repeat(F, 3, axis=1).ravel(), np.tile(F, 3).ravel())),
                      shape=(nv, nv)).tocsc()
    free = np.arange(1, nv)
    solve = spla.factorized(L[free][:, free].tocsc())
    G0 = np.einsum("tja,tjb->tab", P, grad)  # the source's gradient of position (3×3)
    out = []
    for t in times:
        At = Rotation.from_rotvec(t * rotvec).as_matrix() @ ((1.0 - t) * np.eye(3) + t * S)
        D = At @ G0  # wanted ∇X per triangle
        b = area[:, None, None] * np.einsum("tab,tjb->tja", D, grad)  # (T, corner, coord)
        rhs = np.stack([np.bincount(F.ravel(), b[:, :, d].ravel(), minlength=nv)
                        for d in range(3)], axis=1)
        X = np.empty((nv, 3))
        X[0] = (1.0 - t) * V0[0] + t * V1[0]
        rhs -= np.asarray(L[:, [0]].todense()) * X[0]
        X[1:] = np.column_stack([solve(rhs[1:, d]) for d in range(3)])
        out.append(X)
    return out
