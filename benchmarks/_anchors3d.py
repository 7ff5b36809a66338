"""The tetrahedral mesh-motion methods users compare us with, as independent references.

Each ``*_motion(points, tets, handles, path)`` returns the moved node positions ``(N, 3)``;
``path(t)`` gives the handles' positions at ``t ∈ [0, 1]`` (``path(0)`` their rest
positions). One-shot methods use ``path(1)`` only, incremental ones follow the path. The
handles are Dirichlet data, prescribed exactly. libigl and mfem are the ``bench`` extra:
a missing one raises ``ImportError`` and the benchmark prints the row as unavailable.
How to call them: ../shared/ANCHORS.md.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from meshopt_toolkit.kernels.cell_maps import barycentric_gradients
from meshopt_toolkit.kernels.tetrahedra import signed_volumes as tet_signed_volumes
from meshopt_toolkit.solvers import factorize_spd

NU = 0.3  # Poisson ratio of the mesh-motion elasticity


def tet_gradients(points, tets):
    """Barycentric gradients ``γ`` (C, 4, 3) and signed volumes (C,) of the tets."""
    return (barycentric_gradients(np.asarray(points, float)[tets]),
            tet_signed_volumes(points, tets))


def laplacian(points, tets) -> sp.csr_matrix:
    """P1 stiffness (cotangent) matrix ``Σ_e |V_e| γ γᵀ``: (N, N), SPD on the free nodes."""
    g, vol = tet_gradients(points, tets)
    K = np.abs(vol)[:, None, None] * np.einsum("cai,cbi->cab", g, g)
    rows = np.repeat(tets, 4, axis=1).ravel()
    cols = np.tile(tets, (1, 4)).ravel()
    n = len(points)
    return sp.csr_matrix((K.ravel(), (rows, cols)), shape=(n, n))


def elasticity_blocks(points, tets, lam: float, mu: float, weights=None) -> np.ndarray:
    """P1 vector linear-elasticity element matrices ``(C, 4, 3, 4, 3)``, entry
    ``[c, a, i, b, j] = w_c |V_c| (λ γ_ai γ_bj + μ γ_aj γ_bi + μ δ_ij γ_a·γ_b)``:
    the 12×12 stiffness of tet ``c`` in node-major ordering, scaled by ``weights`` (C,)."""
    g, vol = tet_gradients(points, tets)
    w = np.abs(vol) if weights is None else np.abs(vol) * weights
    # strain–displacement matrices in Voigt order (xx, yy, zz, yz, xz, xy): K = w BᵀDB
    B = np.zeros((len(tets), 6, 4, 3))
    for i in range(3):
        B[:, i, :, i] = g[:, :, i]
    for row, (i, j) in zip((3, 4, 5), ((1, 2), (0, 2), (0, 1))):
        B[:, row, :, i] = g[:, :, j]
        B[:, row, :, j] = g[:, :, i]
    B = B.reshape(-1, 6, 12)
    D = np.diag([2 * mu] * 3 + [mu] * 3)
    D[:3, :3] += lam
    K = np.matmul(np.swapaxes(B, 1, 2) * w[:, None, None], D @ B).reshape(-1, 4, 3, 4, 3)
    return K


def assemble_blocks(tets, blocks: np.ndarray, n_vertices: int) -> sp.csr_matrix:
    """Sum the element matrices into the global (3N, 3N) matrix, dof ``3 v + i``."""
    dof = (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 12).astype(np.int32)
    rows = np.repeat(dof, 12, axis=1).ravel()
    cols = np.tile(dof, (1, 12)).ravel()
    n = 3 * n_vertices
    return sp.coo_matrix((blocks.reshape(-1), (rows, cols)), shape=(n, n)).tocsr()


def lame(E: float = 1.0, nu: float = NU) -> tuple[float, float]:
    """Lamé parameters ``(λ, μ)`` of Young's modulus ``E`` and Poisson ratio ``nu`` (3D)."""
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def dirichlet_solve(A: sp.spmatrix, fixed_dofs: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Solve ``A u = 0`` on the free dofs with ``u = values`` (columns allowed) on
    ``fixed_dofs``, by one sparse Cholesky factorization (CHOLMOD where installed)."""
    n = A.shape[0]
    fixed = np.zeros(n, bool)
    fixed[fixed_dofs] = True
    values = np.asarray(values, float)
    u = np.zeros((n,) + values.shape[1:])
    u[fixed_dofs] = values
    A = A.tocsr()
    free = ~fixed
    solve = factorize_spd(A[free][:, free].tocsc())
    rhs = -(A[free][:, fixed] @ u[fixed])
    u[free] = solve(rhs) if rhs.ndim == 1 else np.column_stack(
        [solve(np.ascontiguousarray(c)) for c in rhs.T])
    return u


def harmonic_motion(points, tets, handles, path) -> np.ndarray:
    """Harmonic extension: each coordinate of the handles' displacement extended by the
    P1 Laplacian (Dirichlet on the handles)."""
    L = laplacian(points, tets)
    return points + dirichlet_solve(L, handles, path(1.0) - points[handles])


def elasticity_solve(points, tets, handles, displacement, nu: float = NU) -> np.ndarray:
    """One P1 vector linear-elasticity solve with Young's modulus ``1/V`` per tet (the
    FEniCS/OpenFOAM/SU2 mesh-motion default): assembly, sparse Cholesky, solve. Returns
    the displacement (N, 3) with ``displacement`` on the handles."""
    lam, mu = lame(1.0, nu)
    vol = np.abs(tet_signed_volumes(points, tets))
    A = assemble_blocks(tets, elasticity_blocks(points, tets, lam, mu, 1.0 / vol), len(points))
    dofs = (3 * np.asarray(handles)[:, None] + np.arange(3)).ravel()
    return dirichlet_solve(A, dofs, np.asarray(displacement, float).ravel()).reshape(-1, 3)


def elasticity_motion(points, tets, handles, path) -> np.ndarray:
    """Linear elasticity with E = 1/V, one shot: the cost unit of the benchmark."""
    return points + elasticity_solve(points, tets, handles, path(1.0) - points[handles])


def incremental_elasticity_motion(points, tets, handles, path, steps: int = 10) -> np.ndarray:
    """Elasticity with E = 1/V in ``steps`` increments along the handles' path, each
    re-assembled on the current mesh (the SU2/OpenFOAM practice for large motions)."""
    x = np.array(points, float)
    for k in range(1, steps + 1):
        x = x + elasticity_solve(x, tets, handles, path(k / steps) - x[handles])
    return x


def arap_motion(points, tets, handles, path, iterations: int = 50) -> np.ndarray:
    """libigl's as-rigid-as-possible deformation on tets, from the harmonic extension."""
    import igl

    data = igl.ARAPData()
    data.max_iter = iterations
    igl.arap_precomputation(np.asarray(points, float), tets.astype(np.int64), 3,
                            np.asarray(handles, np.int32), data)
    start = harmonic_motion(points, tets, handles, path)
    return np.asarray(igl.arap_solve(np.asarray(path(1.0), float), data, start))


