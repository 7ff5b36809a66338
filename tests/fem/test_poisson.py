"""PoissonObjective: adjoint derivative by Taylor tests, state against scikit-fem,
convergence to the exact ∫y on (−1, 1)², and the §6.1 behaviour on the 5-vertex square."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from conftest import grid_mesh, square5

from meshopt_toolkit import fem
from meshopt_toolkit.datasets import available, data_path
from meshopt_toolkit.errors import ExpressionError, MeshoptError, NotAdmissibleError
from meshopt_toolkit.mesh import PlanarMesh
from meshopt_toolkit.optimize import Objective
from meshopt_toolkit.fem.poisson import DEFAULT_RHS, PoissonObjective
from meshopt_toolkit.diagnostics import check_gradient


def _bump(X):
    return np.exp(-((X[:, 0] - 0.2) ** 2) - 2 * X[:, 1] ** 2) + X[:, 0]


def _bump_gradient(X):
    e = np.exp(-((X[:, 0] - 0.2) ** 2) - 2 * X[:, 1] ** 2)
    return np.column_stack([-2 * (X[:, 0] - 0.2) * e + 1, -4 * X[:, 1] * e])


class _BumpWithGradient:
    def __call__(self, X):
        return _bump(X)

    def gradient(self, X):
        return _bump_gradient(X)


RHS = {
    "one": 1.0,
    "default": "default",
    "sin-exp": "sin(3*x)*exp(y) - 0.5",
    "callable+gradient": _BumpWithGradient(),
    "callable (finite differences)": _bump,
}


def _disc_meshes():
    names = [n for n in ("disc_77.msh", "disc_146.msh") if n in available()]
    if not names:
        return []
    from meshopt_toolkit.io import load

    return [load(data_path(n)) for n in names]


def _meshes():
    out = {"square5": square5(), "grid": grid_mesh(4, 0.3), "grid-refined": grid_mesh(3, 0.3, 7).refine()}
    for k, m in enumerate(_disc_meshes()):
        out[f"disc{k}"] = m
    return out


MESHES = _meshes()


def _taylor(J, mesh, rng, direction=None):
    h = mesh.diameter / np.sqrt(mesh.n_triangles)
    return check_gradient(J.value, J.derivative, mesh.points, direction, rng=rng, eps0=0.02 * h)


@pytest.mark.parametrize("rhs", list(RHS), ids=list(RHS))
@pytest.mark.parametrize("name", list(MESHES))
def test_derivative_taylor_all_vertices(name, rhs, rng):
    mesh = MESHES[name]
    J = PoissonObjective(mesh, RHS[rhs])
    res = _taylor(J, mesh, rng)
    assert res.passed, res
    assert abs(res.order - 2) < 0.2, res


@pytest.mark.parametrize("rhs", ["default", "callable+gradient"])
def test_derivative_taylor_boundary_and_interior_separately(rhs, rng):
    mesh = grid_mesh(4, 0.3)
    J = PoissonObjective(mesh, RHS[rhs])
    on_boundary = np.zeros(mesh.n_vertices, bool)
    on_boundary[mesh.boundary_vertices] = True
    for mask in (on_boundary, ~on_boundary):
        V = rng.standard_normal((mesh.n_vertices, 2)) * mask[:, None]
        res = _taylor(J, mesh, rng, V)
        assert res.passed and abs(res.order - 2) < 0.2, res
    # boundary vertices really carry derivative
    assert np.abs(J.derivative(mesh.points)[on_boundary]).max() > 1e-3


def test_derivative_with_partial_dirichlet(rng):
    mesh = grid_mesh(4, 0.3)
    bottom = np.flatnonzero(mesh.points[:, 1] == 0)
    J = PoissonObjective(mesh, "default", dirichlet=bottom)
    assert np.array_equal(J.dirichlet, bottom)
    res = _taylor(J, mesh, rng)
    assert res.passed and abs(res.order - 2) < 0.2, res


def test_dirichlet_by_tag_name():
    base = grid_mesh(3)
    bottom = np.flatnonzero(base.points[:, 1] == 0)
    lines = np.column_stack([bottom[:-1], bottom[1:]])
    mesh = PlanarMesh(base.points, base.triangles, lines=lines,
                      line_tags=np.full(len(lines), 7), tag_names={"bottom": (7, 1)})
    J = PoissonObjective(mesh, 1.0, dirichlet="bottom")
    np.testing.assert_array_equal(J.dirichlet, bottom)
    y = J.state(mesh.points)
    assert np.all(y[bottom] == 0) and np.all(np.delete(y, bottom) > 0)


def _skfem_state(mesh, r_func, dirichlet):
    skfem = pytest.importorskip("skfem")
    from skfem.models.poisson import laplace

    m = skfem.MeshTri(mesh.points.T.copy(), mesh.triangles.T.copy(), sort_t=False)
    rule = (np.array([[1.0 / 3.0], [1.0 / 3.0]]), np.array([0.5]))  # centroid rule
    basis = skfem.Basis(m, skfem.ElementTriP1(), quadrature=rule)

    @skfem.LinearForm
    def load(v, w):
        X = np.stack([w.x[0].ravel(), w.x[1].ravel()], 1)
        return r_func(X).reshape(w.x[0].shape) * v

    K = skfem.asm(laplace, basis)
    b = skfem.asm(load, basis)
    return skfem.solve(*skfem.condense(K, b, D=dirichlet))


@pytest.mark.parametrize("rhs", ["one", "default", "callable+gradient"])
def test_state_matches_skfem(rhs):
    mesh = grid_mesh(6, 0.25, seed=5).refine()
    J = PoissonObjective(mesh, RHS[rhs])
    r = {"one": lambda X: np.ones(len(X)), "default": lambda X: (
        2.5 * (X[:, 0] + 0.4 - X[:, 1] ** 2) ** 2 + X[:, 0] ** 2 + X[:, 1] ** 2 - 1),
        "callable+gradient": _bump}[rhs]
    ref = _skfem_state(mesh, r, mesh.boundary_vertices)
    y = J.state(mesh.points)
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-10 * max(1.0, abs(ref).max()))
    # partial Dirichlet as well
    left = np.flatnonzero(mesh.points[:, 0] == 0)
    J2 = PoissonObjective(mesh, RHS[rhs], dirichlet=left)
    ref2 = _skfem_state(mesh, r, left)
    np.testing.assert_allclose(J2.state(mesh.points), ref2, atol=1e-10 * abs(ref2).max())


@functools.cache
def exact_integral_unit_load() -> float:
    """∫y for −Δy = 1 on (−1, 1)², y = 0 on the boundary, from the Fourier series.

    With φ_m(s) = sin(mπ(s+1)/2) on (−1, 1): 1 = Σ_{m,n odd} 16/(π² m n) φ_m φ_n,
    −Δ(φ_mφ_n) = (π/2)²(m² + n²) φ_mφ_n and ∫φ_m = 4/(mπ), so
    ∫y = Σ_{m,n odd} 1024 / (π⁶ m² n² (m² + n²)). The tail beyond m, n > M is below
    (π²/8)·Σ_{m>M} 1/m⁴ / 2 < 1e-10 for M = 4001 (rows summed in blocks).
    """
    odd = np.arange(1, 4002, 2, dtype=float)
    total = 0.0
    for block in np.array_split(odd, 8):
        mm = block[:, None] ** 2
        nn = odd[None, :] ** 2
        total += float((1.0 / (mm * nn * (mm + nn))).sum())
    return 1024.0 / np.pi**6 * total


def test_fourier_reference_is_the_thesis_value():
    # thesis: "approximately 0.5622" (its digits are truncated; the series gives 0.56231)
    assert abs(exact_integral_unit_load() - 0.5622) < 2e-4


def test_unit_load_converges_at_second_order():
    exact = exact_integral_unit_load()
    mesh = square5()
    values, hs = [], []
    for level in range(7):
        if level >= 2:
            values.append(PoissonObjective(mesh, 1.0).value(mesh.points))
            hs.append(2.0 ** -level)
        mesh = mesh.refine()
    values, hs = np.array(values), np.array(hs)
    # observed order from successive differences (needs no reference value) ...
    diffs = np.abs(np.diff(values))
    order_diff = np.polyfit(np.log(hs[:-1]), np.log(diffs), 1)[0]
    # ... and from the error against the Fourier series
    order_err = np.polyfit(np.log(hs), np.log(np.abs(values - exact)), 1)[0]
    assert abs(order_diff - 2) < 0.15, (order_diff, values)
    assert abs(order_err - 2) < 0.15, (order_err, values)
    assert abs(values[-1] - exact) < 2e-4


def j_square5(a: float, b: float) -> float:
    """Closed form of j(q5) for r ≡ 1 on the 5-vertex square with q5 = (a, b).

    One unknown y5: K55 = Σ_K |e_K|²/(4|K|) over the four triangles with the fixed outer
    edges |e_K| = 2, i.e. K55 = Σ_K 1/|K| with areas 1+b, 1−a, 1−b, 1+a; b5 = m5 = Σ|K|/3 = 4/3.
    So j = m5 y5 = (4/3)²/K55 = 8 / (9 (1/(1−a²) + 1/(1−b²))).
    """
    return 8.0 / (9.0 * (1.0 / (1 - a * a) + 1.0 / (1 - b * b)))


def test_square5_closed_form_and_no_minimizer(rng):
    mesh = square5()
    J = PoissonObjective(mesh, 1.0)
    assert J.value(mesh.points) == pytest.approx(4.0 / 9.0, rel=1e-14)
    fixed = mesh.points.copy()
    for a, b in rng.uniform(-0.95, 0.95, (5, 2)):
        Q = fixed.copy()
        Q[4] = a, b
        assert J.value(Q) == pytest.approx(j_square5(a, b), rel=1e-13)
        # derivative in q5 against the closed form: d/da of 8/(9 S), S = Σ 1/(1−s²)
        S = 1 / (1 - a * a) + 1 / (1 - b * b)
        dS = np.array([2 * a / (1 - a * a) ** 2, 2 * b / (1 - b * b) ** 2])
        np.testing.assert_allclose(J.derivative(Q)[4], -8 / (9 * S * S) * dS, rtol=1e-12)
    # j > 0 everywhere and → 0 as q5 approaches the boundary: no minimizer in M+
    values = []
    for eps in 10.0 ** -np.arange(1, 7):
        Q = fixed.copy()
        Q[4] = 0.0, 1.0 - eps
        values.append(J.value(Q))
    assert all(v > 0 for v in values)
    assert np.all(np.diff(values) < 0) and values[-1] < 1e-5
    Q = fixed.copy()
    Q[4] = 0.0, 1.0
    with pytest.raises(NotAdmissibleError):
        J.value(Q)


def test_cache_solves_state_once(monkeypatch):
    calls = []
    original = fem.PoissonSolver.solve

    def counting(self, b):
        calls.append(1)
        return original(self, b)

    monkeypatch.setattr(fem.PoissonSolver, "solve", counting)
    mesh = grid_mesh(4, 0.3)
    J = PoissonObjective(mesh)
    Q = mesh.points.copy()
    v = J.value(Q)
    assert len(calls) == 1
    v2, g = J.value_and_derivative(Q)
    assert v2 == v and len(calls) == 2  # + adjoint only
    np.testing.assert_array_equal(J.derivative(Q), g)
    assert len(calls) == 2
    Q[5] += 1e-3
    J.value(Q)
    assert len(calls) == 3
    Q[5] -= 1e-3  # the caller mutating its array does not fool the cache
    assert J.value(Q) == v


def test_adjoint_and_value_identities():
    mesh = grid_mesh(5, 0.3)
    J = PoissonObjective(mesh, 1.0)
    # r ≡ 1 makes b = m, hence p = −y and j = mᵀy = yᵀKy > 0
    np.testing.assert_allclose(J.adjoint(mesh.points), -J.state(mesh.points), atol=1e-15)
    assert J.value(mesh.points) > 0


def test_rhs_forms_agree(rng):
    mesh = grid_mesh(4, 0.3)
    Q = mesh.points
    ref = PoissonObjective(mesh, DEFAULT_RHS).value_and_derivative(Q)
    for rhs in ("default", lambda X: 2.5 * (X[:, 0] + 0.4 - X[:, 1] ** 2) ** 2
                + X[:, 0] ** 2 + X[:, 1] ** 2 - 1):
        v, g = PoissonObjective(mesh, rhs).value_and_derivative(Q)
        assert v == pytest.approx(ref[0], rel=1e-14)
        np.testing.assert_allclose(g, ref[1], atol=1e-8 * abs(ref[1]).max())
    v, g = PoissonObjective(mesh, _bump, rhs_gradient=_bump_gradient).value_and_derivative(Q)
    v2, g2 = PoissonObjective(mesh, _BumpWithGradient()).value_and_derivative(Q)
    assert v == v2
    np.testing.assert_allclose(g, g2, rtol=1e-14)


def test_amg_agrees_with_direct():
    mesh = grid_mesh(12, 0.3).refine()
    Q = mesh.points
    vd, gd = PoissonObjective(mesh, solver="direct").value_and_derivative(Q)
    va, ga = PoissonObjective(mesh, solver="amg", rtol=1e-12).value_and_derivative(Q)
    assert va == pytest.approx(vd, rel=1e-9)
    np.testing.assert_allclose(ga, gd, atol=1e-8 * abs(gd).max())


def test_errors():
    mesh = grid_mesh(3)
    J = PoissonObjective(mesh)
    Q = mesh.points.copy()
    Q[[5, 6]] = Q[[6, 5]]  # swap two interior vertices: inverted triangles
    with pytest.raises(NotAdmissibleError, match="inverted"):
        J.value(Q)
    with pytest.raises(NotAdmissibleError):
        J.derivative(np.full_like(Q, np.nan))
    with pytest.raises(MeshoptError, match="shape"):
        J.value(Q[:-1])
    with pytest.raises(ExpressionError, match="z is not defined for a planar mesh"):
        PoissonObjective(mesh, "z + 1")
    with pytest.raises(ExpressionError, match="unknown name 'w'"):
        PoissonObjective(mesh, "w + 1")
    with pytest.raises(ExpressionError, match="not finite"):
        PoissonObjective(mesh, "log(x - 0.5)").value(mesh.points)
    with pytest.raises(ExpressionError, match="shape"):
        PoissonObjective(mesh, lambda X: np.ones(3)).value(mesh.points)
    with pytest.raises(MeshoptError, match="at least one Dirichlet"):
        PoissonObjective(mesh, dirichlet=[])
    with pytest.raises(MeshoptError, match="out of range"):
        PoissonObjective(mesh, dirichlet=[999])
    with pytest.raises(ValueError, match="unknown solver"):
        PoissonObjective(mesh, solver="magic")


def test_satisfies_objective_protocol():
    assert isinstance(PoissonObjective(square5()), Objective)
