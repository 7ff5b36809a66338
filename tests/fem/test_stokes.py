"""Taylor–Hood Stokes flow and the dissipation objective (fem.stokes): Poiseuille flow
reproduced exactly, scikit-fem's independent Taylor–Hood assembly, MINRES+AMG against
the direct solve, Taylor tests of the node derivative in 2D and 3D."""

from __future__ import annotations

import numpy as np
import pytest

from fem_helpers import box_mesh, random_direction
from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.errors import MeshoptError
from meshopt_toolkit.fem.simplex import all_boundary_facets
from meshopt_toolkit.fem.stokes import StokesDissipation

skfem = pytest.importorskip("skfem")


def obstacle(d, n=4, jitter=0.2):
    """The unit box without its central cube ``[¼, ¾]^d``: points, cells, the outer and
    the obstacle's facets."""
    P, T, _ = box_mesh(d, n, jitter=jitter)
    T = T[~np.all(np.abs(P[T].mean(axis=1) - 0.5) < 0.25, axis=1)]
    used = np.unique(T)
    remap = np.full(len(P), -1)
    remap[used] = np.arange(len(used))
    P, T = P[used], remap[T]
    F = all_boundary_facets(T)
    outer = np.any(np.all((P[F] < 1e-12) | (P[F] > 1 - 1e-12), axis=1), axis=1)
    return P, T, F[outer], F[~outer]


def drag(d, solver="direct", mu=0.7, jitter=0.2):
    P, T, outer, inner = obstacle(d, jitter=jitter)
    e = np.eye(d)[0]
    return P, T, StokesDissipation(P, T, [(outer, np.zeros(d)), (inner, e)], mu=mu,
                                   solver=solver, rtol=1e-12)


@pytest.mark.parametrize("d", [2, 3])
def test_poiseuille_is_reproduced_exactly(d):
    # u = (y(1 − y), 0, …), p = −2μx + c solve Stokes; P2–P1 holds them exactly, and
    # ∫ 2μ|ε(u)|² = μ ∫ (1 − 2y)² = μ |Ω| / 3 on [0, 2] × [0, 1]^(d−1)
    mu = 0.7
    P, T, _ = box_mesh(d, 3, jitter=0.3, lengths=[2] + [1] * (d - 1))

    def exact(X):
        u = np.zeros_like(X)
        u[:, 0] = X[:, 1] * (1 - X[:, 1])
        return u

    j = StokesDissipation(P, T, [(all_boundary_facets(T), exact)], mu=mu, solver="direct",
                          rtol=1e-13)
    np.testing.assert_allclose(j.velocity(P), exact(j.space.dof_points(P)), atol=1e-12)
    dp = j.pressure(P) + 2 * mu * P[:, 0]
    assert np.ptp(dp) < 1e-11
    assert np.isclose(j.value(P), mu * 2 / 3, rtol=1e-13)
    with pytest.raises(MeshoptError):
        j.derivative(P)  # callable data: its motion is not differentiated


@pytest.mark.parametrize("d", [2, 3])
def test_drag_matches_scikit_fem_taylor_hood(d):
    from skfem.helpers import ddot, div, sym_grad

    mu = 0.7
    P, T, j = drag(d, mu=mu, jitter=0.0)  # the obstacle's nodes found by position
    m = (skfem.MeshTri if d == 2 else skfem.MeshTet)(P.T.copy(), T.T.copy())
    P2, P1 = ((skfem.ElementTriP2(), skfem.ElementTriP1()) if d == 2
              else (skfem.ElementTetP2(), skfem.ElementTetP1()))
    ub = skfem.Basis(m, skfem.ElementVector(P2))
    pb = skfem.Basis(m, P1, quadrature=ub.quadrature)

    @skfem.BilinearForm
    def viscous(u, v, w):
        return 2 * mu * ddot(sym_grad(u), sym_grad(v))

    @skfem.BilinearForm
    def divergence(u, q, w):
        return -div(u) * q

    A = skfem.asm(viscous, ub)
    B = skfem.asm(divergence, ub, pb)
    import scipy.sparse as sp
    K = sp.bmat([[A, B.T], [B, None]], format="csr")
    x = np.zeros(K.shape[0])
    boundary = ub.get_dofs()
    inner = ub.get_dofs(lambda X: np.all(np.abs(X - 0.5) < 0.25 + 1e-12, axis=0))
    x[inner.all("u^1")] = 1.0
    D = np.concatenate([boundary.all(), [A.shape[0]]])  # and the first pressure node
    x = skfem.solve(*skfem.condense(K, np.zeros_like(x), x=x, D=D))
    u = x[:A.shape[0]]
    assert np.isclose(j.value(P), u @ A @ u, rtol=1e-10)


@pytest.mark.parametrize("d", [2, 3])
def test_minres_amg_agrees_with_the_schur_complement_solve(d):
    P, T, direct = drag(d, "direct")
    _, _, iterative = drag(d, "amg")
    assert np.isclose(iterative.value(P), direct.value(P), rtol=1e-9)
    np.testing.assert_allclose(iterative.pressure(P), direct.pressure(P),
                               atol=1e-7 * np.abs(direct.pressure(P)).max())


@pytest.mark.parametrize("d", [2, 3])
def test_dissipation_derivative_taylor(d):
    P, T, j = drag(d)
    res = check_gradient(j.value, j.derivative, P, random_direction(P), eps0=1e-2)
    assert abs(res.order - 2) < 0.1, res


def test_dissipation_is_invariant_under_translation():
    # a translation changes neither the flow nor J: the derivative sums to zero
    P, T, j = drag(2)
    g = j.derivative(P)
    np.testing.assert_allclose(g.sum(axis=0), 0, atol=1e-10 * np.abs(g).max())
