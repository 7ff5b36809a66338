"""Lagrange P1 and P2 elements on affine simplices of any dimension: triangles in the
plane and tetrahedra in space behind one interface (the dimension is that of the arrays).

A cell ``K = (x_0, …, x_d)`` has edge rows ``E = (x_1 − x_0, …, x_d − x_0)`` ``(d, d)``,
signed volume ``det E / d!`` and barycentric gradients ``∇λ_k = (E⁻¹)_{:,k}`` (k ≥ 1),
``∇λ_0 = −Σ_k ∇λ_k`` (from their owners in :mod:`~meshopt_toolkit.kernels`). P2 adds
one node per edge (basis ``4 λ_i λ_j``; vertex basis ``λ_i (2 λ_i − 1)``). Every form here has polynomial integrands of degree ≤ 2 on each
cell, integrated exactly by the degree-2 rules of :data:`QUADRATURE`.

Shape derivatives use the volume form. Moving the nodes by a P1 field ``V`` changes a
cell's Jacobian by ``(I + εD)`` with ``D = ∇V = Σ_a V_a ⊗ ∇λ_a``: ``|K|`` gains the
factor ``1 + ε tr D`` and every transported gradient ``g`` of a Lagrange function becomes
``(I − εDᵀ) g``. A cell term ``Φ_K`` therefore has ``dΦ_K = S_K : D`` for a ``(d, d)``
tensor ``S_K`` (an Eshelby tensor), and ``∂Φ_K/∂x_a = S_K ∇λ_a`` (:func:`node_gradient`),
exactly for the discrete functional.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from itertools import combinations

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError, NotAdmissibleError
from ..kernels.cell_maps import barycentric_gradients, scatter_corners
from ..kernels.tetrahedra import signed_volumes
from ..kernels.triangles import signed_areas

__all__ = ["QUADRATURE", "Geometry", "LagrangeSpace", "assemble", "geometry",
           "local_edges", "node_gradient", "oriented_facets", "facet_normals",
           "facet_normal_gradient", "same_configuration", "all_boundary_facets"]

#: degree-2 rules per dimension: barycentric points ``(Q, d+1)`` and weights (sum 1)
_A3 = (5.0 + 3.0 * math.sqrt(5.0)) / 20.0
_B3 = (5.0 - math.sqrt(5.0)) / 20.0
QUADRATURE = {
    2: (np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]),
        np.full(3, 1 / 3)),
    3: (np.full((4, 4), _B3) + np.eye(4) * (_A3 - _B3), np.full(4, 1 / 4)),
}


def local_edges(d: int) -> np.ndarray:
    """The edges ``(d(d+1)/2, 2)`` of the reference simplex, in lexicographic order: the
    local order of the P2 edge nodes."""
    return np.array(list(combinations(range(d + 1), 2)))


def _check_cells(points: FloatArray, cells: IntArray) -> int:
    d = points.shape[1] if points.ndim == 2 else -1
    if d not in (2, 3) or cells.ndim != 2 or cells.shape[1] != d + 1:
        raise InvalidMeshError(f"simplices need points (N, 2) with cells (T, 3) or points "
                               f"(N, 3) with cells (T, 4); got {points.shape}, {cells.shape}")
    return d


@dataclass(frozen=True)
class Geometry:
    """Affine maps of all cells at one configuration.

    Attributes
    ----------
    grads : (T, d+1, d) barycentric gradients ``∇λ_a``
    volumes : (T,) signed volumes (areas in 2D)
    """

    grads: FloatArray
    volumes: FloatArray

    @property
    def dim(self) -> int:
        return self.grads.shape[2]


def geometry(points: FloatArray, cells: IntArray) -> Geometry:
    """Barycentric gradients and signed volumes of every simplex.

    Parameters
    ----------
    points : (N, d) node positions, d = 2 or 3
    cells : (T, d+1) vertex indices

    Raises
    ------
    NotAdmissibleError
        A cell of volume ≤ 0.
    """
    points = np.asarray(points, dtype=float)
    cells = np.asarray(cells)
    d = _check_cells(points, cells)
    volumes = signed_areas(points, cells) if d == 2 else signed_volumes(points, cells)
    if not np.all(volumes > 0):
        bad = int(np.flatnonzero(~(volumes > 0))[0])
        raise NotAdmissibleError(f"cell {bad} has signed volume {volumes[bad]:.3e}")
    return Geometry(barycentric_gradients(points[cells]), volumes)


def _p2_barycentric_derivatives(lam: FloatArray) -> FloatArray:
    """``∂φ_b/∂λ_k`` ``(Q, nb, d+1)`` of the P2 basis at barycentric points ``(Q, d+1)``."""
    q, m = lam.shape
    edges = local_edges(m - 1)
    out = np.zeros((q, m + len(edges), m))
    idx = np.arange(m)
    out[:, idx, idx] = 4.0 * lam - 1.0
    for e, (i, j) in enumerate(edges):
        out[:, m + e, i] = 4.0 * lam[:, j]
        out[:, m + e, j] = 4.0 * lam[:, i]
    return out


def _p2_values(lam: FloatArray) -> FloatArray:
    """The P2 basis ``(Q, nb)`` at barycentric points ``(Q, d+1)``."""
    edges = local_edges(lam.shape[1] - 1)
    on_edges = 4.0 * lam[:, edges[:, 0]] * lam[:, edges[:, 1]]
    return np.concatenate([lam * (2.0 * lam - 1.0), on_edges], axis=1)


class LagrangeSpace:
    """Scalar P1 or P2 degrees of freedom on a simplicial mesh.

    Parameters
    ----------
    cells : (T, d+1) vertex indices
    n_vertices : number of mesh vertices
    degree : 1 or 2

    Attributes
    ----------
    cell_dofs : (T, nb) global dofs of each cell (vertices first, then the edges in
        :func:`local_edges` order)
    n_dofs : vertices (P1) or vertices + edges (P2)
    edges : (M, 2) sorted global edges (P2: edge ``k`` is dof ``n_vertices + k``)
    """

    def __init__(self, cells: IntArray, n_vertices: int, degree: int = 1) -> None:
        if degree not in (1, 2):
            raise ValueError(f"degree must be 1 or 2, got {degree}")
        self.cells = np.asarray(cells, dtype=np.int64)
        self.dim = self.cells.shape[1] - 1
        self.degree, self.n_vertices = degree, int(n_vertices)
        if degree == 1:
            self.edges = np.zeros((0, 2), np.int64)
            self.cell_dofs, self.n_dofs = self.cells, self.n_vertices
            return
        le = local_edges(self.dim)
        pairs = np.sort(self.cells[:, le], axis=2)  # (T, E, 2)
        keys = pairs[..., 0] * self.n_vertices + pairs[..., 1]
        uniq, inverse = np.unique(keys.ravel(), return_inverse=True)
        self._edge_keys = uniq
        self.edges = np.stack([uniq // self.n_vertices, uniq % self.n_vertices], axis=1)
        self.cell_dofs = np.concatenate(
            [self.cells, self.n_vertices + inverse.reshape(keys.shape)], axis=1)
        self.n_dofs = self.n_vertices + len(uniq)

    def edge_dofs(self, edges: IntArray) -> IntArray:
        """The P2 dofs of edges ``(..., 2)`` of the mesh."""
        e = np.sort(np.asarray(edges, dtype=np.int64), axis=-1)
        k = e[..., 0] * self.n_vertices + e[..., 1]
        pos = np.searchsorted(self._edge_keys, k)
        if np.any(pos >= len(self._edge_keys)) or np.any(self._edge_keys[np.minimum(
                pos, len(self._edge_keys) - 1)] != k):
            raise InvalidMeshError("a boundary facet's edge is not an edge of the cells")
        return self.n_vertices + pos

    def facet_dofs(self, facets: IntArray) -> IntArray:
        """All dofs ``(F, nf)`` on facets ``(F, d)``: vertices, then (P2) the facet edges
        in :func:`local_edges` order of the facet."""
        facets = np.asarray(facets, dtype=np.int64)
        if self.degree == 1:
            return facets
        le = local_edges(facets.shape[1] - 1)
        return np.concatenate([facets, self.edge_dofs(facets[:, le])], axis=1)

    def dof_points(self, points: FloatArray) -> FloatArray:
        """Positions ``(n_dofs, d)`` of the nodes: vertices, then (P2) edge midpoints."""
        if self.degree == 1:
            return np.asarray(points, dtype=float)
        return np.concatenate([points, 0.5 * (points[self.edges[:, 0]] + points[self.edges[:, 1]])])

    @cached_property
    def reference(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(values (Q, nb), ∂φ/∂λ (Q, nb, d+1), weights (Q,), barycentric points)``
        at the degree-2 rule's points."""
        lam, w = QUADRATURE[self.dim]
        if self.degree == 1:
            identity = np.broadcast_to(np.eye(self.dim + 1), (len(w),) + (self.dim + 1,) * 2)
            return lam, identity, w, lam
        return _p2_values(lam), _p2_barycentric_derivatives(lam), w, lam

    def gradients(self, geo: Geometry) -> FloatArray:
        """Physical basis gradients ``(T, Q, nb, d)`` at the quadrature points."""
        return np.matmul(self.reference[1][None], geo.grads[:, None])

    def interpolate(self, points: FloatArray, f) -> FloatArray:
        """Nodal interpolant of ``f: (M, d) → (M, …)`` at the space's nodes."""
        return np.asarray(f(self.dof_points(points)), dtype=float)


