"""Linear elasticity and the compliance objective (fem.linear_elasticity): scikit-fem's
independent assembly on the same mesh, closed-form energies and Taylor tests of the exact
node derivative, P1 and P2, in 2D (plane stress) and 3D."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fem_helpers import box_mesh, random_direction
from meshopt_toolkit.fem.simplex import all_boundary_facets as boundary_facets
from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.errors import MeshoptError
from meshopt_toolkit.fem.linear_elasticity import ComplianceObjective

skfem = pytest.importorskip("skfem")

CASES = [(2, 1), (2, 2), (3, 1), (3, 2)]


def bar(d, degree, n=3, jitter=0.3, top_load=True, solver="direct"):
    """A bar [0, 2] × [0, 1]^(d-1) clamped at x = 0, pulled and sheared at x = 2, pressed
    on y = 1."""
    P, T, _ = box_mesh(d, n, jitter=jitter, lengths=[2] + [1] * (d - 1))
    F = boundary_facets(T)
    X = P[F]
    s = np.zeros((d, d))
    s[0, 0], s[0, 1], s[1, 0] = 1.0, 0.3, 0.3
    press = np.zeros((d, d))
    press[1, 1] = -0.5
    loads = [(F[np.all(X[..., 0] > 2 - 1e-12, axis=1)], s)]
    if top_load:
        loads.append((F[np.all(X[..., 1] > 1 - 1e-12, axis=1)], press))
    j = ComplianceObjective(P, T, F[np.all(X[..., 0] < 1e-12, axis=1)], loads, E=2.0, nu=0.3,
                            degree=degree, solver=solver, rtol=1e-12)
    return P, T, j, s


@pytest.mark.parametrize("d, degree", CASES)
def test_matches_scikit_fem(d, degree):
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    P, T, j, s = bar(d, degree, top_load=False)
    m = (skfem.MeshTri if d == 2 else skfem.MeshTet)(P.T.copy(), T.T.copy())
    el = {(2, 1): skfem.ElementTriP1, (2, 2): skfem.ElementTriP2,
          (3, 1): skfem.ElementTetP1, (3, 2): skfem.ElementTetP2}[d, degree]()
    basis = skfem.Basis(m, skfem.ElementVector(el))
    K = skfem.asm(linear_elasticity(j.lam, j.mu), basis)
    fb = skfem.FacetBasis(m, skfem.ElementVector(el),
                          facets=m.facets_satisfying(lambda X: X[0] > 2 - 1e-12))

    @skfem.LinearForm
    def traction(v, w):
        return dot(np.einsum("ij,j...->i...", s, w.n), v)

    f = skfem.asm(traction, fb)
    x = skfem.solve(*skfem.condense(K, f, D=basis.get_dofs(lambda X: X[0] < 1e-12).all()))
    assert np.isclose(j.value(P), f @ x, rtol=1e-12)
    u = j.displacement(P)[:len(P)]
    np.testing.assert_allclose(u, x[basis.nodal_dofs].T, atol=1e-11 * np.abs(u).max())


@pytest.mark.parametrize("d, degree", CASES)
def test_energy_of_a_uniform_stretch_in_closed_form(d, degree):
    # u = (x, 0, …): ε = e_1 ⊗ e_1, σ:ε = λ + 2μ = E/(1−ν²) (plane stress) or
    # E(1−ν)/((1+ν)(1−2ν)) (3D), over |Ω| = 2
    P, T, j, _ = bar(d, degree, jitter=0.3)
    u = np.zeros((j.space.n_dofs, d))
    u[:, 0] = j.space.dof_points(P)[:, 0]
    E, nu = 2.0, 0.3
    modulus = E / (1 - nu**2) if d == 2 else E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    assert np.isclose(u.ravel() @ j.stiffness(P) @ u.ravel(), 2 * modulus)


def test_uniaxial_load_equals_force_times_face_area():
    # Σ b = ∫_Γ σ_g n: the pulled face x = 2 of area 1 carries the force (1, 0.3, 0)
    P, T, j, _ = bar(3, 2, top_load=False)
    np.testing.assert_allclose(j.load(P).sum(axis=0), [1.0, 0.3, 0.0], atol=1e-14)


@pytest.mark.parametrize("d, degree", CASES)
def test_compliance_derivative_taylor(d, degree):
    P, T, j, _ = bar(d, degree)
    res = check_gradient(j.value, j.derivative, P, random_direction(P), eps0=1e-2)
    assert abs(res.order - 2) < 0.1, res


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**16), d=st.sampled_from([2, 3]), degree=st.sampled_from([1, 2]))
def test_derivative_of_a_translation_vanishes(seed, d, degree):
    # translating the body changes neither u nor J: Σ_a dJ/dx_a = 0 on any mesh
    P, T, _ = box_mesh(d, 2, jitter=0.5, seed=seed, lengths=[2] + [1] * (d - 1))
    F = boundary_facets(T)
    X = P[F][..., 0]
    j = ComplianceObjective(P, T, F[np.all(X < 1e-12, axis=1)],
                            [(F[np.all(X > 2 - 1e-12, axis=1)], np.eye(d))], degree=degree,
                            solver="direct")
    g = j.derivative(P)
    np.testing.assert_allclose(g.sum(axis=0), 0, atol=1e-11 * np.abs(g).max())


@pytest.mark.parametrize("d, degree", CASES)
def test_rigid_modes_span_the_kernel_and_amg_agrees(d, degree):
    from meshopt_toolkit.fem.elasticity import rigid_modes

    P, T, direct, _ = bar(d, degree)
    B = rigid_modes(direct.space.dof_points(P))
    assert B.shape[1] == (3 if d == 2 else 6)
    K = direct.stiffness(P)
    assert abs(K @ B).max() < 1e-12 * abs(K).max()
    _, _, iterative, _ = bar(d, degree, solver="amg")
    np.testing.assert_allclose(iterative.displacement(P), direct.displacement(P),
                               atol=1e-8 * np.abs(direct.displacement(P)).max())


def test_refuses_a_floating_body_out_of_equilibrium_and_bad_stress():
    P, T, _ = box_mesh(2, 2)
    F = boundary_facets(T)
    with pytest.raises(MeshoptError, match="equilibrium"):
        ComplianceObjective(P, T, np.zeros((0, 2), int), [(F[:1], np.eye(2))])
    with pytest.raises(MeshoptError):
        ComplianceObjective(P, T, F[:1], [(F, np.eye(3))])
