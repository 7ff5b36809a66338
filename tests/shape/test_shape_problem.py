"""The user's shape problem on gmsh meshes with physical groups: boundary data and the
tracking functional (exact adjoints, closed forms), fixed and moving groups, the exact
area constraint, and the default run on plates with holes, L-shapes and channels."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.cli import main
from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.errors import InvalidMeshError, MeshoptError, OptimizationError, OptionError
from meshopt_toolkit.fem.poisson import PoissonObjective
from meshopt_toolkit.io import load
from meshopt_toolkit.kernels.triangles import aspect_ratios, signed_areas
from meshopt_toolkit.optimize import DEFAULT_PENALTY_BETA, ProblemSpec, optimize
from meshopt_toolkit.pipeline import Document, registry
from meshopt_toolkit.shape.area import AreaConstraint, shoelace_area, shoelace_gradient
from meshopt_toolkit.shape.cases import user_mesh
from meshopt_toolkit.shape.spec import parse_assignment, parse_objective, spec_from_options

SIZES = {"plate": 0.5, "lshape": 0.25, "channel": 0.2, "rectangle": 0.3}


@pytest.fixture(scope="module")
def paths(tmp_path_factory):
    root = tmp_path_factory.mktemp("users")
    return {case: user_mesh(case, root / f"{case}.msh", size) for case, size in SIZES.items()}


@pytest.fixture(scope="module")
def meshes(paths):
    return {case: load(p).as_planar() for case, p in paths.items()}


def _taylor(J, mesh, rng, V=None):
    h = mesh.diameter / np.sqrt(mesh.n_triangles)
    return check_gradient(J.value, J.derivative, mesh.points, V, rng=rng, eps0=0.02 * h)


PROBLEMS = {
    "dirichlet": dict(dirichlet={"hole1": 1.0, "hole2": -0.5}),
    "neumann": dict(neumann={"outer": 0.7}, dirichlet={"hole1": 2.0}),
    "tracking": dict(tracking="sin(x) + y"),
    "all": dict(tracking="0.1*x*y", neumann={"hole2": 1.5}, dirichlet={"hole1": 0.3}, rhs="1+x"),
    "by number": dict(dirichlet={"1": 1.0}, neumann={3: -0.2}),
}


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_boundary_data_and_tracking_derivatives_pass_taylor_tests(name, meshes, rng):
    mesh = meshes["plate"]
    J = PoissonObjective(mesh, **{"rhs": "default", **PROBLEMS[name]})
    res = _taylor(J, mesh, rng)
    assert res.passed and abs(res.order - 2) < 0.2, res
    on_boundary = np.zeros(mesh.n_vertices, bool)
    on_boundary[mesh.boundary_vertices] = True
    V = rng.standard_normal((mesh.n_vertices, 2)) * on_boundary[:, None]
    res = _taylor(J, mesh, rng, V)  # the boundary terms alone
    assert res.passed and abs(res.order - 2) < 0.2, res


@pytest.mark.parametrize("data", [
    dict(dirichlet={"left": 0.0, "right": 2.0}, neumann={"top": 0.0, "bottom": 0.0}),
    dict(dirichlet={"left": 0.0}, neumann={"right": 1.0, "top": 0.0, "bottom": 0.0}),
    dict(dirichlet={"right": 2.0}, neumann={"left": -1.0, "top": 0.0, "bottom": 0.0}),
])
def test_linear_solution_is_reproduced_exactly(data, meshes):
    """y = x solves −Δy = 0 with these data on [0, 2] × [0, 1] (∂y/∂n = n_x); P1 is exact
    for it, ∫y = 2 exactly, and tracking y_d = x gives j = 0 with a zero derivative."""
    mesh = meshes["rectangle"]
    J = PoissonObjective(mesh, rhs=0.0, **data)
    np.testing.assert_allclose(J.state(mesh.points), mesh.points[:, 0], atol=1e-12)
    assert J.value(mesh.points) == pytest.approx(2.0, abs=1e-12)
    T = PoissonObjective(mesh, rhs=0.0, tracking="x", **data)
    assert T.value(mesh.points) == pytest.approx(0.0, abs=1e-24)
    np.testing.assert_allclose(T.derivative(mesh.points), 0.0, atol=1e-12)


def test_unknown_group_and_all_neumann_are_refused(meshes):
    mesh = meshes["rectangle"]
    with pytest.raises(InvalidMeshError, match="no physical group named 'inlet'.*left"):
        PoissonObjective(mesh, dirichlet={"inlet": 1.0})
    with pytest.raises(MeshoptError, match="Dirichlet part"):
        PoissonObjective(mesh, neumann={g: 0.0 for g in ("left", "right", "top", "bottom")})


def test_move_fixes_every_other_boundary_part(meshes):
    mesh = meshes["plate"]
    stay = ProblemSpec(move=("hole1",)).fixed_mask(mesh)
    expect = np.zeros(mesh.n_vertices, bool)
    expect[mesh.tagged_vertices("outer")] = True
    expect[mesh.tagged_vertices("hole2")] = True
    np.testing.assert_array_equal(stay, expect)
    both = ProblemSpec(fixed=("hole2",), move=("hole1", "hole2")).fixed_mask(mesh)
    np.testing.assert_array_equal(both, expect)
    assert ProblemSpec().fixed_mask(mesh) is None


def test_option_strings_are_parsed_and_bad_ones_named():
    spec = spec_from_options(fixed=["outer", "2"], dirichlet="hole1=1, hole2=-0.5",
                             objective="tracking: x*y", scale="0.5")
    assert spec.fixed == ("outer", 2) and spec.dirichlet == {"hole1": 1.0, "hole2": -0.5}
    assert parse_objective(spec.objective) == "x*y" and spec.scale == 0.5
    for bad in ("hole1", "=1", "hole1=nan", "hole1=x"):
        with pytest.raises(MeshoptError, match="GROUP=VALUE"):
            parse_assignment(bad, "--dirichlet")
    with pytest.raises(MeshoptError, match="tracking: EXPR"):
        parse_objective("least squares")
    with pytest.raises(OptimizationError, match="auto"):
        spec_from_options(scale="-1")


def test_area_is_the_shoelace_sum_with_an_exact_gradient_and_restoration(meshes, rng):
    mesh = meshes["plate"]
    edges = mesh.boundary_edges
    A0 = shoelace_area(mesh.points, edges)
    assert A0 == pytest.approx(signed_areas(mesh.points, mesh.triangles).sum(), rel=1e-13)
    assert A0 == pytest.approx(12 - 2 * np.pi * 0.45**2, rel=0.02)  # the polygonal holes
    res = check_gradient(lambda Q: shoelace_area(Q, edges), lambda Q: shoelace_gradient(Q, edges),
                         mesh.points, rng=rng)
    assert res.passed, res
    c = AreaConstraint(edges, A0, lambda Q, P: P)  # Euclidean projection
    X = mesh.points + 0.01 * rng.standard_normal(mesh.points.shape)
    R = c.restore(X, c.normal(mesh.points)[1])
    assert abs(shoelace_area(R, edges) - A0) <= 1e-12 * A0
    V = c.project(mesh.points, rng.standard_normal(mesh.points.shape))
    assert abs(np.sum(shoelace_gradient(mesh.points, edges) * V)) < 1e-12 * np.abs(V).max()


def test_holes_move_with_the_outer_boundary_fixed_and_the_area_kept(meshes):
    mesh = meshes["plate"]
    res = optimize(mesh, None, problem=ProblemSpec(fixed=("outer",), keep_area=True,
                                                   scale="auto"),
                   penalty=DEFAULT_PENALTY_BETA)
    assert res.success, res.message
    outer = mesh.tagged_vertices("outer")
    assert np.array_equal(res.x[outer], mesh.points[outer])  # bit for bit
    A0 = shoelace_area(mesh.points, mesh.boundary_edges)
    assert abs(shoelace_area(res.x, mesh.boundary_edges) - A0) <= 1e-8 * A0
    assert abs(signed_areas(res.x, mesh.triangles).sum() - A0) <= 1e-8 * A0
    for hole in ("hole1", "hole2"):
        v = mesh.tagged_vertices(hole)
        assert np.abs(res.x[v] - mesh.points[v]).max() > 1e-3
    assert res.j < res.history[0].j
    assert aspect_ratios(res.x, mesh.triangles).min() >= 0.5 * aspect_ratios(
        mesh.points, mesh.triangles).min()
    out = res.mesh  # connectivity and groups go through
    assert np.array_equal(out.triangles, mesh.triangles)
    assert out.tag_names == mesh.tag_names and np.array_equal(out.lines, mesh.lines)


def test_keep_area_needs_a_quasi_newton_method(meshes):
    with pytest.raises(OptionError, match="keep_area"):
        optimize(meshes["plate"], None, problem=ProblemSpec(keep_area=True), method="steepest",
                 penalty=DEFAULT_PENALTY_BETA)


@pytest.mark.parametrize("case", ["plate", "lshape", "channel"])
def test_default_run_converges_keeping_the_worst_triangle(case, meshes):
    """`meshopt optimize MESH`'s problem: the thesis rhs, j weighed to the mesh."""
    mesh = meshes[case]
    res = optimize(mesh, None, problem=ProblemSpec(scale="auto"),
                   penalty=DEFAULT_PENALTY_BETA)
    assert res.success, res.message
    ar0 = aspect_ratios(mesh.points, mesh.triangles).min()
    assert aspect_ratios(res.x, mesh.triangles).min() >= 0.5 * ar0
    assert res.j < res.history[0].j and 0 < res.objective_weight < 1


