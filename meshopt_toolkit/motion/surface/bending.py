"""Discrete shell bending of triangle surfaces in R³ (Grinspun et al. 2003; Heeren, Rumpf,
Wardetzky & Wirth 2012): per interior edge the change of its dihedral angle, weighted by
the rest edge's length squared over its rest area,

    E_b(Q) = ½ Σ_e c_e (θ_e(Q) − θ̄_e)²,   c_e = ℓ̄_e² / Ā_e,   Ā_e = (A₁ + A₂)/3,

with θ_e the signed angle between the normals of the edge's two triangles (0 where they
are coplanar). ``E_b`` is invariant under rigid motions and uniform scaling. Its
residuals ``√c_e (θ_e − θ̄_e)`` and their exact Jacobian rows (12 entries: the two edge
ends and the two opposite corners) feed Gauss–Newton.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...kernels.cell_maps import block_jacobian, coordinate_columns


def edge_diamonds(triangles: IntArray) -> IntArray:
    """The interior manifold edges as diamonds ``(i, j, k, l)`` (E, 4): triangle
    ``(i, j, k)`` holds the half-edge i→j, a second triangle holds j→i with opposite
    corner ``l``; each edge once. Edges on the boundary, edges of more than two triangles
    and edges whose two triangles are oriented alike are left out."""
    return diamonds_and_triangles(triangles)[0]


def diamonds_and_triangles(triangles: IntArray) -> tuple[IntArray, IntArray]:
    """:func:`edge_diamonds` and, for each diamond, the two triangles holding it (E, 2):
    that of the half-edge i→j, then that of j→i."""
    F = np.asarray(triangles, dtype=np.int64)
    tails = F.ravel()
    heads = F[:, [1, 2, 0]].ravel()
    tips = F[:, [2, 0, 1]].ravel()
    n = int(F.max()) + 1 if F.size else 0
    key = tails * n + heads
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    unique, counts = np.unique(sorted_key, return_counts=True)
    single = unique[counts == 1]
    reverse = heads * n + tails
    ok = (tails < heads) & np.isin(key, single) & np.isin(reverse, single)
    pos = np.searchsorted(sorted_key, reverse[ok])
    mate = order[pos]
    return (np.stack([tails[ok], heads[ok], tips[ok], tips[mate]], axis=1),
            np.stack([np.flatnonzero(ok) // 3, mate // 3], axis=1))


def _normals(Q: FloatArray, D: IntArray):
    xi, xj, xk, xl = (Q[D[:, m]] for m in range(4))
    e = xj - xi
    n1 = np.cross(e, xk - xi)
    n2 = np.cross(xl - xi, e)
    return xi, e, xk, xl, n1, n2


def dihedral_angles(Q: FloatArray, diamonds: IntArray) -> FloatArray:
    """Signed bending angle of each diamond in (−π, π]: the angle from the normal of
    ``(i, j, k)`` to that of ``(j, i, l)`` about the edge i→j (0 when flat)."""
    _, e, _, _, n1, n2 = _normals(np.asarray(Q, float), diamonds)
    length = np.linalg.norm(e, axis=1)
    return np.arctan2(np.einsum("ei,ei->e", np.cross(n1, n2), e) / length,
                      np.einsum("ei,ei->e", n1, n2))


def dihedral_gradients(Q: FloatArray, diamonds: IntArray) -> FloatArray:
    """``∂θ_e/∂x`` at the diamond's corners ``(i, j, k, l)``: (E, 4, 3).

    The opposite corners move θ along their triangle's normal, ``∂θ/∂x_k = −|e| n₁/|n₁|²``,
    ``∂θ/∂x_l = −|e| n₂/|n₂|²``; the edge ends take the rest so that translations and
    rotations leave θ unchanged, split by where ``k`` and ``l`` project onto the edge."""
    xi, e, xk, xl, n1, n2 = _normals(np.asarray(Q, float), diamonds)
    ee = np.einsum("ei,ei->e", e, e)
    length = np.sqrt(ee)
    gk = -(length / np.einsum("ei,ei->e", n1, n1))[:, None] * n1
    gl = -(length / np.einsum("ei,ei->e", n2, n2))[:, None] * n2
    ak = (np.einsum("ei,ei->e", xk - xi, e) / ee)[:, None]
    al = (np.einsum("ei,ei->e", xl - xi, e) / ee)[:, None]
    gi = -(1.0 - ak) * gk - (1.0 - al) * gl
    gj = -ak * gk - al * gl
    return np.stack([gi, gj, gk, gl], axis=1)


def wrap(angle: FloatArray) -> FloatArray:
    """Angles wrapped into [−π, π)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


class ShellBending:
    """The bending energy of a surface against its rest shape (module docstring).

    Parameters
    ----------
    reference : (N, 3) float array
        Rest positions (rest angles, lengths and areas).
    triangles : (T, 3) int array
    """

    def __init__(self, reference: FloatArray, triangles: IntArray) -> None:
        reference = np.asarray(reference, float)
        self.n_vertices = len(reference)
        self.diamonds = edge_diamonds(triangles)
        D = self.diamonds
        self.rest_angles = dihedral_angles(reference, D)
        _, e, _, _, n1, n2 = _normals(reference, D)
        area = (np.linalg.norm(n1, axis=1) + np.linalg.norm(n2, axis=1)) / 6.0
        self.weights = np.einsum("ei,ei->e", e, e) / area

    def residuals(self, Q: FloatArray) -> FloatArray:
        """``√c_e (θ_e(Q) − θ̄_e)`` (E,), the angle change wrapped into [−π, π)."""
        return np.sqrt(self.weights) * wrap(dihedral_angles(Q, self.diamonds)
                                            - self.rest_angles)

    def energy(self, Q: FloatArray) -> float:
        """``½ |residuals|²``."""
        r = self.residuals(Q)
        return 0.5 * float(r @ r)

    def jacobian_blocks(self, Q: FloatArray) -> FloatArray:
        """Rows of the residuals' Jacobian at the diamonds' corners: (E, 12)."""
        G = dihedral_gradients(Q, self.diamonds)
        return np.sqrt(self.weights)[:, None] * G.reshape(len(G), 12)

    def columns(self) -> IntArray:
        """Global coordinate index ``3·vertex + d`` of each block column: (E, 12)."""
        return coordinate_columns(self.diamonds, 3)

    def jacobian_matrix(self, Q: FloatArray) -> sp.csr_matrix:
        """The residuals' Jacobian (E × 3N)."""
        blocks = self.jacobian_blocks(Q)
        return block_jacobian(blocks[:, None, :], self.columns(), 3 * self.n_vertices)

    def gradient(self, Q: FloatArray) -> FloatArray:
        """``∇E_b`` (N, 3)."""
        return (self.jacobian_matrix(Q).T @ self.residuals(Q)).reshape(-1, 3)
