"""The mesh-motion methods users compare us with, called as independent references.

Each ``*_motion(points, triangles, handles, targets)`` returns the moved node positions
``(N, 2)``; the handles are Dirichlet data (prescribed exactly) except for SLIM, where they
are a soft penalty. libigl (``pip install libigl``) and mfem (``pip install mfem``) are the
``bench`` extra, never runtime dependencies; a missing one raises ``ImportError`` and the
benchmark prints the row as unavailable. How to call them: ../shared/ANCHORS.md.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from meshopt_toolkit.fem.elasticity import BlockPattern, element_blocks, lame_parameters
from meshopt_toolkit.kernels.triangles import signed_areas
from meshopt_toolkit.solvers import factorize_spd, nested_dissection


def _free_solve(A: sp.spmatrix, handles: np.ndarray, values: np.ndarray, n_vertices: int,
                dofs_per_vertex: int, points: np.ndarray) -> np.ndarray:
    """Solve ``A u = 0`` with ``u = values`` on the handles' dofs (interleaved ordering),
    factorized in the geometric nested-dissection ordering of ``points``."""
    d = dofs_per_vertex
    fixed = np.zeros(n_vertices * d, bool)
    fixed[(d * handles[:, None] + np.arange(d)).ravel()] = True
    u = np.zeros(n_vertices * d)
    u[fixed] = values.ravel()
    A = A.tocsr()
    Aff = A[~fixed][:, ~fixed].tocsc()
    moving = np.ones(n_vertices, bool)
    moving[handles] = False
    # the ordering move's own factorizations use: the fastest SuperLU gets on these meshes
    order = nested_dissection(points[moving], Aff, d)
    u[~fixed] = factorize_spd(Aff, order)(-(A[~fixed][:, fixed] @ u[fixed]))
    return u


def elasticity_motion(points, triangles, handles, targets, nu: float = 0.3) -> np.ndarray:
    """Linear elasticity with Young's modulus 1/area per element (Jacobian stiffening, the
    FEniCS/OpenFOAM/SU2 mesh-motion default), boundary displacement as Dirichlet data: one
    assembly, one factorization, one solve — the cost unit of the motion benchmarks."""
    lam, mu = lame_parameters(1.0, nu)
    blocks = element_blocks(points, triangles, lam, mu, 0.0)
    blocks /= signed_areas(points, triangles)[:, None, None, None, None]
    A = BlockPattern.from_triangles(triangles, len(points)).assemble(blocks)
    u = _free_solve(A, handles, targets - points[handles], len(points), 2, points)
    return points + u.reshape(-1, 2)


def harmonic_motion(points, triangles, handles, targets, order: int = 1) -> np.ndarray:
    """libigl's (bi)harmonic extension of the handle positions (order 1 or 2)."""
    import igl

    return np.asarray(igl.harmonic(points, triangles.astype(np.int64), handles.astype(np.int64),
                                   np.asarray(targets, float), order))


def arap_motion(points, triangles, handles, targets, iterations: int = 50) -> np.ndarray:
    """libigl's as-rigid-as-possible deformation, started from the harmonic extension."""
    import igl

    data = igl.ARAPData()
    data.max_iter = iterations
    igl.arap_precomputation(points, triangles.astype(np.int64), 2, handles.astype(np.int32), data)
    start = harmonic_motion(points, triangles, handles, targets)
    return np.asarray(igl.arap_solve(np.asarray(targets, float), data, start))


def slim_motion(points, triangles, handles, targets, iterations: int = 50,
                soft_weight: float = 1e5) -> np.ndarray:
    """libigl's SLIM (symmetric Dirichlet, never inverts; the handles are a soft penalty, so
    they miss their targets on large motions), started from the input (valid)."""
    import igl

    V3 = np.asfortranarray(np.column_stack([points, np.zeros(len(points))]))
    F = np.asfortranarray(triangles.astype(np.int32))
    data = igl.slim_precompute(V3, F, np.asarray(points, float),
                               igl.MappingEnergyType.SYMMETRIC_DIRICHLET,
                               handles.astype(np.int32), np.asarray(targets, float), soft_weight)
    return np.asarray(igl.slim_solve(data, iterations))[:, :2]


def tmop_motion(points, triangles, handles, targets) -> np.ndarray:
    """mfem's TMOP from the elasticity start: worst-case untangler (metric 4, shifted
    barrier) when the start is tangled, then shape optimization (metric 2); handles fixed."""
    import mfem.ser as mfem
    from mfem._ser import tmop, tmop_tools

    n = len(points)
    mesh = mfem.Mesh(2, n, len(triangles), 0, 2)
    for p in points:
        mesh.AddVertex([float(p[0]), float(p[1])])
    for t in triangles:
        mesh.AddTriangle([int(i) for i in t])
    mesh.FinalizeTriMesh(1, 1, True)
    fec = mfem.H1_FECollection(1, 2)
    fes = mfem.FiniteElementSpace(mesh, fec, 2, mfem.Ordering.byNODES)
    mesh.SetNodalFESpace(fes)
    x0 = mfem.GridFunction(fes)
    x0.Assign(np.concatenate([points[:, 0], points[:, 1]]))
    start = elasticity_motion(points, triangles, handles, targets)
    x = mfem.GridFunction(fes)
    x.Assign(np.concatenate([start[:, 0], start[:, 1]]))
    mesh.NewNodes(x, False)
    essential = mfem.intArray(list(map(int, np.concatenate([handles, handles + n]))))
    ir = mfem.IntegrationRules(0, mfem.Quadrature1D.GaussLobatto)

    def optimize(metric, min_det=None):
        target = tmop.TargetConstructor(tmop.TargetConstructor.IDEAL_SHAPE_EQUAL_SIZE)
        target.SetNodes(x0)
        integ = tmop.TMOP_Integrator(metric, target)
        integ.SetIntegrationRules(ir, 8)
        form = mfem.NonlinearForm(fes)
        form.AddDomainIntegrator(integ)
        form.SetEssentialVDofs(essential)
        solver = tmop_tools.TMOPNewtonSolver(ir.Get(mfem.Geometry.TRIANGLE, 8), 0)
        if min_det is not None:
            p = mfem.doublep()
            p.assign(min_det)
            solver.SetMinDetPtr(p)
        minres = mfem.MINRESSolver()
        minres.SetMaxIter(100)
        minres.SetRelTol(1e-8)
        solver.SetPreconditioner(minres)
        solver.SetOperator(form)
        solver.SetMaxIter(200)
        solver.SetRelTol(1e-10)
        solver.SetAbsTol(0.0)
        solver.SetPrintLevel(-1)
        tv = x.GetTrueVector()
        solver.Mult(mfem.Vector(0), tv)
        x.SetFromTrueVector()
        return metric, target, integ, form, solver, minres  # keep alive until done

    current = np.column_stack([x.GetDataArray()[:n], x.GetDataArray()[n:]]).copy()
    min_det = float(signed_areas(current, triangles).min())
    if min_det <= 0:
        W = tmop.TMOP_WorstCaseUntangleOptimizer_Metric
        base = tmop.TMOP_Metric_004()
        worst = W(base, 2, 1.5, 1e-3, 1e-3, W.BarrierType_Shifted, W.WorstCaseType__None)
        _alive = optimize(worst, 2.0 * min_det)  # noqa: F841
    _alive2 = optimize(tmop.TMOP_Metric_002())  # noqa: F841
    out = np.column_stack([x.GetDataArray()[:n], x.GetDataArray()[n:]]).copy()
    return out