def test_only_the_moving_group_moves_under_a_tracking_objective(meshes):
    mesh = meshes["channel"]
    spec = ProblemSpec(move=("disc",), dirichlet={"inlet": 1.0}, neumann={"outlet": 0.5},
                       objective="tracking: 1 - 0.3*x", rhs=0.0, scale="auto")
    res = optimize(mesh, None, problem=spec, penalty=DEFAULT_PENALTY_BETA)
    assert res.success, res.message
    assert res.j < res.history[0].j
    for group in ("inlet", "outlet", "walls", "square"):
        v = mesh.tagged_vertices(group)
        assert np.array_equal(res.x[v], mesh.points[v])
    disc = mesh.tagged_vertices("disc")
    assert np.abs(res.x[disc] - mesh.points[disc]).max() > 1e-4


def test_cli_poses_the_users_problem(paths, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["optimize", str(paths["plate"]), "-o", str(out), "--no-plots", "--json",
            "--fixed", "outer", "--keep-area", "--dirichlet", "hole1=1", "--neumann", "hole2=0.5",
            "--objective", "tracking: 0.5"]
    assert main(argv) == 0, capsys.readouterr().err
    summary = json.loads(capsys.readouterr().out)
    assert summary["success"] and summary["keep_area"] and summary["fixed"] == ["outer"]
    before, after = load(paths["plate"]).as_planar(), load(out / "optimized.msh").as_planar()
    outer = before.tagged_vertices("outer")
    assert np.array_equal(after.points[outer], before.points[outer])
    A0 = signed_areas(before.points, before.triangles).sum()
    assert abs(signed_areas(after.points, after.triangles).sum() - A0) <= 1e-8 * A0
    assert np.array_equal(after.triangles, before.triangles)


@pytest.mark.parametrize("extra, message", [
    (["--dirichlet", "hole1"], "GROUP=VALUE"),
    (["--fixed", "inlet"], "no physical group named 'inlet'"),
    (["--objective", "tracking:"], "tracking: EXPR"),
    (["--keep-area", "--method", "steepest"], "--keep-area"),
])
def test_cli_bad_problem_options_are_one_line(extra, message, paths, tmp_path, capsys):
    assert main(["optimize", str(paths["plate"]), "-o", str(tmp_path / "o"), "--no-plots",
                 *extra]) != 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err


def test_filter_parameters_pose_the_same_problem(meshes):
    mesh = meshes["plate"]
    doc = Document([mesh])
    registry.get("apply_coord_shape_optimization")()(doc, fixed="outer", keep_area=True,
                                                 dirichlet="hole1=1", max_iterations=5)
    expected = optimize(mesh, None, problem=ProblemSpec(fixed=("outer",), keep_area=True,
                                                        dirichlet={"hole1": 1.0}, scale="auto"),
                        penalty=DEFAULT_PENALTY_BETA, max_iterations=5)
    np.testing.assert_allclose(doc.mesh.points, expected.x, rtol=0, atol=1e-12)


@pytest.mark.parametrize("case", ["plate", "lshape", "channel"])
def test_contact_barrier_is_zero_on_a_healthy_boundary(case, meshes, rng):
    """β3's cut-off: on the initial meshes f2 and its gradient are those without it."""
    from meshopt_toolkit.penalties import QualityPenalty
    from meshopt_toolkit.shape.setup import contact_options

    mesh = meshes[case]
    Q = mesh.points + 1e-3 * rng.standard_normal(mesh.points.shape)
    with_barrier = QualityPenalty(mesh, beta=DEFAULT_PENALTY_BETA, **contact_options(mesh))
    without = QualityPenalty(mesh, beta=DEFAULT_PENALTY_BETA[:2] + (0.0,) + DEFAULT_PENALTY_BETA[3:])
    assert with_barrier.value(Q) == pytest.approx(without.value(Q), rel=1e-14)
    np.testing.assert_allclose(with_barrier.gradient(Q), without.gradient(Q), rtol=0, atol=1e-14)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31), amplitude=st.floats(1e-4, 3e-2))
