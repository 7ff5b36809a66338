"""Per-cell affine maps of simplices in 3D and the quality measures bounded through them.

A simplex with rest corners ``p_0 … p_k`` (in rest coordinates of dimension ``k``) and
current corners ``x_0 … x_k`` (in R³) is the image of its rest simplex under an affine
map whose linear part is ``A = Σ_j x_j ⊗ γ_j`` (3 × k), with ``γ_j`` the gradients of the
rest barycentric coordinates (:func:`barycentric_gradients`). Tetrahedra use their rest
positions as rest coordinates; surface triangles use coordinates in their own rest plane
(:func:`triangle_plane_coordinates`), so ``AᵀA`` is the first fundamental form pulled back
to the rest triangle.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError

SQRT3 = np.sqrt(3.0)

#: edge matrix (columns x_j − x_0) of the regular tetrahedron with unit edges
REGULAR_TET_EDGES = np.array([[1.0, 0.5, 0.5],
                              [0.0, SQRT3 / 2, SQRT3 / 6],
                              [0.0, 0.0, np.sqrt(2.0 / 3.0)]])


def edge_matrices(points: FloatArray, cells: IntArray) -> FloatArray:
    """``D[c] = [x_1 − x_0, …, x_k − x_0]`` as columns: (C, dim, k)."""
    p = np.asarray(points, float)[cells]
    return np.swapaxes(p[:, 1:] - p[:, :1], 1, 2)


def triangle_plane_coordinates(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Corners of each triangle of a 3D surface in an orthonormal frame of its own plane:
    (T, 3, 2), corner 0 at the origin, corner 1 on the positive first axis, corner 2 in
    the upper half plane (counter-clockwise seen from the normal ``e₀₁ × e₀₂``)."""
    p = np.asarray(points, float)[triangles]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    l1 = np.linalg.norm(e1, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = e1 / l1[:, None]
    x2 = np.einsum("ti,ti->t", e2, u)
    y2 = np.linalg.norm(e2 - x2[:, None] * u, axis=1)
    out = np.zeros((len(triangles), 3, 2))
    out[:, 1, 0] = l1
    out[:, 2, 0] = x2
    out[:, 2, 1] = y2
    return out


def barycentric_gradients(rest: FloatArray) -> FloatArray:
    """Gradients ``γ_j`` of the barycentric coordinates of each rest simplex.

    Parameters
    ----------
    rest : (C, k + 1, k) float array
        Corners of each cell in rest coordinates (non-degenerate simplices).

    Returns
    -------
    (C, k + 1, k) float array
        ``γ[c, j]``; ``Σ_j γ_j = 0`` and ``Σ_j x_j ⊗ γ_j`` is the affine map's linear part.
    """
    rest = np.asarray(rest, float)
    D = np.swapaxes(rest[:, 1:] - rest[:, :1], 1, 2)  # (C, k, k)
    G = np.linalg.inv(D)  # rows: gradients of λ_1 … λ_k
    out = np.empty_like(rest)
    out[:, 1:] = G
    out[:, 0] = -G.sum(axis=1)
    return out


def affine_maps(points: FloatArray, cells: IntArray, gradients: FloatArray) -> FloatArray:
    """Linear parts ``A = Σ_j x_j ⊗ γ_j`` of the cells' affine maps: (C, dim, k)."""
    # a batched product (C, dim, k+1) @ (C, k+1, k): several times faster than einsum here
    return np.matmul(np.swapaxes(np.asarray(points, float)[cells], 1, 2), gradients)


def space_cells(points: FloatArray, cells: IntArray, corners: int,
                what: str) -> tuple[FloatArray, IntArray]:
    """``points`` as an (N, 3) float array and ``cells`` as a (C, ``corners``) array.

    Raises
    ------
    InvalidMeshError
        Other shapes: ``"{what} needs (N, 3) points and (C, 4) cells"``.
    """
    points, cells = np.asarray(points, dtype=float), np.asarray(cells)
    if points.ndim != 2 or points.shape[1] != 3 or cells.shape[1:] != (corners,):
        raise InvalidMeshError(f"{what} needs (N, 3) points and (C, {corners}) cells")
    return points, cells


def coordinate_columns(cells: IntArray, dimension: int) -> IntArray:
    """Global coordinate index ``dimension·vertex + a`` of each corner coordinate of each
    cell ``(C, k)``: (C, k·dimension), corner-major (the columns of per-cell Jacobian
    blocks)."""
    cells = np.asarray(cells)
    return (dimension * cells[:, :, None] + np.arange(dimension)).reshape(len(cells), -1)


def scatter_corners(cells: IntArray, per_corner: FloatArray, n: int) -> FloatArray:
    """Sum per-corner vectors ``(C, k, d)`` of the cells ``(C, k)`` onto their vertices:
    ``(n, d)`` (the transpose of gathering ``points[cells]``)."""
    idx = np.asarray(cells).ravel()
    per_corner = np.asarray(per_corner)
    flat = per_corner.reshape(len(idx), per_corner.shape[-1])
    return np.column_stack([np.bincount(idx, flat[:, k], n) for k in range(flat.shape[1])])


def block_jacobian(blocks: FloatArray, columns: IntArray, n_columns: int) -> sp.csr_matrix:
    """Assemble per-cell blocks (C, m, K) into the sparse Jacobian (m·C × ``n_columns``):
    row ``m·c + i`` of block ``[c, i]``, its entries in the columns ``columns[c]`` (C, K)
    (:func:`coordinate_columns`); duplicates summed."""
    n, m, _ = blocks.shape
    rows = np.broadcast_to(np.arange(n * m).reshape(n, m, 1), blocks.shape)
    cols = np.broadcast_to(np.asarray(columns)[:, None, :], blocks.shape)
    return sp.coo_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())),
                         shape=(n * m, n_columns)).tocsr()


def tet_condition_numbers(points: FloatArray, tets: IntArray) -> FloatArray:
    """Condition number ``κ₂(S) = σ_max/σ_min`` of the map ``S = D W⁻¹`` from the regular
    tet (edge matrix ``W``) to each tet; 1 iff regular, ``inf`` when degenerate. (C,)."""
    S = edge_matrices(points, tets) @ np.linalg.inv(REGULAR_TET_EDGES)
    s = np.linalg.svd(S, compute_uv=False)
    with np.errstate(divide="ignore"):
        return s[:, 0] / s[:, -1]


def surface_inverse_shape_quality(points: FloatArray, triangles: IntArray) -> FloatArray:
    """``1/ψ = (E0² + E1² + E2²) / (4√3 A)`` (5.23) of triangles in R³ (``A`` the unsigned
    area): ≥ 1, 1 iff equilateral, ``inf`` when degenerate. Returns (T,)."""
    p = np.asarray(points, float)[triangles]
    e = p[:, [1, 2, 0]] - p
    sq = np.einsum("tlk,tlk->t", e, e)
    area = 0.5 * np.linalg.norm(np.cross(e[:, 0], -e[:, 2]), axis=1)
    with np.errstate(divide="ignore"):
        return sq / (4.0 * SQRT3 * area)