def same_configuration(state, Q) -> bool:
    """Whether a cached ``state`` (with the positions ``.Q`` it was computed at, or None)
    holds for ``Q``: the objectives' one-configuration cache."""
    return state is not None and np.shape(Q) == state.Q.shape and np.array_equal(Q, state.Q)


def assemble(rows: IntArray, cols: IntArray, local: FloatArray, shape: tuple[int, int]
             ) -> sp.csr_matrix:
    """Sparse matrix ``Σ_K`` of local matrices ``(T, a, b)`` at rows ``(T, a)`` and columns
    ``(T, b)`` (COO summed into CSR)."""
    r = np.broadcast_to(rows[:, :, None], local.shape).ravel()
    c = np.broadcast_to(cols[:, None, :], local.shape).ravel()
    return sp.csr_matrix((local.ravel(), (r, c)), shape=shape)


def node_gradient(S: FloatArray, geo: Geometry, cells: IntArray, n: int) -> FloatArray:
    """``Σ_K S_K ∇λ_a`` at every vertex ``(n, d)``: the derivative of ``Σ_K Φ_K`` with
    ``dΦ_K = S_K : ∇V`` (module docstring). ``S`` is ``(T, d, d)``."""
    return scatter_corners(cells, np.einsum("tij,taj->tai", S, geo.grads), n)