def test_area_restoration_and_projection_on_random_perturbations(seed, amplitude):
    """On random nearby configurations of a polygon with a hole, restoring along a random
    free direction reaches the area to round-off and moves only the free vertices."""
    rng = np.random.default_rng(seed)
    outer = np.array([[0, 0], [3, 0], [3, 2], [0, 2]], float)
    t = np.linspace(0, 2 * np.pi, 7)[:-1]
    hole = np.column_stack([1.5 + 0.5 * np.cos(t), 1 + 0.5 * np.sin(t)])
    Q0 = np.vstack([outer, hole])
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0]] + [[4 + (k + 1) % 6, 4 + k] for k in range(6)])
    A0 = shoelace_area(Q0, edges)
    assert A0 == pytest.approx(6 - 0.75 * np.sqrt(3) * 0.25 * 2, rel=1e-12)  # hexagonal hole
    free = np.arange(len(Q0)) >= 4
    c = AreaConstraint(edges, A0, lambda Q, P: np.where(free[:, None], P, 0.0))
    X = Q0 + amplitude * rng.standard_normal(Q0.shape) * free[:, None]
    R = c.restore(X, c.normal(Q0)[1])
    assert R is not None and abs(shoelace_area(R, edges) - A0) <= 1e-12 * A0
    assert np.array_equal(R[~free], Q0[~free])
    V = c.project(Q0, rng.standard_normal(Q0.shape) * free[:, None])
    assert abs(np.sum(shoelace_gradient(Q0, edges) * V)) <= 1e-12 * max(np.abs(V).max(), 1.0)


