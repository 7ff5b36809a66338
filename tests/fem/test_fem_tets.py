"""Lagrange elements on triangles and tetrahedra (fem.simplex) and the Poisson objective
on them (fem.poisson_simplex): closed forms, scikit-fem, the planar objective, a
convergence rate and Taylor tests of the node derivative."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fem_helpers import box_mesh, random_direction
from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.errors import NotAdmissibleError
from meshopt_toolkit.fem.poisson import PoissonObjective
from meshopt_toolkit.fem.poisson_simplex import SimplexPoisson, p1_matrices
from meshopt_toolkit.fem.simplex import (LagrangeSpace, QUADRATURE, assemble, geometry,
                                         facet_normals, oriented_facets)
from meshopt_toolkit.mesh import PlanarMesh

skfem = pytest.importorskip("skfem")


@pytest.mark.parametrize("d", [2, 3])
def test_quadrature_integrates_quadratics_exactly(d):
    lam, w = QUADRATURE[d]
    from math import factorial
    # ∫ λ_0² over the reference simplex / its volume = 2 d! / (d + 2)!
    assert np.isclose(w @ lam[:, 0] ** 2, 2 * factorial(d) / factorial(d + 2))
    assert np.isclose(w @ (lam[:, 0] * lam[:, 1]), factorial(d) / factorial(d + 2))


@pytest.mark.parametrize("d", [2, 3])
def test_p1_stiffness_and_mass_match_scikit_fem(d):
    P, T, _ = box_mesh(d, 3, jitter=0.3)
    from skfem.models.poisson import laplace, unit_load
    m = (skfem.MeshTri if d == 2 else skfem.MeshTet)(P.T.copy(), T.T.copy())
    basis = skfem.Basis(m, skfem.ElementTriP1() if d == 2 else skfem.ElementTetP1())
    _, K, mass = p1_matrices(P, T)
    assert abs(K - skfem.asm(laplace, basis)).max() < 1e-13
    np.testing.assert_allclose(mass, skfem.asm(unit_load, basis), atol=1e-15)


@pytest.mark.parametrize("d", [2, 3])
def test_p2_stiffness_integrates_quadratics_exactly(d):
    # P2 interpolates quadratics exactly: uᵀ K v = ∫ ∇u·∇v over [0, 1]^d in closed form
    P, T, _ = box_mesh(d, 2, jitter=0.3)
    space = LagrangeSpace(T, len(P), degree=2)
    grads = space.gradients(geometry(P, T))
    w = QUADRATURE[d][1]
    vol = geometry(P, T).volumes
    local = np.einsum("q,tqad,tqbd->tab", w, grads, grads) * vol[:, None, None]
    K = assemble(space.cell_dofs, space.cell_dofs, local, (space.n_dofs,) * 2)
    u = space.interpolate(P, lambda X: X[:, 0] ** 2)           # ∇u = (2x, 0, …)
    v = space.interpolate(P, lambda X: X[:, 0] * X[:, 1])      # ∇v = (y, x, …)
    assert np.isclose(u @ K @ u, 4 / 3)
    assert np.isclose(u @ K @ v, 0.5)                          # ∫ 2xy = 1/2


@pytest.mark.parametrize("d", [2, 3])
def test_oriented_facets_point_outward(d):
    P, T, _ = box_mesh(d, 2)
    from meshopt_toolkit.fem.simplex import all_boundary_facets as boundary_facets
    F = oriented_facets(P, T, boundary_facets(T)[:, ::-1])
    N = facet_normals(P, F)
    # the divergence theorem: Σ N_F = 0, Σ x_F · N_F = d |Ω| with |Ω| = 1
    np.testing.assert_allclose(N.sum(axis=0), 0, atol=1e-14)
    assert np.isclose(np.einsum("fd,fd->", P[F].mean(axis=1), N), d)


def test_refuses_inverted_cells():
    P, T, _ = box_mesh(3, 1)
    with pytest.raises(NotAdmissibleError):
        geometry(P, T[:, [1, 0, 2, 3]])


@pytest.mark.parametrize("tracking", [None, "x*y"])
def test_planar_case_is_the_planar_objective(tracking):
    P, T, b = box_mesh(2, 6, jitter=0.3)
    ref = PoissonObjective(PlanarMesh(P, T), rhs="1+x*y", tracking=tracking, solver="direct")
    j = SimplexPoisson(T, b, rhs="1+x*y", tracking=tracking, solver="direct")
    assert np.isclose(j.value(P), ref.value(P), rtol=1e-13)
    np.testing.assert_allclose(j.derivative(P), ref.derivative(P), atol=1e-14)


@pytest.mark.parametrize("tracking", [None, "x*y + z"])
def test_tet_derivative_taylor(tracking):
    P, T, b = box_mesh(3, 3, jitter=0.3)
    j = SimplexPoisson(T, b, rhs="1 + x*y*z", tracking=tracking, solver="direct",
                       dirichlet_values=np.where(P[b, 2] > 0.5, 0.5, 0.0))
    res = check_gradient(j.value, j.derivative, P, random_direction(P), eps0=1e-2)
    assert abs(res.order - 2) < 0.1, res
    # the adjoint solves K p = −m with p = 0 on the Dirichlet nodes
    assert np.all(j.adjoint(P)[b] == 0)


def test_tet_convergence_rate_l2():
    # −Δy = 3π² y, y = Π sin(π x_i) on the unit cube, y = 0 on the boundary
    def exact(X):
        return np.prod(np.sin(np.pi * X), axis=1)

    hs, errors = [], []
    for n in (6, 10, 14):
        P, T, b = box_mesh(3, n)
        rhs = "3*pi**2*sin(pi*x)*sin(pi*y)*sin(pi*z)"
        y = SimplexPoisson(T, b, rhs=rhs, solver="direct").state(P)
        lam, w = QUADRATURE[3]
        X = np.einsum("qa,tad->tqd", lam, P[T])
        yh = np.einsum("qa,ta->tq", lam, y[T])
        misfit = yh - exact(X.reshape(-1, 3)).reshape(yh.shape)
        err2 = (geometry(P, T).volumes[:, None] * w * misfit**2).sum()
        hs.append(1 / n)
        errors.append(np.sqrt(err2))
    rate = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert 1.85 < rate < 2.15, (rate, errors)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**16), angle=st.floats(-3.0, 3.0))
def test_derivative_vanishes_on_rigid_motions(seed, angle):
    # with a constant load j is invariant under rigid motions: Σ_a g_a = 0, Σ_a x_a × g_a = 0
    P, T, b = box_mesh(3, 2, jitter=0.4, seed=seed)
    c, s = np.cos(angle), np.sin(angle)
    P = P @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T
    g = SimplexPoisson(T, b, rhs=1.0, solver="direct").derivative(P)
    scale = np.abs(g).max()
    np.testing.assert_allclose(g.sum(axis=0), 0, atol=1e-12 * scale)
    np.testing.assert_allclose(np.cross(P, g).sum(axis=0), 0, atol=1e-12 * scale)