def all_boundary_facets(cells: IntArray) -> IntArray:
    """The facets ``(F, d)`` held by exactly one cell, sorted vertex indices."""
    m = cells.shape[1]
    f = np.sort(np.concatenate([np.delete(cells, k, axis=1) for k in range(m)]), axis=1)
    u, c = np.unique(f, axis=0, return_counts=True)
    return u[c == 1]


def oriented_facets(points: FloatArray, cells: IntArray, facets: IntArray) -> IntArray:
    """Facets ``(F, d)`` of ``cells`` reordered so that :func:`facet_normals` points out of
    the cell holding each (a boundary facet: outward).

    Raises
    ------
    InvalidMeshError
        A facet that is no facet of a cell.
    """
    cells = np.asarray(cells, dtype=np.int64)
    facets = np.array(facets, dtype=np.int64, copy=True)
    m = cells.shape[1]
    n = max(int(cells.max()) + 1, len(points))
    # every facet of every cell as a sorted key, with the vertex opposite it
    all_f = np.concatenate([np.delete(cells, k, axis=1) for k in range(m)])
    opposite = np.concatenate([cells[:, k] for k in range(m)])
    sort_all = np.sort(all_f, axis=1)
    keys_all = np.ravel_multi_index(sort_all.T, (n,) * (m - 1))
    order = np.argsort(keys_all)
    keys_sorted = keys_all[order]
    keys = np.ravel_multi_index(np.sort(facets, axis=1).T, (n,) * (m - 1))
    pos = np.minimum(np.searchsorted(keys_sorted, keys), len(keys_sorted) - 1)
    if np.any(keys_sorted[pos] != keys):
        raise InvalidMeshError("a boundary facet is not a facet of any cell")
    opp = opposite[order[pos]]
    inward = points[opp] - points[facets[:, 0]]
    flip = np.einsum("fd,fd->f", facet_normals(points, facets), inward) > 0
    facets[flip, :2] = facets[flip, 1::-1]
    return facets


def facet_normals(points: FloatArray, facets: IntArray) -> FloatArray:
    """Area-weighted normals ``N_F = n |F|`` ``(F, d)``: for an edge ``(a, b)``
    ``R (b − a)`` with ``R (t_x, t_y) = (t_y, −t_x)``; for a triangle
    ``½ (b−a)×(c−a)``."""
    x = np.asarray(points, dtype=float)[facets]
    if facets.shape[1] == 2:
        t = x[:, 1] - x[:, 0]
        return np.stack([t[:, 1], -t[:, 0]], axis=1)
    return 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])


def facet_normal_gradient(points: FloatArray, facets: IntArray, c: FloatArray, n: int
                          ) -> FloatArray:
    """``∂/∂x (Σ_F c_F · N_F)`` ``(n, d)`` at fixed vectors ``c`` ``(F, d)``."""
    x = np.asarray(points, dtype=float)[facets]
    if facets.shape[1] == 2:
        gb = np.stack([-c[:, 1], c[:, 0]], axis=1)  # Rᵀc
        per = np.stack([-gb, gb], axis=1)
    else:
        u, v = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
        gb, gc = 0.5 * np.cross(v, c), 0.5 * np.cross(c, u)
        per = np.stack([-gb - gc, gb, gc], axis=1)
    return scatter_corners(facets, per, n)