@pytest.mark.parametrize("variant", ["complete-euclidean", "complete-complete"])
@pytest.mark.parametrize("method", ["lbfgs", "cg"])
def test_area_is_kept_along_every_retraction_and_method(variant, method, meshes):
    mesh = meshes["plate"]
    res = optimize(mesh, None, problem=ProblemSpec(fixed=("outer",), keep_area=True, scale="auto"),
                   variant=variant, method=method, penalty=DEFAULT_PENALTY_BETA, max_iterations=4,
                   options=dict(tolerance=None, gtol=None))
    assert res.nit == 4 and res.j < res.history[0].j
    A0 = shoelace_area(mesh.points, mesh.boundary_edges)
    assert abs(shoelace_area(res.x, mesh.boundary_edges) - A0) <= 1e-10 * A0
    outer = mesh.tagged_vertices("outer")
    assert np.array_equal(res.x[outer], mesh.points[outer])


def test_keep_names_the_constraints_held_exactly():
    """``keep`` spells the area (its 3D name "volume") and the barycenter; a name outside
    them is refused, naming it."""
    assert spec_from_options(keep="volume, barycenter").keep_area
    assert spec_from_options(keep=["barycenter"]).keep_barycenter
    plain = spec_from_options()
    assert not (plain.keep_area or plain.keep_barycenter)
    with pytest.raises(OptionError, match="'mass'"):
        spec_from_options(keep="area,mass")
