"""Tests of the Euclidean, elasticity and complete metrics (SPEC §4)."""

from __future__ import annotations

import importlib.util
import sys
import types

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import grid_mesh

from meshopt_toolkit.fem import elasticity
from meshopt_toolkit.errors import InvalidMeshError, MeshoptError, NotAdmissibleError
from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.riemannian.metrics import (
    CompleteMetric,
    ElasticityMetric,
    EuclideanMetric,
    Metric,
    MetricNotImplementedError,
)
from meshopt_toolkit.penalties import HeightPenalty, QualityPenalty
from meshopt_toolkit.diagnostics import check_gradient


class InverseAreaPenalty:
    """Test penalty f(Q) = s Σ_k 1/A_k with its exact gradient (independent of penalties.py).

    The scale ``s`` keeps |∇f| moderate so that round-off in the checks stays ~1e-12.
    """

    def __init__(self, mesh, scale=1e-3):
        self.triangles = mesh.triangles
        self.scale = scale

    def _areas_and_dareas(self, Q):
        p = Q[self.triangles]
        e = np.roll(p, -2, axis=1) - np.roll(p, -1, axis=1)  # edge a opposite vertex a
        area = 0.5 * (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
        dA = 0.5 * np.stack([-e[..., 1], e[..., 0]], axis=-1)  # ∂A/∂q_a, (T, 3, 2)
        return area, dA

    def value(self, Q):
        return self.scale * float(np.sum(1.0 / self._areas_and_dareas(Q)[0]))

    def gradient(self, Q):
        area, dA = self._areas_and_dareas(Q)
        g = np.zeros_like(Q)
        np.add.at(g, self.triangles, -self.scale * dA / area[:, None, None] ** 2)
        return g


def _real_penalties(mesh):
    """The toolkit's f2 (QualityPenalty) and f1 (HeightPenalty)."""
    return [
        QualityPenalty(mesh, beta=(1.0, 0.5, 0.1, 0.2)),
        HeightPenalty(mesh, alpha=(0.1, 0.05, 0.3)),
    ]


HAVE_PYAMG = importlib.util.find_spec("pyamg") is not None
needs_pyamg = pytest.mark.skipif(not HAVE_PYAMG, reason="pyamg not installed")


def _metrics(mesh):
    return {
        "euclidean": EuclideanMetric(),
        "elasticity-direct": ElasticityMetric(mesh, solver="direct"),
        "elasticity-amg": ElasticityMetric(mesh, solver="amg"),  # imports pyamg on first solve
        "elasticity-custom": ElasticityMetric(mesh, E=3.0, nu=0.25, delta=0.7, solver="direct"),
        "complete": CompleteMetric(InverseAreaPenalty(mesh)),
        "distortion": _distortion_metric(mesh),
    }


def _distortion_metric(mesh):
    """The per-triangle distortion metric with a sheared reference (so ``φ ≠ 0`` at the
    mesh), a weight and triangle weights."""
    shear = np.array([[1.0, 0.3], [0.0, 0.8]])
    weights = 1.0 + np.linspace(0.0, 1.0, mesh.n_triangles)
    return GraphMetric(mesh.points @ shear.T, mesh.triangles, 1.7, triangle_weights=weights)


METRIC_NAMES = [
    pytest.param(name, marks=needs_pyamg) if "amg" in name else name
    for name in (
        "euclidean", "elasticity-direct", "elasticity-amg", "elasticity-custom", "complete",
        "distortion",
    )
]


@pytest.fixture
def mesh():
    return grid_mesh(5, jitter=0.4, seed=3)


# -- interface identities shared by every metric --------------------------------------------


@pytest.mark.parametrize("name", METRIC_NAMES)
def test_riesz_is_inverse_of_inner(name, mesh, rng):
    metric = _metrics(mesh)[name]
    Q = mesh.points
    P = rng.standard_normal(Q.shape)
    G = metric.riesz(Q, P)
    assert G.shape == Q.shape
    for _ in range(3):
        V = rng.standard_normal(Q.shape)
        assert metric.inner(Q, G, V) == pytest.approx(np.vdot(P, V), rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("name", METRIC_NAMES)
def test_inner_symmetric_positive_and_norm(name, mesh, rng):
    metric = _metrics(mesh)[name]
    Q = mesh.points
    U, V = rng.standard_normal((2,) + Q.shape)
    assert metric.inner(Q, U, V) == pytest.approx(metric.inner(Q, V, U), rel=1e-12)
    assert metric.inner(Q, V, V) > 0
    assert metric.norm(Q, V) == pytest.approx(np.sqrt(metric.inner(Q, V, V)), rel=1e-12)
    # bilinear: inner(aU + V, W) = a inner(U, W) + inner(V, W)
    W = rng.standard_normal(Q.shape)
    lhs = metric.inner(Q, 2.5 * U + V, W)
    assert lhs == pytest.approx(2.5 * metric.inner(Q, U, W) + metric.inner(Q, V, W), rel=1e-10)


@pytest.mark.parametrize("name", METRIC_NAMES)
def test_restricted_riesz_with_fixed_vertices(name, mesh, rng):
    metric = _metrics(mesh)[name]
    Q = mesh.points
    free = np.ones(len(Q), bool)
    free[mesh.boundary_vertices] = False
    P = rng.standard_normal(Q.shape)
    G = metric.riesz(Q, P, free=free)
    assert np.all(G[~free] == 0.0)
    V = rng.standard_normal(Q.shape)
    V[~free] = 0.0
    assert metric.inner(Q, G, V) == pytest.approx(np.vdot(P, V), rel=1e-9)
    # an all-true mask is the unrestricted map
    np.testing.assert_allclose(metric.riesz(Q, P, free=np.ones(len(Q), bool)), metric.riesz(Q, P))


@pytest.mark.parametrize("name", METRIC_NAMES)
def test_every_metric_implements_the_protocol(name, mesh):
    metric = _metrics(mesh)[name]
    assert isinstance(metric, Metric)
    assert metric.is_flat == (name == "euclidean")


def test_metrics_exported_from_package():
    import meshopt_toolkit as mt

    assert mt.EuclideanMetric is EuclideanMetric
    assert mt.ElasticityMetric is ElasticityMetric
    assert mt.CompleteMetric is CompleteMetric
    assert mt.GraphMetric is GraphMetric


# -- Euclidean ------------------------------------------------------------------------------


def test_euclidean_closed_forms(mesh, rng):
    metric = EuclideanMetric()
    Q = mesh.points
    U, V = rng.standard_normal((2,) + Q.shape)
    assert metric.inner(Q, U, V) == pytest.approx(float(U.ravel() @ V.ravel()))
    assert metric.norm(Q, V) == pytest.approx(np.sqrt((V**2).sum()))
    np.testing.assert_array_equal(metric.exp(Q, V, 0.3), Q + 0.3 * V)
    G = metric.riesz(Q, U)
    np.testing.assert_array_equal(G, U)
    assert G is not U


# -- elasticity -----------------------------------------------------------------------------


def _skfem_matrix(mesh, E, nu, delta):
    """K + δM assembled by scikit-fem, permuted to our dof ordering 2 i + c."""
    skfem = pytest.importorskip("skfem")
    from skfem.helpers import dot
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    m = skfem.MeshTri(np.asarray(mesh.points, float).T.copy(), np.asarray(mesh.triangles).T.copy())
    basis = skfem.Basis(m, skfem.ElementVector(skfem.ElementTriP1()))
    lam, mu = lame_parameters(E, nu)

    @skfem.BilinearForm
    def mass(u, v, w):
        return dot(u, v)

    A = skfem.asm(linear_elasticity(lam, mu), basis) + delta * skfem.asm(mass, basis)
    perm = np.empty(2 * len(mesh.points), dtype=int)
    perm[0::2] = basis.nodal_dofs[0]  # our dof 2i   <- skfem dof of (vertex i, x)
    perm[1::2] = basis.nodal_dofs[1]  # our dof 2i+1 <- skfem dof of (vertex i, y)
    return A.tocsr()[perm][:, perm]


@pytest.mark.parametrize(("E", "nu", "delta"), [(1.0, 0.4, 0.2), (2.5, 0.1, 0.05)])
def test_elasticity_matches_scikit_fem(E, nu, delta, rng):
    mesh = grid_mesh(6, jitter=0.3, seed=7)
    ref = _skfem_matrix(mesh, E, nu, delta)
    metric = ElasticityMetric(mesh, E=E, nu=nu, delta=delta)
    A = metric.matrix(mesh.points)
    assert A.shape == ref.shape
    assert abs(A - ref).max() <= 1e-12 * abs(ref).max()
    for _ in range(3):
        U, V = rng.standard_normal((2,) + mesh.points.shape)
        expected = U.ravel() @ (ref @ V.ravel())
        assert metric.inner(mesh.points, U, V) == pytest.approx(expected, rel=1e-10)


def test_elasticity_spd(square):
    for mesh in (square, grid_mesh(3, jitter=0.3)):
        A = ElasticityMetric(mesh).matrix(mesh.points).toarray()
        np.testing.assert_allclose(A, A.T, atol=1e-14 * abs(A).max())
        assert np.linalg.eigvalsh(A).min() > 0
        np.linalg.cholesky(A)  # raises LinAlgError unless SPD


def test_elasticity_rigid_motions_only_see_mass(mesh):
    """K annihilates rigid velocities, so their energy is δ ∫|v|² (closed forms on [0,1]²)."""
    Q = mesh.points
    A1 = ElasticityMetric(mesh, delta=1.0).matrix(Q)
    A2 = ElasticityMetric(mesh, delta=2.0).matrix(Q)
    M = A2 - A1
    K = A1 - M
    R = elasticity.rigid_modes(Q)
    assert abs(K @ R).max() < 1e-12 * abs(K).max()
    delta = 0.2
    metric = ElasticityMetric(mesh, delta=delta)
    tx = np.tile([1.0, 0.0], (len(Q), 1))
    rot = np.stack([-Q[:, 1], Q[:, 0]], axis=1)  # rotation about the origin
    # ∫_[0,1]² 1 = 1 and ∫_[0,1]² (x² + y²) = 2/3 (P1 interpolates linear fields exactly)
    assert metric.inner(Q, tx, tx) == pytest.approx(delta * 1.0, rel=1e-12)
    assert metric.inner(Q, rot, rot) == pytest.approx(delta * 2.0 / 3.0, rel=1e-12)
    assert metric.inner(Q, tx, rot) == pytest.approx(delta * -0.5, rel=1e-12)  # ∫ -y = -1/2


def test_elasticity_matrix_is_rigidly_equivariant(mesh):
    """A(Q Rᵀ + c) = blockdiag(R) A(Q) blockdiag(R)ᵀ: the metric moves with the mesh."""
    Q = mesh.points
    th = 0.7
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    metric = ElasticityMetric(mesh)
    A = metric.matrix(Q)
    Ar = metric.matrix(Q @ R.T + [3.0, -1.0])
    Rb = sp.block_diag([R] * len(Q))
    np.testing.assert_allclose((Rb @ A @ Rb.T).toarray(), Ar.toarray(), atol=1e-13)


def test_elasticity_factorizes_once_per_q(mesh, rng):
    for solver in ("direct", "amg") if HAVE_PYAMG else ("direct",):
        metric = ElasticityMetric(mesh, solver=solver)
        Q = mesh.points.copy()
        P1, P2 = rng.standard_normal((2,) + Q.shape)
        metric.riesz(Q, P1)
        metric.riesz(Q, P2)
        metric.inner(Q, P1, P2)
        metric.riesz(Q.copy(), P1)  # equal bytes, different object: still cached
        assert metric.n_factorizations == 1
        assert metric.n_assemblies == 1
        Q[5] += 1e-3  # in-place change invalidates the cache ...
        G = metric.riesz(Q, P1)
        assert metric.n_assemblies == 2
        # ... and a nearby Q is solved by CG on the kept factorization, to rtol
        assert metric.n_factorizations == 1
        exact = ElasticityMetric(mesh, solver="direct").riesz(Q, P1)
        np.testing.assert_allclose(G, exact, rtol=0, atol=1e-8 * abs(exact).max())


def test_elasticity_refactorizes_when_the_kept_factorization_stops_paying(mesh, rng):
    """A far-away Q (CG does not converge within REFACTOR_AFTER_CG iterations on the kept
    factorization) gets its own factorization; the result solves the system to the
    metric's rtol either way (checked against the residual and SciPy's own solve)."""
    from scipy.sparse.linalg import spsolve

    metric = ElasticityMetric(mesh, solver="direct")
    Q = mesh.points.copy()
    P = rng.standard_normal(Q.shape)
    metric.riesz(Q, P)
    far = Q * [3.0, 0.2]  # an admissible affine image, far from Q
    G = metric.riesz(far, P)
    assert metric.n_factorizations == 2
    A = metric.matrix(far)
    assert np.linalg.norm(P.ravel() - A @ G.ravel()) <= metric.rtol * np.linalg.norm(P)
    exact = spsolve(A.tocsc(), P.ravel()).reshape(P.shape)
    np.testing.assert_allclose(G, exact, rtol=0, atol=1e-8 * abs(exact).max())


def test_elasticity_assembly_buffer_keeps_every_matrix(mesh, rng):
    """The metric assembles into one kept element-block buffer: matrices made at earlier
    positions are not changed by later assemblies, and each equals a fresh assembly."""
    metric = ElasticityMetric(mesh)
    Q1 = mesh.points
    Q2 = Q1 + 0.01 * rng.standard_normal(Q1.shape) * mesh.diameter / np.sqrt(len(Q1))
    A1 = metric.matrix(Q1)
    before = A1.copy()
    A2 = metric.matrix(Q2)
    for A, Q in ((A1, Q1), (A2, Q2)):
        fresh = elasticity.assemble(Q, mesh.triangles, metric.E, metric.nu, metric.delta)
        assert abs(A - fresh.tocsr()).max() == 0.0
    assert abs(A1 - before).max() == 0.0


def test_elasticity_orders_once_per_free_set(mesh, rng, monkeypatch):
    """The direct method's nested-dissection ordering is computed at the first
    factorization of a free set and reused by later ones (a moving mesh keeps it good)."""
    calls = []
    real = elasticity.nested_dissection
    monkeypatch.setattr(elasticity, "nested_dissection",
                        lambda *a, **k: calls.append(1) or real(*a, **k))
    metric = ElasticityMetric(mesh, solver="direct")
    Q = mesh.points.copy()
    P = rng.standard_normal(Q.shape)
    metric.riesz(Q, P)
    far = Q * [3.0, 0.2]
    G = metric.riesz(far, P)  # refactorized (see the test above), same ordering
    assert metric.n_factorizations == 2 and len(calls) == 1
    A = metric.matrix(far)
    assert np.linalg.norm(P.ravel() - A @ G.ravel()) <= metric.rtol * np.linalg.norm(P)


def test_elasticity_direct_solves_in_float32_from_a_size(mesh, rng, monkeypatch):
    """With CHOLMOD the direct method's factor is double precision and exact at every
    size; without it, below SINGLE_PRECISION_MIN_DOFS, too, and from it the factor is
    SuperLU's float32 and CG refines the solve to the metric's rtol."""
    from scipy.sparse.linalg import spsolve

    Q = mesh.points
    P = rng.standard_normal(Q.shape)
    A = ElasticityMetric(mesh).matrix(Q)
    exact = spsolve(A.tocsc(), P.ravel())
    monkeypatch.setattr(elasticity, "SINGLE_PRECISION_MIN_DOFS", 10)
    for cholmod in (True, False):
        monkeypatch.setattr(elasticity, "cholmod_available", lambda: cholmod)
        if not cholmod:
            monkeypatch.setattr(elasticity, "SINGLE_PRECISION_MIN_DOFS", 10**9)
        exact_factor = ElasticityMetric(mesh, solver="direct")._solver(Q, None)
        # double precision: the factor itself solves (behind `kept_factor.FactorOf`)
        assert getattr(exact_factor.solve, "factor", exact_factor.solve) is exact_factor.precondition
        np.testing.assert_allclose(exact_factor.solve(P.ravel()), exact, rtol=0,
                                   atol=1e-12 * abs(exact).max())
    monkeypatch.setattr(elasticity, "SINGLE_PRECISION_MIN_DOFS", 10)
    metric = ElasticityMetric(mesh, solver="direct")
    large = metric._solver(Q, None)
    rough = large.precondition(P.ravel()) - exact
    assert 1e-12 < abs(rough).max() / abs(exact).max() < 1e-4  # a float32 factor
    G = metric.riesz(Q, P)
    assert np.linalg.norm(P.ravel() - A @ G.ravel()) <= metric.rtol * np.linalg.norm(P)


@needs_pyamg
def test_elasticity_amg_agrees_with_direct(rng):
    mesh = grid_mesh(20, jitter=0.4, seed=1)
    P = rng.standard_normal(mesh.points.shape)
    x_direct = ElasticityMetric(mesh, solver="direct").riesz(mesh.points, P)
    x_amg = ElasticityMetric(mesh, solver="amg").riesz(mesh.points, P)
    np.testing.assert_allclose(x_amg, x_direct, rtol=0, atol=1e-8 * abs(x_direct).max())


def test_elasticity_auto_solver_picks_by_size(mesh, monkeypatch):
    """AMG from AUTO_AMG_MIN_DOFS dofs with SuperLU, from CHOLMOD_AMG_MIN_DOFS with CHOLMOD."""
    Q = mesh.points
    assert ElasticityMetric(mesh)._solver(Q, None).method == "direct"
    amg = "amg" if HAVE_PYAMG else "direct"
    for cholmod, switch in ((False, "AUTO_AMG_MIN_DOFS"), (True, "CHOLMOD_AMG_MIN_DOFS")):
        monkeypatch.setattr(elasticity, "cholmod_available", lambda: cholmod)
        monkeypatch.setattr(elasticity, switch, 10)
        assert ElasticityMetric(mesh)._solver(Q, None).method == amg
        monkeypatch.undo()
        assert ElasticityMetric(mesh)._solver(Q, None).method == "direct"


def test_elasticity_without_pyamg(mesh, monkeypatch, rng):
    """pyamg is optional: "auto" falls back to SuperLU, "amg" says what to install."""
    monkeypatch.setitem(sys.modules, "pyamg", None)  # makes `import pyamg` fail
    monkeypatch.setattr(elasticity, "AUTO_AMG_MIN_DOFS", 10)
    monkeypatch.setattr(elasticity, "CHOLMOD_AMG_MIN_DOFS", 10)
    P = rng.standard_normal(mesh.points.shape)
    metric = ElasticityMetric(mesh)
    G = metric.riesz(mesh.points, P)
    assert metric.inner(mesh.points, G, P) == pytest.approx(np.vdot(P, P))
    assert metric._solver(mesh.points, None).method == "direct"
    with pytest.raises(MeshoptError, match="pip install pyamg"):
        ElasticityMetric(mesh, solver="amg").riesz(mesh.points, P)


def test_elasticity_errors(mesh):
    metric = ElasticityMetric(mesh)
    with pytest.raises(MetricNotImplementedError, match=r"ElasticityMetric\.exp"):
        metric.exp(mesh.points, mesh.points)
    assert issubclass(MetricNotImplementedError, MeshoptError)
    Q = mesh.points.copy()
    Q[[0, 1]] = Q[[1, 0]]  # swapping two corner positions inverts a triangle
    with pytest.raises(NotAdmissibleError, match="positive triangle areas"):
        metric.inner(Q, Q, Q)
    with pytest.raises(InvalidMeshError, match="vertices"):
        metric.riesz(mesh.points[:-1], mesh.points[:-1])
    with pytest.raises(ValueError, match="solver"):
        ElasticityMetric(mesh, solver="cholmod")
    with pytest.raises(ValueError, match="Poisson"):
        ElasticityMetric(mesh, nu=0.5)
    with pytest.raises(ValueError, match="delta"):
        ElasticityMetric(mesh, delta=0.0)


# -- complete -------------------------------------------------------------------------------


def test_test_penalty_gradient_is_exact(mesh, rng):
    pen = InverseAreaPenalty(mesh)
    res = check_gradient(pen.value, pen.gradient, mesh.points, eps0=1e-3, rng=rng)
    assert res.passed, res
    assert res.order == pytest.approx(2.0, abs=0.3)


def _complete_metrics(mesh):
    yield CompleteMetric(InverseAreaPenalty(mesh))
    try:
        import meshopt_toolkit.penalties  # noqa: F401
    except ImportError:
        return
    for pen in _real_penalties(mesh):
        yield CompleteMetric(pen)


def test_complete_metric_against_dense_matrix(rng):
    mesh = grid_mesh(3, jitter=0.3, seed=2)
    Q = mesh.points
    for metric in _complete_metrics(mesh):
        g = metric.penalty.gradient(Q).ravel()
        G = np.eye(g.size) + np.outer(g, g)  # g = I + ∇f∇fᵀ, (5.17)
        P, U, V = rng.standard_normal((3,) + Q.shape)
        np.testing.assert_allclose(
            metric.riesz(Q, P).ravel(), np.linalg.solve(G, P.ravel()), rtol=1e-10, atol=1e-12
        )
        assert metric.inner(Q, U, V) == pytest.approx(U.ravel() @ G @ V.ravel(), rel=1e-12)
        assert metric.norm(Q, V) == pytest.approx(np.sqrt(V.ravel() @ G @ V.ravel()), rel=1e-12)
        # restricted version: the dense matrix on the free dofs
        free = np.ones(len(Q), bool)
        free[mesh.boundary_vertices] = False
        dof = np.repeat(free, 2)
        x = np.zeros(g.size)
        x[dof] = np.linalg.solve(G[np.ix_(dof, dof)], P.ravel()[dof])
        np.testing.assert_allclose(metric.riesz(Q, P, free=free).ravel(), x, rtol=1e-10, atol=1e-12)


def test_complete_metric_with_toolkit_penalties(rng):
    """inner(riesz(P), V) = P·V with the real f1 and f2 as the metric's penalty."""
    mesh = grid_mesh(4, jitter=0.3, seed=5)
    Q = mesh.points
    for pen in _real_penalties(mesh):
        metric = CompleteMetric(pen)
        P, V = rng.standard_normal((2,) + Q.shape)
        assert metric.inner(Q, metric.riesz(Q, P), V) == pytest.approx(np.vdot(P, V), rel=1e-10)
        g = pen.gradient(Q)
        # a step along ∇f costs (1 + |∇f|²) times its Euclidean length squared
        assert metric.inner(Q, g, g) == pytest.approx(np.vdot(g, g) * (1 + np.vdot(g, g)))


def test_complete_metric_caches_penalty_gradient(mesh, rng):
    pen = InverseAreaPenalty(mesh)
    calls = []
    original = pen.gradient

    def counting_gradient(Q):
        calls.append(1)
        return original(Q)

    pen.gradient = counting_gradient
    metric = CompleteMetric(pen)
    assert metric.penalty is pen
    Q = mesh.points.copy()
    P, V = rng.standard_normal((2,) + Q.shape)
    metric.riesz(Q, P)
    metric.inner(Q, P, V)
    metric.norm(Q.copy(), V)
    assert len(calls) == 1 == metric.n_gradient_evaluations
    Q[3, 1] += 1e-4
    metric.riesz(Q, P)
    assert len(calls) == 2


def test_complete_exp_delegates_to_geodesics(mesh, monkeypatch):
    seen = {}

    def fake_exp_map(metric, Q, V, t=1.0, **options):
        seen["args"] = (metric, Q, V, t)
        seen["options"] = options
        return Q + 2 * t * V

    fake = types.ModuleType("meshopt_toolkit.riemannian.geodesics")
    fake.exp_map = fake_exp_map
    monkeypatch.setitem(sys.modules, "meshopt_toolkit.riemannian.geodesics", fake)
    metric = CompleteMetric(InverseAreaPenalty(mesh))
    Q = mesh.points
    V = np.ones_like(Q)
    out = metric.exp(Q, V, 0.25, rtol=1e-9)
    np.testing.assert_array_equal(out, Q + 0.5 * V)
    assert seen["args"][0] is metric and seen["args"][3] == 0.25
    assert seen["options"] == {"rtol": 1e-9}


def test_complete_exp_with_real_geodesics(rng):
    """exp_Q(0) = Q, and for a tiny velocity the geodesic is Q + tV to first order."""
    from meshopt_toolkit.riemannian import geodesics
    mesh = grid_mesh(3, jitter=0.2, seed=4)
    metric = CompleteMetric(_real_penalties(mesh)[0])
    Q = mesh.points
    V = rng.standard_normal(Q.shape)
    np.testing.assert_allclose(metric.exp(Q, 0.0 * V), Q, atol=1e-14)
    h = 1e-4
    step = metric.exp(Q, V, h)
    np.testing.assert_allclose(step, geodesics.exp_map(metric, Q, V, h), rtol=1e-12, atol=1e-14)
    assert np.abs(step - (Q + h * V)).max() < 1e-3 * h * np.abs(V).max()


def test_block_pattern_assembly_equals_coo_sum(rng):
    """Summing element blocks through the precomputed scatter map == plain COO → CSR sum."""
    mesh = grid_mesh(4, jitter=0.2, seed=6)
    perm = rng.permutation(len(mesh.points))  # scramble vertex numbers and triangle order
    tri = perm[mesh.triangles][rng.permutation(mesh.n_triangles)]
    N, T = len(mesh.points), len(tri)
    pattern = elasticity.BlockPattern.from_triangles(tri, N)
    blocks = rng.standard_normal((T, 3, 3, 2, 2))
    A = pattern.assemble(blocks)
    shape = (T, 3, 3, 2, 2)
    c = np.arange(2)
    rows = np.broadcast_to(2 * tri[:, :, None, None, None] + c[:, None], shape).ravel()
    cols = np.broadcast_to(2 * tri[:, None, :, None, None] + c, shape).ravel()
    ref = sp.coo_matrix((blocks.ravel(), (rows, cols)), shape=(2 * N, 2 * N)).toarray()
    np.testing.assert_allclose(A.toarray(), ref, atol=1e-13)
    assert pattern.n_blocks == N + 2 * len(mesh.edges)  # diagonal + both directions of edges


# -- the per-triangle distortion metric ----------------------------------------------------


def test_distortion_metric_is_the_pullback_of_its_embedding(mesh, rng):
    """``g_Q(V, V) = |dX(Q)V|²`` for the embedding ``X(Q) = (m^½ ⊙ Q, w c φ(Q))``: central
    differences of ``X`` (values only, no Jacobian) agree to O(h²)."""
    metric = _distortion_metric(mesh)
    Q = mesh.points
    for _ in range(3):
        V = rng.standard_normal(Q.shape)
        errors = []
        for h in (1e-3, 5e-4):
            plus, minus = (np.concatenate(metric.embed(Q + s * h * V)) for s in (1, -1))
            fd = float(np.sum(((plus - minus) / (2 * h)) ** 2))
            errors.append(abs(fd - metric.inner(Q, V, V)) / metric.inner(Q, V, V))
        assert errors[0] < 1e-3 and 3.5 < errors[0] / errors[1] < 4.5, errors  # O(h²)


def test_distortion_metric_matrix_is_spd_and_its_inner_product(mesh, rng):
    metric = _distortion_metric(mesh)
    Q = mesh.points
    A = metric.matrix(Q).toarray()
    assert A.shape == (2 * mesh.n_vertices,) * 2
    np.testing.assert_allclose(A, A.T, rtol=0, atol=1e-12 * np.abs(A).max())
    assert np.linalg.eigvalsh(A).min() > 0
    U, V = rng.standard_normal((2,) + Q.shape)
    assert metric.inner(Q, U, V) == pytest.approx(U.ravel() @ A @ V.ravel(), rel=1e-12)
    P = rng.standard_normal(Q.shape)
    np.testing.assert_allclose(metric.riesz(Q, P).ravel(), np.linalg.solve(A, P.ravel()),
                               rtol=1e-9, atol=1e-12 * np.abs(np.linalg.solve(A, P.ravel())).max())


def test_distortion_metric_exp_and_inverted_meshes(mesh):
    metric = _distortion_metric(mesh)
    Q = mesh.points
    with pytest.raises(MetricNotImplementedError, match="GraphMetric.exp"):
        metric.exp(Q, Q)
    flipped = Q.copy()
    flipped[:, 0] *= -1.0  # every triangle inverted
    with pytest.raises(NotAdmissibleError, match="inverted"):
        metric.riesz(flipped, Q)
