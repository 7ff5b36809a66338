"""Linear elasticity on triangles (plane stress) and tetrahedra, P1 or P2, with traction
loads per boundary group and the compliance objective with its exact node derivative.

Vector dofs are interleaved: component ``c`` of scalar node ``i`` is dof ``d i + c``. The
bilinear form is ``a(u, v) = ∫ σ(u) : ε(v)``, ``σ(u) = 2μ ε(u) + λ tr ε(u) I``; in 2D
``λ = Eν/(1 − ν²)`` (plane stress), in 3D ``λ = Eν/((1 + ν)(1 − 2ν))``,
``μ = E/(2(1 + ν))``.
A traction group is a set of boundary facets with a stress tensor ``σ_g``: the load is
``∫_F (σ_g n)·v``, i.e. ``b_{a} = ω_a σ_g N_F`` with ``N_F = n |F|`` and the facet
weights ``ω_a = ∫_F φ_a / |F|`` (P1: ``1/d``; P2 on an edge ``(1/6, 1/6, 2/3)``, on a
triangle 0 at vertices and ``1/3`` at edges).

Compliance ``J = bᵀu = ∫_Γ t·u`` with ``K u = b`` (``u = 0`` on clamped facets) is
self-adjoint: the Lagrangian ``bᵀu − wᵀ(K u − b)`` is stationary at ``w = u``, so

``dJ/dx = 2 ∂_x(bᵀu) − ∂_x(uᵀ K u)`` at fixed ``u``.

``uᵀKu = Σ_K |K| Σ_q w_q σ:ε`` has the Eshelby tensor (:mod:`.simplex`)
``S = |K| Σ_q w_q [(σ:∇u) I − 2 ∇uᵀ σ]``, and ``bᵀu = Σ_F (σ_gᵀ ū_F)·N_F`` with
``ū_F = Σ_a ω_a u_a`` is differentiated through ``N_F``
(:func:`~.simplex.facet_normal_gradient`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import MeshoptError
from ..kernels.cell_maps import scatter_corners
from ..solvers import factorize_spd
from .elasticity import factorize
from .cached import CachedObjective, SimplexState
from .simplex import (Geometry, LagrangeSpace, assemble, facet_normal_gradient, facet_normals,
                      geometry, node_gradient, oriented_facets)

__all__ = ["ComplianceObjective", "elastic_lame", "facet_weights", "strain_energy_tensor",
           "vector_dofs", "vector_stiffness"]


def elastic_lame(E: float, nu: float, dim: int) -> tuple[float, float]:
    """``(λ, μ)``: plane stress for ``dim = 2``, three-dimensional for ``dim = 3``."""
    if not E > 0 or not -1.0 < nu < 0.5:
        raise MeshoptError(f"elasticity needs E > 0 and -1 < nu < 0.5, got E={E}, nu={nu}")
    mu = E / (2.0 * (1.0 + nu))
    lam = E * nu / (1.0 - nu * nu) if dim == 2 else E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return lam, mu


def vector_dofs(scalar_dofs: IntArray, d: int) -> IntArray:
    """Interleaved vector dofs ``(..., nb d)`` of scalar dofs ``(..., nb)``."""
    s = np.asarray(scalar_dofs)
    return (d * s[..., None] + np.arange(d)).reshape(s.shape[:-1] + (-1,))


def facet_weights(d: int, degree: int) -> FloatArray:
    """``ω_a = ∫_F φ_a / |F|`` for the dofs of :meth:`.LagrangeSpace.facet_dofs`."""
    if degree == 1:
        return np.full(d, 1.0 / d)
    return np.array([1 / 6, 1 / 6, 2 / 3]) if d == 2 else np.r_[np.zeros(3), np.full(3, 1 / 3)]


def vector_stiffness(space: LagrangeSpace, geo: Geometry, lam: float, mu: float) -> FloatArray:
    """Local matrices ``(T, nb d, nb d)`` of ``∫ 2μ ε(u):ε(v) + λ div u div v``."""
    g = space.gradients(geo)  # (T, Q, nb, d)
    t, nq, nb, d = g.shape
    gf = g.reshape(t, nq, nb * d)
    scale = space.reference[2][None, :, None] * geo.volumes[:, None, None]
    # A[t, a, i, b, j] = |K| Σ_q w_q ∂_i φ_a ∂_j φ_b (batched products: einsum is far slower)
    A = np.matmul((gf * scale).transpose(0, 2, 1), gf).reshape(t, nb, d, nb, d)
    K = lam * A + mu * A.transpose(0, 1, 4, 3, 2)
    trace = np.einsum("taibi->tab", A)
    for c in range(d):
        K[:, :, c, :, c] += mu * trace
    return K.reshape(t, nb * d, nb * d)


def strain_energy_tensor(space: LagrangeSpace, geo: Geometry, U: FloatArray, lam: float,
                         mu: float) -> FloatArray:
    """The Eshelby tensors ``(T, d, d)`` of ``Σ_K ∫_K σ(u):ε(u)`` at fixed nodal values
    ``U`` ``(n_dofs, d)``: ``|K| Σ_q w_q [(σ:∇u) I − 2 ∇uᵀ σ]``."""
    g, w = space.gradients(geo), space.reference[2]
    if space.degree == 1:  # ∇u constant on each cell: one point with the rule's weight
        g, w = g[:, :1], w.sum(keepdims=True)
    # batched products, not einsum: this is most of the derivative's time
    G = np.matmul(U[space.cell_dofs].transpose(0, 2, 1)[:, None], g)  # ∇u
    d = G.shape[-1]
    Gt = G.transpose(0, 1, 3, 2)
    tr = np.trace(G, axis1=2, axis2=3)
    sigma = mu * (G + Gt)
    sigma[..., range(d), range(d)] += lam * tr[..., None]
    energy = (sigma * G).sum(axis=(2, 3))
    per_q = -2.0 * np.matmul(Gt, sigma)
    per_q[..., range(d), range(d)] += energy[..., None]
    return (per_q * w[:, None, None]).sum(axis=1) * geo.volumes[:, None, None]


def rigid_modes(points: FloatArray) -> FloatArray:
    """The rigid motions ``(d N, d(d+1)/2)`` at the nodes, interleaved dofs: translations,
    then rotations about the centroid."""
    X = np.asarray(points, dtype=float)
    X = X - X.mean(axis=0)
    n, d = X.shape
    cols = [np.tile(np.eye(d)[c], n) for c in range(d)]
    for a, b in ((0, 1),) if d == 2 else ((0, 1), (1, 2), (2, 0)):
        r = np.zeros((n, d))
        r[:, a], r[:, b] = -X[:, b], X[:, a]
        cols.append(r.ravel())
    return np.column_stack(cols)


def rigid_pins(points: FloatArray) -> IntArray:
    """``d(d+1)/2`` vertex dofs whose rows of the rigid modes are independent: fixing them
    removes the rigid motions and nothing else (a statically determinate support). Chosen
    among the vertex nearest the centroid and the ones farthest from it and from both."""
    from scipy.linalg import qr

    X = np.asarray(points, dtype=float)
    d = X.shape[1]
    a = int(np.argmin(np.linalg.norm(X - X.mean(axis=0), axis=1)))
    b = int(np.argmax(np.linalg.norm(X - X[a], axis=1)))
    nodes = [a, b]
    if d == 3:
        nodes.append(int(np.argmax(np.linalg.norm(np.cross(X - X[a], X[b] - X[a]), axis=1))))
    nodes = np.unique(nodes)
    dofs = vector_dofs(nodes[:, None], d).ravel()
    R = rigid_modes(X)[dofs]
    _, _, piv = qr(R.T, pivoting=True)
    return np.sort(dofs[piv[:R.shape[1]]])


@dataclass
class _State(SimplexState):
    u: FloatArray  # (n_dofs, d)
    value: float


class ComplianceObjective(CachedObjective):
    """Compliance ``J = ∫_Γ t·u`` of a linear elastic body, P1 or P2, in 2D or 3D.

    Parameters
    ----------
    points : (N, d) reference positions (they orient the facets outward)
    cells : (T, d+1) positive simplices
    clamped : (F, d) boundary facets with ``u = 0``; none: the body floats, its rigid
        motions are pinned at :func:`rigid_pins` (no stress: the compliance is that of
        the free body) and tractions that do not balance are refused; solved by
        ``factorize_spd`` whatever ``solver`` says
    tractions : sequence of ``(facets (F, d), stress (d, d))``: ``t = σ_g n`` on the facets
    E, nu : Young's modulus and Poisson ratio (plane stress in 2D)
    degree : 1 or 2
    solver : ``"auto"``, ``"direct"`` (CHOLMOD on the clamped-reduced SPD system, nested
        dissection ordering) or ``"amg"`` (CG preconditioned by smoothed aggregation with
        the rigid modes): :func:`~.elasticity.factorize`, the elasticity metric's solvers

    Notes
    -----
    ``value(Q)`` then ``derivative(Q)`` costs one solve: the adjoint is ``u`` itself.
    """

    def __init__(self, points: FloatArray, cells: IntArray, clamped: IntArray, tractions,
                 *, E: float = 1.0, nu: float = 0.3, degree: int = 1,
                 solver: str = "auto", rtol: float = 1e-10) -> None:
        points = np.asarray(points, dtype=float)
        self.cells = np.asarray(cells, dtype=np.int64)
        self.dim = points.shape[1]
        self.space = LagrangeSpace(self.cells, len(points), degree)
        self.lam, self.mu = elastic_lame(E, nu, self.dim)
        clamped = np.asarray(clamped, dtype=np.int64).reshape(-1, self.dim)
        # no clamped facet: the body floats, and its rigid motions are pinned by d(d+1)/2
        # dofs that hold it without stress (compliance needs loads in equilibrium then)
        self.floating = not len(clamped)
        fixed = (np.unique(self.space.facet_dofs(clamped)) if len(clamped)
                 else np.zeros(0, np.int64))
        self.clamped = rigid_pins(points) if self.floating else vector_dofs(fixed, self.dim).ravel()
        self._free_nodes = np.setdiff1d(np.arange(self.space.n_dofs), fixed)
        self._free = np.setdiff1d(np.arange(self.dim * self.space.n_dofs), self.clamped)
        facets, stresses = [], []
        for f, s in tractions:
            f = oriented_facets(points, self.cells, np.asarray(f, dtype=np.int64))
            s = np.asarray(s, dtype=float)
            if s.shape != (self.dim, self.dim) or not np.isfinite(s).all():
                raise MeshoptError(
                    f"a traction stress must be a finite {self.dim}×{self.dim} tensor")
            facets.append(f)
            stresses.append(np.broadcast_to(s, (len(f), self.dim, self.dim)))
        self.facets = np.concatenate(facets) if facets else np.zeros((0, self.dim), np.int64)
        self.stresses = np.concatenate(stresses) if stresses else np.zeros((0, self.dim, self.dim))
        self._facet_dofs = self.space.facet_dofs(self.facets)
        self._omega = facet_weights(self.dim, degree)
        self.solver, self.rtol = solver, float(rtol)
        if self.floating:
            b = self.load(points).ravel()
            R = rigid_modes(self.space.dof_points(points))
            size = np.ptp(points, axis=0).max()
            scale = np.abs(b).sum() * np.r_[np.ones(self.dim), np.full(len(R[0]) - self.dim, size)]
            if np.any(np.abs(b @ R) > 1e-9 * scale):
                raise MeshoptError("the tractions are not in equilibrium: a body with no "
                                   "clamped group needs loads with zero net force and moment")

    def load(self, Q: FloatArray) -> FloatArray:
        """The traction load ``(n_dofs, d)``."""
        force = np.einsum("fij,fj->fi", self.stresses, facet_normals(Q, self.facets))
        per = self._omega[None, :, None] * force[:, None, :]
        return scatter_corners(self._facet_dofs, per, self.space.n_dofs)

    def stiffness(self, Q: FloatArray, geo: Geometry | None = None):
        """The vector stiffness matrix ``(d n_dofs, d n_dofs)`` at ``Q``."""
        geo = geometry(Q, self.cells) if geo is None else geo
        dofs = vector_dofs(self.space.cell_dofs, self.dim)
        n = self.dim * self.space.n_dofs
        return assemble(dofs, dofs, vector_stiffness(self.space, geo, self.lam, self.mu), (n, n))

    def _compute(self, Q) -> _State:
        Q = np.array(Q, dtype=float)
        geo = geometry(Q, self.cells)
        b = self.load(Q).ravel()
        K = self.stiffness(Q, geo)
        # the elasticity metric's solvers: CHOLMOD on a geometric nested-dissection
        # ordering, or CG preconditioned by smoothed aggregation with the rigid modes
        free = self._free
        u = np.zeros_like(b)
        if self.floating:
            u[free] = factorize_spd(K[free][:, free].tocsc())(b[free])
        else:
            points = self.space.dof_points(Q)[self._free_nodes]
            u[free] = factorize(K[free][:, free], points, self.solver, self.rtol).solve(b[free])
        return _State(Q, geo, u.reshape(-1, self.dim), float(b @ u))

    def displacement(self, Q: FloatArray) -> FloatArray:
        """Nodal displacements ``(n_dofs, d)`` (P2: vertices, then edge midpoints)."""
        return self._state(Q).u.copy()

    def derivative(self, Q: FloatArray) -> FloatArray:
        """Exact ``dJ/dQ`` ``(N, d)``, every node included."""
        s = self._state(Q)
        n = len(s.Q)
        S = strain_energy_tensor(self.space, s.geo, s.u, self.lam, self.mu)
        g = -node_gradient(S, s.geo, self.cells, n)
        ubar = np.einsum("a,fai->fi", self._omega, s.u[self._facet_dofs])
        c = np.einsum("fji,fj->fi", self.stresses, ubar)  # σ_gᵀ ū_F
        return g + 2.0 * facet_normal_gradient(s.Q, self.facets, c, n)
