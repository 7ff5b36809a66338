"""Shape optimization on tetrahedra (shape/tets.py, the 3D paths of shape/spec.py,
optimize.py and ``meshopt optimize``): Taylor tests of every objective and of the
penalized problem's derivative in 3D, the volume cubic's step limit against numpy's
roots, the factored metric against the assembled one, and runs on a sphere in a box with
the constraints, the box and the mesh's health checked on the result."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.cells.tetrahedra import exact_orientations
from meshopt_toolkit.cli import main
from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.io import load_cells
from meshopt_toolkit.kernels.tetrahedra import mean_ratios, signed_volumes
from meshopt_toolkit.shape.cases import body_in_box
from meshopt_toolkit.shape.constraints import barycenter, enclosed_measure
from meshopt_toolkit.shape.spec import spec_from_options
from meshopt_toolkit.shape.tets import (DistortionPenalty, FactoredMetric, TetShapeProblem,
                                        tet_setup, tet_step_limit)

STOKES = dict(pde="stokes", dirichlet=["body=1,0,0", "outer=0,0,0"], move=["body"])


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    """A sphere of radius ½ in the 8 × 6 × 6 box, coarse (~700 tets)."""
    return body_in_box(tmp_path_factory.mktemp("sphere") / "sphere.msh", 2.5, 0.35)


@pytest.fixture(scope="module")
def mesh(sphere):
    return load_cells(sphere).to_tet_mesh("test")


def _direction(mesh, free, seed=0):
    """A standard normal field on the free vertices, zero on the others."""
    V = np.random.default_rng(seed).standard_normal(mesh.points.shape)
    V[~free] = 0.0
    return V


def _free(spec, mesh):
    stay = spec.fixed_mask(mesh)
    return np.ones(mesh.n_vertices, bool) if stay is None else ~stay


@pytest.mark.parametrize("options", [
    STOKES,
    dict(pde="elasticity", stress=["body=0.5,-0.2,0.1,0.05,0,0.1"], clamped=["outer"],
         move=["body"]),
    dict(objective="integral", rhs="x*y + z**2 - 0.3", dirichlet=["body=1"], move=["body"]),
    dict(objective="tracking: 0.2*x - y*z", rhs="1 + x", move=["body"]),
], ids=["dissipation", "compliance", "integral", "tracking"])
def test_objective_derivatives_pass_the_taylor_test_in_3d(mesh, options):
    spec = spec_from_options(**options)
    j = spec.make_objective(mesh)
    free = _free(spec, mesh)
    res = check_gradient(j.value, j.derivative, np.array(mesh.points),
                         _direction(mesh, free), eps0=2e-3, n=6)
    assert abs(res.order - 2) < 0.15, res


def test_dissipation_derivative_by_minres_passes_the_taylor_test(mesh):
    # the iterative Stokes solve the larger 3D meshes get (fem.stokes_solver)
    spec = spec_from_options(**STOKES)
    j = spec.make_objective(mesh, solver="minres")
    assert j.method == "minres"
    res = check_gradient(j.value, j.derivative, np.array(mesh.points),
                         _direction(mesh, _free(spec, mesh)), eps0=2e-3, n=6)
    assert abs(res.order - 2) < 0.15, res


def test_penalized_problem_derivative_passes_the_taylor_test(mesh):
    spec = spec_from_options(**STOKES)
    f2, metric, Problem, floor = tet_setup(mesh, "elasticity-euclidean", (0.1, 0, 0, 0), "auto")
    free = _free(spec, mesh)
    problem = Problem(spec.make_objective(mesh), f2, metric, mesh.tets, mesh.boundary_faces,
                      free, None, quality_floor=floor)
    Q = np.array(mesh.points)
    V = _direction(mesh, free, 1)
    res = check_gradient(lambda X: problem.values(X)[0], problem.derivative, Q, V, eps0=2e-3,
                         n=6)
    assert abs(res.order - 2) < 0.15, res
    assert np.all(problem.derivative(Q)[~free] == 0)


def test_distortion_penalty_taylor_and_zero_at_the_reference(mesh):
    Q0 = np.array(mesh.points)
    f2 = DistortionPenalty(Q0, mesh.tets, 0.3)
    assert f2.value(Q0) < 1e-28 and np.abs(f2.gradient(Q0)).max() < 1e-12
    Q = Q0 + 0.01 * np.random.default_rng(2).standard_normal(Q0.shape)
    res = check_gradient(f2.value, f2.gradient, Q, eps0=1e-3, rng=3)
    assert abs(res.order - 2) < 0.1, res


def _random_tets(seed, n=30):
    r = np.random.default_rng(seed)
    q = r.standard_normal((n, 4, 3))
    neg = signed_volumes(q.reshape(-1, 3), np.arange(4 * n).reshape(n, 4)) < 0
    q[neg] = q[neg][:, [1, 0, 2, 3]]
    return q.reshape(-1, 3), np.arange(4 * n).reshape(n, 4)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(1e-3, 1e3))
def test_step_limit_is_the_first_root_of_the_volume_cubics(seed, scale):
    Q, tets = _random_tets(seed)
    d = scale * np.random.default_rng(seed + 1).standard_normal(Q.shape)
    t = tet_step_limit(Q, tets, d)
    roots = []
    for c in tets:  # numpy's roots of each tet's 6V(t), sampled exactly at four steps
        ts = np.array([0.0, 1.0, 2.0, 3.0]) / scale
        v = [6 * signed_volumes(Q + s * d, c[None])[0] for s in ts]
        poly = np.polyfit(ts, v, 3)
        r = np.roots(poly)
        r = r[(np.abs(r.imag) < 1e-9 * np.abs(r).max()) & (r.real > 0)].real
        roots.append(r.min() if len(r) else np.inf)
    expected = min(roots)
    assert t == pytest.approx(expected, rel=1e-6)
    if np.isfinite(t):
        assert signed_volumes(Q + 0.999 * t * d, tets).min() > 0
        assert signed_volumes(Q + 1.001 * t * d, tets).min() < 0


def test_factored_metric_is_the_tet_metric_and_factors_once(mesh):
    from meshopt_toolkit.cells.registry import metric_for

    spec = spec_from_options(**STOKES)
    free = _free(spec, mesh)
    Q = np.array(mesh.points)
    base = metric_for(mesh)
    metric = FactoredMetric(base)
    P = _direction(mesh, free, 4)
    G1 = metric.riesz(Q, P, free)
    np.testing.assert_allclose(G1, base.riesz(Q, P, free), rtol=1e-9, atol=1e-12)
    metric.riesz(Q, 2 * P, free)
    assert metric.n_factorizations == 1 and np.all(G1[~free] == 0)


def test_fixed_mask_keeps_the_box_and_frees_the_body_and_interior(mesh):
    spec = spec_from_options(**STOKES)
    stay = spec.fixed_mask(mesh)
    outer = np.unique(mesh.triangles[mesh.triangle_tags == mesh.tag_names["outer"][0]])
    body = np.unique(mesh.triangles[mesh.triangle_tags == mesh.tag_names["body"][0]])
    assert stay[outer].all() and not stay[body].any()
    assert stay.sum() == len(outer)


def _check_run(mesh, Q1, spec):
    Q0 = mesh.points
    facets = spec.body_facets(mesh)
    assert enclosed_measure(Q1, facets) == pytest.approx(enclosed_measure(Q0, facets), rel=1e-6)
    b0, b1 = barycenter(Q0, facets), barycenter(Q1, facets)
    assert np.abs(b1 - b0).max() <= 1e-6 * 0.5
    assert (exact_orientations(Q1, mesh.tets) > 0).all()
    assert mean_ratios(Q1, mesh.tets).min() >= 0.3 * mean_ratios(Q0, mesh.tets).min()
    stay = spec.fixed_mask(mesh)
    assert np.array_equal(Q1[stay], Q0[stay])
    assert np.abs(Q1[~stay] - Q0[~stay]).max() > 1e-3


@pytest.mark.slow
def test_stokes_drag_decreases_with_volume_and_barycenter_kept(mesh):
    from meshopt_toolkit.optimize import optimize

    spec = spec_from_options(**STOKES, keep="volume,barycenter", scale="auto")
    result = optimize(mesh, problem=spec, max_iterations=8)
    j0 = spec.make_objective(mesh).value(mesh.points)
    fresh = spec.make_objective(mesh).value(result.x)  # a new solver at the final mesh
    assert result.j == pytest.approx(fresh, rel=1e-9) and fresh < 0.97 * j0
    _check_run(mesh, result.x, spec)


@pytest.mark.slow
def test_cli_stokes_writes_every_group_and_keeps_the_box(sphere, tmp_path):
    out = tmp_path / "out"
    main(["optimize", str(sphere), "--pde", "stokes", "--dirichlet", "body=1,0,0",
          "--dirichlet", "outer=0,0,0", "--objective", "dissipation", "--move", "body",
          "--keep-volume", "--keep-barycenter", "--max-iterations", "4", "-o", str(out)])
    before, after = load_cells(sphere), load_cells(out / "optimized.msh")
    assert after.cell_counts() == before.cell_counts()
    m0, m1 = before.to_tet_mesh("t"), after.to_tet_mesh("t")
    assert m1.tag_names == m0.tag_names and np.array_equal(m1.triangle_tags, m0.triangle_tags)
    assert np.array_equal(m1.tets, m0.tets)
    spec = spec_from_options(**STOKES, keep="volume,barycenter")
    _check_run(m0, m1.points, spec)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_tets"] == m0.n_tets and summary["min_mean_ratio"] > 0


@pytest.mark.parametrize("options", [
    ["--pde", "elasticity", "--stress", "body=1,0,0,0,0,0", "--clamped", "outer",
     "--move", "body", "--keep-volume"],
    ["--rhs", "x + y*z", "--dirichlet", "body=1", "--move", "body", "--keep-barycenter"],
], ids=["elasticity", "poisson"])
def test_cli_elasticity_and_poisson_in_3d(sphere, mesh, tmp_path, options):
    out = tmp_path / "out"
    main(["optimize", str(sphere), *options, "--max-iterations", "2", "-o", str(out)])
    Q0, Q1 = mesh.points, load_cells(out / "optimized.msh").to_tet_mesh("t").points
    spec = spec_from_options(move=["body"])
    stay = spec.fixed_mask(mesh)
    assert np.array_equal(Q1[stay], Q0[stay]) and not np.array_equal(Q1, Q0)
    assert (exact_orientations(Q1, mesh.tets) > 0).all()
    if "--keep-volume" in options:  # the domain's volume, all its faces
        F = mesh.boundary_faces
        assert enclosed_measure(Q1, F) == pytest.approx(enclosed_measure(Q0, F), rel=1e-9)
    else:
        F = spec.body_facets(mesh)
        np.testing.assert_allclose(barycenter(Q1, F), barycenter(Q0, F), rtol=0, atol=1e-9)


@pytest.mark.parametrize("args, words", [
    (["--pde", "stokes", "--move", "body"], "--dirichlet"),
    (["--pde", "stokes", "--dirichlet", "nobody=1,0,0"], "nobody"),
    (["--pde", "stokes", "--dirichlet", "body=1,0"], "3 components"),
    (["--pde", "elasticity", "--stress", "outer=2,1,0"], "6 components"),
    (["--pde", "elasticity", "--stress", "outer=1,0,0,0,0,0", "--move", "nobody"], "nobody"),
    (["--neumann", "body=1"], "--neumann"),
    (["--variant", "complete-euclidean", "--pde", "stokes", "--dirichlet", "body=1,0,0"],
     "--variant"),
    (["--pde", "stokes", "--dirichlet", "body=1,0,0", "--keep-barycenter"], "--move"),
])
def test_bad_input_is_one_line_before_any_output(sphere, tmp_path, capsys, args, words):
    out = tmp_path / "out"
    assert main(["optimize", str(sphere), *args, "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and sphere.name in err, err
    assert "Traceback" not in err and not out.exists()


def test_tet_problem_rejects_inverted_and_squeezed_trials(mesh):
    f2, metric, Problem, floor = tet_setup(mesh, "elasticity-euclidean", None, "auto")
    assert Problem is TetShapeProblem and f2 is None
    spec = spec_from_options(**STOKES)
    problem = Problem(spec.make_objective(mesh), None, metric, mesh.tets, mesh.boundary_faces,
                      _free(spec, mesh), None, quality_floor=floor)
    Q = np.array(mesh.points)
    assert problem.admissible(Q)
    body = np.unique(mesh.triangles[mesh.triangle_tags == mesh.tag_names["body"][0]])
    X = Q.copy()
    X[body[0]] = -X[body[0]]  # a body vertex through the sphere's centre: tets invert
    assert not problem.admissible(X) and problem.values(X)[0] == np.inf


def test_filter_optimizes_a_tet_document_as_the_library_does(mesh):
    from meshopt_toolkit.optimize import optimize
    from meshopt_toolkit.pipeline import Document, registry

    doc = Document([mesh])
    registry.get("apply_coord_shape_optimization")()(
        doc, pde="stokes", dirichlet="body=1,0,0, outer=0,0,0", move="body", keep_area=True,
        max_iterations=2, tolerance=0)
    spec = spec_from_options(**STOKES, keep="volume")
    expected = optimize(mesh, problem=spec, max_iterations=2, options=dict(tolerance=None))
    moved = doc.mesh
    assert np.allclose(moved.points, expected.x, rtol=0, atol=1e-12)
    assert not np.allclose(moved.points, mesh.points)
    assert moved.tag_names == mesh.tag_names and np.array_equal(moved.tets, mesh.tets)
