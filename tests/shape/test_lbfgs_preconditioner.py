"""Preconditioned L-BFGS (meshopt_toolkit.shape.preconditioners): the penalty
Hessian blocks against the penalty's own Hessian-vector product, the two-loop recursion
with an SPD ``H_0 = γ B⁻¹`` (descent directions; Newton in one step when ``B`` is the
exact Hessian of a quadratic), and the same minimizer as steepest descent on the thesis'
problem."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh
from hypothesis import given, settings
from hypothesis import strategies as st

import meshopt_toolkit as mt
from meshopt_toolkit.errors import OptimizationError, OptionError
from meshopt_toolkit.fem.poisson import PoissonObjective
from meshopt_toolkit.optimize import (OptimizeOptions, default_metric_beta, optimize,
                                      thesis_penalty_beta)
from meshopt_toolkit.penalties import QualityPenalty
from meshopt_toolkit.riemannian.metrics import EuclideanMetric
from meshopt_toolkit.shape import LBFGSMemory
from meshopt_toolkit.shape.driver import run_descent
from meshopt_toolkit.shape.preconditioners import PenaltyHessian, quality_hessian_blocks
from meshopt_toolkit.shape.problem import ShapeProblem


@pytest.fixture(scope="module")
def disc():
    return mt.load(mt.data_path("disc_146.msh")).as_planar()


def _set2(mesh, variant, method, max_iterations=1000, **options):
    return optimize(mesh, PoissonObjective(mesh), variant=variant, method=method,
                    penalty=thesis_penalty_beta(2, mesh.n_vertices),
                    metric_beta=default_metric_beta(mesh.n_vertices), max_iterations=max_iterations,
                    options=options)


def test_quality_hessian_blocks_assemble_the_penalty_hessian():
    mesh = grid_mesh(4, jitter=0.2, seed=3)
    rng = np.random.default_rng(0)
    beta1 = 0.7
    pen = QualityPenalty(mesh, beta=(beta1, 0.0, 0.0, 0.0))
    V = rng.normal(size=mesh.points.shape)
    H = quality_hessian_blocks(mesh.points, mesh.triangles,
                               beta1 / (4 * np.sqrt(3) * mesh.n_triangles))
    dofs = (2 * mesh.triangles[:, :, None] + np.arange(2)).reshape(-1, 6)
    hv = np.zeros(mesh.points.size)
    np.add.at(hv, dofs, np.einsum("tij,tj->ti", H, V.ravel()[dofs]))
    ref = pen.hvp(mesh.points, V).ravel()
    np.testing.assert_allclose(hv, ref, atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("fixed", [False, True])
def test_penalty_preconditioner_is_spd_on_the_free_dofs(fixed):
    mesh = grid_mesh(4, jitter=0.3, seed=1)
    pen = QualityPenalty(mesh, beta=(0.1, 0.01, 0.0, 0.0))  # β4 = 0: the floor alone
    free = None
    if fixed:
        free = np.ones(mesh.n_vertices, bool)
        free[mesh.boundary_vertices] = False
    B = PenaltyHessian(mesh, pen, free).matrix(mesh.points).toarray()
    np.testing.assert_allclose(B, B.T, atol=1e-14)
    assert np.linalg.eigvalsh(B).min() > 0
    assert B.shape[0] == 2 * (mesh.n_vertices if free is None else free.sum())


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), pairs=st.integers(1, 6))
def test_two_loop_with_an_spd_h0_gives_a_descent_direction(seed, pairs):
    rng = np.random.default_rng(seed)
    n = 8
    R = rng.normal(size=(n, n))
    B = R @ R.T + 0.1 * np.eye(n)  # SPD, badly scaled
    mem = LBFGSMemory(size=4)
    for _ in range(pairs):
        s = rng.normal(size=(n // 2, 2))
        y = rng.normal(size=(n // 2, 2))
        if np.sum(s * y) <= 0:
            y = -y
        mem.update(s, y, slope=-1.0)
    P = rng.normal(size=(n // 2, 2))
    d = mem.direction(P, riesz=lambda X: X,
                      h0=lambda X: np.linalg.solve(B, X.ravel()).reshape(X.shape))
    assert np.sum(P * d) < 0


class _Quadratic:
    def __init__(self, A, c):
        self.A, self.c = A, c

    def value(self, Q):
        r = Q.ravel() - self.c
        return 0.5 * float(r @ self.A @ r)

    def derivative(self, Q):
        return (self.A @ (Q.ravel() - self.c)).reshape(Q.shape)


@pytest.mark.parametrize("seed", [0, 1])
def test_exact_inverse_hessian_as_h0_converges_in_one_iteration(seed):
    """With ``B = A`` (the Hessian of a quadratic) the first direction is Newton's and the
    unit step, tried first, lands on the minimizer; BFGS updates with ``ŷ = A s`` keep
    ``H_k = A⁻¹`` (and ``γ = 1``)."""
    mesh = grid_mesh(3, jitter=0.1, seed=seed)
    rng = np.random.default_rng(seed)
    n = mesh.points.size
    U, _ = np.linalg.qr(rng.normal(size=(n, n)))
    A = U @ np.diag(np.geomspace(1.0, 1e3, n)) @ U.T
    c = mesh.points.ravel() + 0.02 * rng.uniform(-1, 1, n)
    obj = _Quadratic(A, c)
    problem = ShapeProblem(obj, None, EuclideanMetric(), mesh.triangles, mesh.boundary_edges)

    def h0(Q, P):
        return np.linalg.solve(A, P.ravel()).reshape(P.shape)

    options = OptimizeOptions(gtol=1e-9, tolerance=None, memory=5, sigma=1e-4, c2=None,
                              segment_fraction=1.0, min_step=1e-10)
    kw = dict(method="lbfgs", variant="euclidean-euclidean", retraction=None,
              max_iterations=50, options=options, callback=None)
    res = run_descent(mesh, problem, h0=h0, **kw)
    assert res.status == "converged" and res.nit == 1
    np.testing.assert_allclose(res.x.ravel(), c, atol=1e-9)
    plain = run_descent(mesh, problem, **kw)
    assert plain.nit > 3  # condition number 1e3 without the preconditioner
    # with pairs in memory the direction is still Newton's
    mem = LBFGSMemory(size=3)
    for _ in range(3):
        s = rng.normal(size=mesh.points.shape)
        mem.update(s, (A @ s.ravel()).reshape(s.shape), slope=-1.0)
    P = rng.normal(size=mesh.points.shape)
    d = mem.direction(P, riesz=lambda X: X, h0=lambda X: h0(None, X))
    np.testing.assert_allclose(d, -h0(None, P), rtol=1e-8, atol=1e-12)


@pytest.mark.parametrize("variant", ["complete-euclidean", "complete-complete"])
def test_preconditioned_lbfgs_reaches_steepest_descents_minimizer(disc, variant):
    """Table 6.4 set 2: the same optimum as steepest descent (within 2e-4), in ≤ 1/4 of
    its iterations (20 against 233-237 on disc_146)."""
    sd = _set2(disc, variant, "steepest")
    pre = _set2(disc, variant, "lbfgs")  # "auto": the penalty preconditioner
    none = _set2(disc, variant, "lbfgs", lbfgs_preconditioner="none")
    assert sd.success and pre.success and none.success
    assert abs(pre.fun - sd.fun) <= 2e-4 and abs(pre.fun - none.fun) <= 2e-5
    assert pre.nit <= 0.25 * sd.nit and pre.nit < none.nit
    assert np.abs(pre.x - none.x).max() < 5e-2  # flat directions: cond(∇²F) ≈ 900
    explicit = _set2(disc, variant, "lbfgs", lbfgs_preconditioner="penalty")
    assert explicit.nit == pre.nit and explicit.fun == pre.fun  # auto = penalty here


def test_elasticity_preconditioner_and_auto_on_other_variants(disc):
    auto = _set2(disc, "elasticity-euclidean", "lbfgs", max_iterations=8, gtol=None, tolerance=None)
    none = _set2(disc, "elasticity-euclidean", "lbfgs", max_iterations=8, gtol=None, tolerance=None,
                 lbfgs_preconditioner="none")
    assert auto.fun == none.fun  # auto is "none" off the complete metric
    el = _set2(disc, "complete-euclidean", "lbfgs", lbfgs_preconditioner="elasticity")
    assert el.success and el.fun < auto.fun


def test_preconditioner_option_is_checked(disc):
    obj = PoissonObjective(disc)
    with pytest.raises(OptionError, match="unknown lbfgs_preconditioner"):
        optimize(disc, obj, options=dict(lbfgs_preconditioner="newton"), penalty=None)
    with pytest.raises(OptionError, match="method='lbfgs' only"):
        optimize(disc, obj, method="cg", options=dict(lbfgs_preconditioner="penalty"), penalty=None)
    with pytest.raises(OptionError, match="needs a penalty"):
        optimize(disc, obj, variant="complete-euclidean",
                 options=dict(lbfgs_preconditioner="penalty"), penalty=None)
    # auto with cg, steepest or without a penalty quietly means "none"
    optimize(disc, obj, variant="complete-euclidean", method="cg", max_iterations=1, penalty=None)
    optimize(disc, obj, variant="complete-euclidean", max_iterations=1, penalty=None)
