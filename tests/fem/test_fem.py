"""P1 kernels against scikit-fem and brute force; the shape-derivative kernel by Taylor tests."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from conftest import grid_mesh, square5

from meshopt_toolkit import fem
from meshopt_toolkit.errors import MeshoptError
from meshopt_toolkit.expressions import parse_expression
from meshopt_toolkit.diagnostics import check_gradient

skfem = pytest.importorskip("skfem")
from skfem.models.poisson import laplace


def centroid_basis(mesh):
    """scikit-fem P1 basis whose quadrature is exactly the one-point centroid rule."""
    m = skfem.MeshTri(mesh.points.T.copy(), mesh.triangles.T.copy(), sort_t=False)
    rule = (np.array([[1.0 / 3.0], [1.0 / 3.0]]), np.array([0.5]))
    basis = skfem.Basis(m, skfem.ElementTriP1(), quadrature=rule)
    X, W = basis.quadrature
    assert X.shape == (2, 1) and np.allclose(X, 1 / 3) and np.isclose(W.sum(), 0.5)
    return m, basis


def brute_element_stiffness(points, triangles):
    """``|K| ∇λ_a·∇λ_b`` with ∇λ from inverting the affine interpolation matrix."""
    out = []
    for tri in triangles:
        V = np.column_stack([np.ones(3), points[tri]])  # rows (1, x, y)
        C = np.linalg.inv(V)  # column a: coefficients of λ_a
        G = C[1:, :].T  # (3, 2) gradients
        area = 0.5 * abs(np.linalg.det(V))
        out.append(area * G @ G.T)
    return np.array(out)


MESHES = [square5(), grid_mesh(4, 0.3), grid_mesh(5, 0.4, seed=3).refine()]


@pytest.mark.parametrize("mesh", MESHES, ids=["square5", "grid4", "grid5-refined"])
def test_stiffness_against_brute_force_and_skfem(mesh):
    ke = fem.element_stiffness(mesh.points, mesh.triangles)
    np.testing.assert_allclose(ke, brute_element_stiffness(mesh.points, mesh.triangles),
                               atol=1e-12)
    K = fem.p1_stiffness(mesh.points, mesh.triangles)
    _, basis = centroid_basis(mesh)
    Kref = skfem.asm(laplace, basis)
    assert abs(K - Kref).max() < 1e-12
    assert abs(K - K.T).max() < 1e-14
    np.testing.assert_allclose(K @ np.ones(mesh.n_vertices), 0, atol=1e-12)
    # linear functions have zero energy only when constant; K is PSD
    assert np.linalg.eigvalsh(K.toarray()).min() > -1e-12


@pytest.mark.parametrize("mesh", MESHES[1:], ids=["grid4", "grid5-refined"])
def test_load_and_mass_against_skfem(mesh):
    r = parse_expression("sin(3*x)*exp(y) + x*y")
    b = fem.lumped_load(mesh.points, mesh.triangles, r(fem.centroids(mesh.points, mesh.triangles)))

    @skfem.LinearForm
    def load(v, w):
        return np.sin(3 * w.x[0]) * np.exp(w.x[1]) * v + w.x[0] * w.x[1] * v

    @skfem.LinearForm
    def one(v, w):
        return v

    _, basis = centroid_basis(mesh)
    np.testing.assert_allclose(b, skfem.asm(load, basis), atol=1e-14)
    m = fem.nodal_mass_weights(mesh.points, mesh.triangles)
    np.testing.assert_allclose(m, skfem.asm(one, basis), atol=1e-14)
    np.testing.assert_allclose(m.sum(), 1.0, rtol=1e-13)  # area of [0, 1]²


def test_mass_weights_integrate_p1_exactly(rng):
    mesh = grid_mesh(5, 0.4, seed=1)
    y = rng.standard_normal(mesh.n_vertices)
    m = fem.nodal_mass_weights(mesh.points, mesh.triangles)
    _, basis = centroid_basis(mesh)

    @skfem.Functional
    def integral(w):
        return w["y"]

    # a P1 function is linear per triangle: the centroid rule integrates it exactly
    assert abs(m @ y - integral.assemble(basis, y=basis.interpolate(y))) < 1e-13


def lagrangian(mesh, y, p, r):
    """``L(Q) = mᵀy + pᵀK(Q)y − pᵀb(Q)`` at fixed nodal ``y, p``."""
    tri = mesh.triangles

    def L(Q):
        K = fem.p1_stiffness(Q, tri)
        b = fem.lumped_load(Q, tri, r(fem.centroids(Q, tri)))
        return fem.nodal_mass_weights(Q, tri) @ y + p @ (K @ y) - p @ b

    def dL(Q):
        xi = fem.centroids(Q, tri)
        return fem.poisson_shape_derivative(Q, tri, y, p, r(xi), r.gradient(xi))

    return L, dL


@pytest.mark.parametrize("mesh", MESHES, ids=["square5", "grid4", "grid5-refined"])
@pytest.mark.parametrize("rhs", ["1", "2.5*(x1 + 0.4 - x2**2)**2 + x1**2 + x2**2 - 1",
                                 "sin(2*x)*exp(y)"])
def test_shape_derivative_kernel_taylor(mesh, rhs, rng):
    """The kernel is the exact Q-gradient of the Lagrangian for ANY y, p (nonzero on the
    boundary too), so each of its three parts is exercised by itself."""
    y = rng.standard_normal(mesh.n_vertices)
    p = rng.standard_normal(mesh.n_vertices)
    L, dL = lagrangian(mesh, y, p, parse_expression(rhs))
    h = mesh.diameter / np.sqrt(mesh.n_triangles)
    res = check_gradient(L, dL, mesh.points, rng=rng, eps0=0.05 * h)
    assert res.passed, res
    assert abs(res.order - 2) < 0.2, res


def test_area_term_alone(rng):
    """Only ``mᵀy``: the derivative is ``Σ_K s_y/3 · ∂A/∂q`` (y, p = 0 parts vanish)."""
    mesh = grid_mesh(3, 0.3)
    y = rng.standard_normal(mesh.n_vertices)
    zero = np.zeros(mesh.n_vertices)
    L, dL = lagrangian(mesh, y, zero, parse_expression("0"))
    res = check_gradient(L, dL, mesh.points, rng=rng, eps0=1e-2)
    assert res.passed and abs(res.order - 2) < 0.2, res


@pytest.mark.parametrize("method", ["direct", "amg"])
def test_solver_matches_spsolve(method, rng):
    mesh = grid_mesh(8, 0.3).refine()
    K = fem.p1_stiffness(mesh.points, mesh.triangles)
    D = mesh.boundary_vertices
    solver = fem.PoissonSolver(K, D, method=method, rtol=1e-12)
    assert solver.method == method
    free = np.setdiff1d(np.arange(mesh.n_vertices), D)
    for _ in range(2):  # one factorization/hierarchy, several right-hand sides
        b = rng.standard_normal(mesh.n_vertices)
        y = solver.solve(b)
        assert np.all(y[D] == 0)
        ref = spla.spsolve(K[free][:, free].tocsc(), b[free])
        np.testing.assert_allclose(y[free], ref, rtol=0, atol=1e-9 * abs(ref).max())


def test_solver_auto_and_errors():
    mesh = grid_mesh(3)
    K = fem.p1_stiffness(mesh.points, mesh.triangles)
    assert fem.PoissonSolver(K, mesh.boundary_vertices).method == "direct"
    with pytest.raises(MeshoptError, match="at least one Dirichlet"):
        fem.PoissonSolver(K, [])
    with pytest.raises(MeshoptError, match="out of range"):
        fem.PoissonSolver(K, [mesh.n_vertices])
    with pytest.raises(ValueError, match="solver must be one of"):
        fem.PoissonSolver(K, [0], method="cg")


def test_p1_edges_and_areas_come_from_the_kernels():
    """P1 assembly's component-major edges (``kernels.edges_xy``) equal ``edge_vectors``,
    close every triangle, and their areas equal ``signed_areas``."""
    from meshopt_toolkit.fem.p1 import _edges_and_areas
    from meshopt_toolkit.kernels.triangles import edge_vectors, signed_areas

    mesh = grid_mesh(3, 0.2)
    ex, ey, a = _edges_and_areas(mesh.points, mesh.triangles)
    e = np.stack([ex, ey], axis=-1)
    assert e.shape == (mesh.n_triangles, 3, 2)
    np.testing.assert_array_equal(e, edge_vectors(mesh.points, mesh.triangles))
    np.testing.assert_allclose(e.sum(axis=1), 0, atol=1e-15)
    p = mesh.points[mesh.triangles]
    np.testing.assert_array_equal(e[:, 0], p[:, 2] - p[:, 1])
    np.testing.assert_allclose(a, signed_areas(mesh.points, mesh.triangles), rtol=1e-14)
