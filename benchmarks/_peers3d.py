"""An independent drag for ``bench_shape3d.py``: scikit-fem's Taylor–Hood P2–P1 Stokes
assembly on a written ``.msh`` (tetrahedra, triangle groups), ``u = velocity`` on one
group and 0 on the rest of the boundary, ``∫ 2μ|ε(u)|²``.

Only the assembly and the boundary dofs are scikit-fem's; the saddle-point system is
solved by CG on its Schur complement over a CHOLMOD factor of the velocity block (generic
linear algebra: scipy's SuperLU takes too long on 3D P2 systems).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from _peers2d import read_groups, taylor_hood_forms
from meshopt_toolkit.solvers import factorize_spd, schur_complement_solve


def dissipation_skfem3d(path, group: str = "body", velocity=(1.0, 0.0, 0.0),
                        mu: float = 1.0) -> float:
    """``∫ 2μ|ε(u)|²`` of the Stokes flow in the tet mesh ``path``."""
    import skfem

    P, T, groups = read_groups(path, "tetra", "triangle")
    used = np.unique(T)  # gmsh may keep unused nodes
    remap = np.full(len(P), -1)
    remap[used] = np.arange(len(used))
    m = skfem.MeshTet(P[used].T.copy(), remap[T].T.copy())
    ub = skfem.Basis(m, skfem.ElementVector(skfem.ElementTetP2()), intorder=4)
    pb = skfem.Basis(m, skfem.ElementTetP1(), intorder=4)

    visc, bdiv = taylor_hood_forms(mu)
    A, B = visc.assemble(ub).tocsr(), bdiv.assemble(ub, pb).tocsr()
    index = {tuple(f): i for i, f in enumerate(np.sort(m.facets.T, axis=1).tolist())}
    facets = np.array([index[tuple(f)] for f in np.sort(remap[groups[group]], axis=1).tolist()])
    body = ub.get_dofs(facets)
    x = np.zeros(A.shape[0])
    for c, v in enumerate(velocity, start=1):
        for kind in (body.nodal, body.edge, body.facet):  # P2 in 3D: vertices and edges
            if f"u^{c}" in kind:
                x[kind[f"u^{c}"]] = v
    fixed = ub.get_dofs(m.boundary_facets()).all()
    free = np.setdiff1d(np.arange(A.shape[0]), fixed)
    Af, Bf = A[free][:, free], B[1:][:, free]  # the first pressure fixed
    rhs = -np.concatenate([(A @ x)[free], (B @ x)[1:]])
    mass = np.asarray(_p1_mass(pb).sum(axis=1)).ravel()[1:]  # lumped
    solve = schur_complement_solve(factorize_spd(sp.csc_matrix(Af)), Bf,
                                   lambda r: mu * r / mass, 1e-12, 3000)
    x[free] = solve(rhs)[:len(free)]
    return float(x @ A @ x)


def _p1_mass(pb):
    import skfem

    @skfem.BilinearForm
    def mass(p, q, w):
        return p * q

    return mass.assemble(pb)