def tmop_motion(points, tets, handles, path, iterations: int = 200) -> np.ndarray:
    """mfem's TMOP from the 10-step elasticity result: shape metric 303
    (``|T|²/(3 det(T)^{2/3}) − 1``, the 3D mean-ratio metric), Newton with MINRES, the
    handles fixed. TMOP's Newton only accepts steps that keep every Jacobian positive, so
    it needs a valid start; PyMFEM's worst-case untangler takes only the 2D base metrics
    4, 14 and 66, so a tangled start raises ``RuntimeError``."""
    import mfem.ser as mfem
    from mfem._ser import tmop, tmop_tools

    start = incremental_elasticity_motion(points, tets, handles, path)
    inverted = int((tet_signed_volumes(start, tets) <= 0).sum())
    if inverted:
        raise RuntimeError(f"start has {inverted} inverted tets")
    n = len(points)
    mesh = mfem.Mesh(3, n, len(tets), 0, 3)
    for p in points:
        mesh.AddVertex([float(c) for c in p])
    for t in tets:
        mesh.AddTet([int(i) for i in t])
    mesh.FinalizeTetMesh(1, 1, True)
    fec = mfem.H1_FECollection(1, 3)
    fes = mfem.FiniteElementSpace(mesh, fec, 3, mfem.Ordering.byNODES)
    mesh.SetNodalFESpace(fes)
    x0 = mfem.GridFunction(fes)
    x0.Assign(np.ascontiguousarray(points.T).ravel())
    x = mfem.GridFunction(fes)
    x.Assign(np.ascontiguousarray(start.T).ravel())
    mesh.NewNodes(x, False)
    handles = np.asarray(handles)
    essential = mfem.intArray(list(map(int, np.concatenate([handles, handles + n,
                                                            handles + 2 * n]))))
    ir = mfem.IntegrationRules(0, mfem.Quadrature1D.GaussLobatto)
    metric = tmop.TMOP_Metric_303()
    target = tmop.TargetConstructor(tmop.TargetConstructor.IDEAL_SHAPE_EQUAL_SIZE)
    target.SetNodes(x0)
    integ = tmop.TMOP_Integrator(metric, target)
    integ.SetIntegrationRules(ir, 8)
    form = mfem.NonlinearForm(fes)
    form.AddDomainIntegrator(integ)
    form.SetEssentialVDofs(essential)
    solver = tmop_tools.TMOPNewtonSolver(ir.Get(mfem.Geometry.TETRAHEDRON, 8), 0)
    minres = mfem.MINRESSolver()
    minres.SetMaxIter(100)
    minres.SetRelTol(1e-8)
    solver.SetPreconditioner(minres)
    solver.SetOperator(form)
    solver.SetMaxIter(iterations)
    solver.SetRelTol(1e-10)
    solver.SetAbsTol(0.0)
    solver.SetPrintLevel(-1)
    tv = x.GetTrueVector()
    solver.Mult(mfem.Vector(0), tv)
    x.SetFromTrueVector()
    out = np.asarray(x.GetDataArray()).reshape(3, n).T.copy()
    del solver, minres, form, integ, target, metric  # in this order: mfem holds pointers
    return out
