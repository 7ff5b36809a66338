"""Geodesic morph: path energy derivatives, discrete geodesics, log map, morph, CLI, filter."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import grid_mesh

from meshopt_toolkit.datasets import data_path
from meshopt_toolkit.errors import (IntegrationError, InvalidMeshError, NotAdmissibleError,
                                    OptionError)
from meshopt_toolkit.riemannian.geodesics import exp_map, geodesic
from meshopt_toolkit.kernels.triangles import aspect_ratios, signed_areas
from meshopt_toolkit.fem.interpolation import arap_interpolation
from meshopt_toolkit.mesh import PlanarMesh, check_mesh
from meshopt_toolkit.riemannian.metrics import CompleteMetric
from meshopt_toolkit.motion.planar.scalar_morph import (
    DEFAULT_BETA,
    SHOOTING_RTOL,
    discrete_geodesic,
    geodesic_morph,
    initial_path,
    log_map,
    morph_metric,
    twisted,
)
from meshopt_toolkit.riemannian._boundary_value import _Counter
from meshopt_toolkit.riemannian.newton_cg import _PathEnergy
from meshopt_toolkit.penalties import HeightPenalty, QualityPenalty
from meshopt_toolkit.diagnostics import check_gradient, check_hvp


def bend(mesh: PlanarMesh, amount: float = 0.15) -> np.ndarray:
    """A smooth interior deformation of the unit-square grid, boundary fixed."""
    P = mesh.points
    bump = np.sin(np.pi * P[:, 0]) * np.sin(np.pi * P[:, 1])
    return P + amount * bump[:, None] * np.array([1.0, -0.5])


@pytest.fixture(scope="module")
def disc():
    from meshopt_toolkit.io import load

    return load(data_path("disc_146.msh")).as_planar()


@pytest.fixture(scope="module")
def twist_morph(disc):
    return geodesic_morph(disc, disc.with_points(twisted(disc).points), frames=9)


# -- the path energy --------------------------------------------------------------------


def _path_energy(K=4):
    mesh = grid_mesh(3, jitter=0.3, seed=2)
    pen = QualityPenalty(mesh, beta=(1, 1, 0, 1))
    Q0, Q1 = mesh.points, bend(mesh)
    path = initial_path(pen, Q0, Q1, K)
    return _PathEnergy(_Counter(pen), Q0, Q1, K, pen.value(Q0), pen.value(Q1)), path[1:-1]


def test_path_energy_gradient_and_hvp_taylor(rng):
    pe, X = _path_energy()
    f = pe.value

    def grad(Y):
        return pe.evaluate(Y)[1]

    def hvp(Y, U):
        pe.evaluate(Y)
        return pe.hvp(U)

    d = 0.05 * rng.standard_normal(X.shape)
    res = check_gradient(f, grad, X, direction=d)
    assert res.passed, res
    res = check_hvp(f, grad, hvp, X, direction=d)
    assert res.passed, res
    # value of evaluate agrees with value
    assert np.isclose(pe.evaluate(X)[0], pe.value(X), rtol=1e-13)


def test_gauss_newton_preconditioner_is_exact_inverse(rng):
    pe, X = _path_energy(K=4)
    pe.evaluate(X)
    n = X.size
    I = np.eye(n)
    # dense Gauss–Newton matrix 2K (L ⊗ I) + 2K Fᵀ L F, built independently
    K = pe.K
    L = 2 * np.eye(K - 1) - np.eye(K - 1, k=1) - np.eye(K - 1, k=-1)
    F = np.zeros((K - 1, n))
    m = X[0].size
    for k in range(K - 1):
        F[k, k * m:(k + 1) * m] = pe.gs[k].ravel()
    H = 2 * K * (np.kron(L, np.eye(m)) + F.T @ L @ F)
    G = rng.standard_normal(X.shape)
    assert np.allclose(pe.precondition(G).ravel(), np.linalg.solve(H, G.ravel()), rtol=1e-10,
                       atol=1e-12)
    assert I.shape == H.shape


# -- the log map ------------------------------------------------------------------------


@pytest.mark.parametrize("scale", [0.03, 0.06])
def test_log_exp_round_trip(rng, scale):
    mesh = grid_mesh(4, jitter=0.3)
    metric = CompleteMetric(QualityPenalty(mesh, beta=(1, 1, 0, 1)))
    Q0 = mesh.points
    V = scale * rng.standard_normal(Q0.shape)
    Q1 = exp_map(metric, Q0, V, rtol=SHOOTING_RTOL)
    res = log_map(metric, Q0, Q1)
    tol = 1e-8 * mesh.diameter
    assert res.success and res.residual <= tol
    back = exp_map(metric, Q0, res.velocity, rtol=SHOOTING_RTOL)
    assert np.max(np.abs(back - Q1)) <= 2 * tol
    # short geodesics are minimizing and unique: the velocity itself comes back
    assert np.allclose(res.velocity, V, atol=1e-6)
    assert np.isclose(res.path_length, metric.norm(Q0, V), rtol=1e-6)


def test_translation_is_the_geodesic_when_alpha3_is_zero(rng):
    mesh = grid_mesh(4, jitter=0.3)
    metric = CompleteMetric(HeightPenalty(mesh, alpha=(1.0, 0.0, 0.0)))
    c = np.array([0.7, -0.4])
    Q0, Q1 = mesh.points, mesh.points + c
    res = log_map(metric, Q0, Q1)
    assert res.success
    assert np.allclose(res.velocity, np.broadcast_to(c, Q0.shape), atol=1e-7)
    morph = geodesic_morph(mesh, mesh.with_points(Q1), frames=5, metric=metric)
    expect = Q0[None] + np.linspace(0, 1, 5)[:, None, None] * c
    assert np.allclose(morph.points, expect, atol=1e-8)
    shoot = geodesic_morph(mesh, mesh.with_points(Q1), frames=5, metric=metric, method="shooting")
    assert shoot.method == "shooting"
    assert np.allclose(shoot.points, expect, atol=1e-8)


# -- the 225° twist ---------------------------------------------------------------------


def test_twist_target_admissible_and_linear_interpolation_inverts(disc):
    Q1 = twisted(disc).points
    assert check_mesh(disc.with_points(Q1)).admissible
    worst = min(signed_areas((1 - t) * disc.points + t * Q1, disc.triangles).min()
                for t in np.linspace(0, 1, 201))
    assert worst < 0


@pytest.mark.slow
def test_twist_morph_is_admissible_and_reaches_the_target(disc, twist_morph):
    res = twist_morph
    Q1 = twisted(disc).points
    assert res.n_frames == 9
    assert np.array_equal(res.points[0], disc.points)
    assert np.array_equal(res.points[-1], Q1)
    assert res.admissible.all()
    assert (res.min_area > 0).all()
    assert all(signed_areas(p, disc.triangles).min() > 0 for p in res.points)
    assert res.linear_min_area_dense < 0
    s = res.summary()
    # the scalar metric's discrete geodesic creeps near its minimizer (nearly degenerate
    # triangles: why the distortion metric is the default); whether it stops "stationary"
    # or at max_iter here changes with round-off (SuperLU's or CHOLMOD's rigid start:
    # 235 or 500 iterations, |∇E| 0.052 or 0.043). What must hold is that it says which.
    assert res.discrete.status in ("converged", "stationary", "max_iter")
    assert s["discrete_status"] == res.discrete.status
    assert s["discrete_converged"] == (res.discrete.status == "converged")
    assert s["admissible"] and s["linear_inverts"] and s["target_error"] == 0.0
    # the as-rigid-as-possible comparison at the same times
    rigid = arap_interpolation(disc.points, Q1, disc.triangles, res.times)
    assert np.allclose(res.rigid_min_aspect_ratio,
                       [aspect_ratios(p, disc.triangles).min() for p in rigid])
    assert s["rigid_inverts"] is False and s["rigid_min_aspect_ratio"] > 0
    # straight in-betweens of consecutive frames: checked against dense sampling, which can
    # only miss the minimum of a quadratic a + b s + c s² by c·(h/2)² (grid step h); c from
    # three area evaluations, A(0) + A(1) − 2 A(½) = c/2
    h = 0.01
    sub = np.linspace(0, 1, 101)[:, None, None]
    for k, low in enumerate(res.between_frames_min_area):
        a, b = res.points[k], res.points[k + 1]
        sampled = min(signed_areas(p, disc.triangles).min() for p in (1 - sub) * a + sub * b)
        c = 2 * (signed_areas(a, disc.triangles) + signed_areas(b, disc.triangles)
                 - 2 * signed_areas(0.5 * (a + b), disc.triangles))
        assert low <= sampled + 1e-15
        assert sampled - low <= max(c.max(), 0.0) * (h / 2) ** 2 + 1e-15
    assert s["inversion_free_between_frames"] == bool(res.between_frames_min_area.min() > 0)
    # the frames are (close to) equally spaced in the graph metric: a discrete geodesic
    pen = morph_metric(disc).penalty  # √N·f2 (default normalization)
    assert np.allclose(pen.beta, np.sqrt(disc.n_vertices) * np.array(DEFAULT_BETA))
    assert s["metric_scale"] == pytest.approx(np.sqrt(disc.n_vertices))
    f = np.array([pen.value(p) for p in res.discrete.points])
    seg = np.sqrt(np.sum(np.diff(res.discrete.points, axis=0) ** 2, axis=(1, 2)) + np.diff(f) ** 2)
    assert seg.max() / seg.min() < 1.5
    # and the morph is shorter than the barrier-sliding initial path
    assert res.discrete.length <= np.sum(seg) * (1 + 1e-9)


@pytest.mark.slow
def test_stationary_stop_is_close_to_the_minimum(disc):
    # the energy-stagnation stop ends within 1e-5 of the energy of a run to |∇E| ≤ 1e-7·√E
    # (the energy is then converged to round-off; 1e-9 is below what round-off allows here)
    metric = CompleteMetric(QualityPenalty(disc, beta=DEFAULT_BETA, reference=disc))
    Q1 = twisted(disc).points
    stopped = discrete_geodesic(metric, disc.points, Q1, 8)
    tight = discrete_geodesic(metric, disc.points, Q1, 8,
                               options=dict(energy_rtol=0, tolerance=1e-7))
    assert stopped.status in ("converged", "stationary")
    assert tight.converged and tight.status == "converged"
    assert tight.energy <= stopped.energy * (1 + 1e-12)
    assert stopped.energy - tight.energy <= 1e-5 * tight.energy
    assert tight.nit >= stopped.nit


def test_discrete_geodesic_converges_to_the_shooting_geodesic_second_order():
    mesh = grid_mesh(4, jitter=0.3)
    metric = CompleteMetric(QualityPenalty(mesh, beta=(1, 1, 0, 1)))
    Q0, Q1 = mesh.points, bend(mesh, 0.12)
    V = log_map(metric, Q0, Q1).velocity
    errors = []
    for K in (4, 8, 16):
        dg = discrete_geodesic(metric, Q0, Q1, K)
        assert dg.converged
        exact = geodesic(metric, Q0, V, 1.0, times=np.linspace(0, 1, K + 1),
                         rtol=SHOOTING_RTOL).points
        errors.append(np.max(np.abs(dg.points - exact)))
    rate = np.polyfit(np.log([4, 8, 16]), np.log(errors), 1)[0]
    assert rate < -1.8, (errors, rate)


# -- symmetry ---------------------------------------------------------------------------


def test_reverse_morph_is_the_reversed_morph():
    mesh = grid_mesh(4, jitter=0.3)
    B = mesh.with_points(bend(mesh, 0.12))
    metric = CompleteMetric(QualityPenalty(mesh, beta=(1, 1, 0, 1)))
    ab = geodesic_morph(mesh, B, frames=5, metric=metric)
    ba = geodesic_morph(B, mesh, frames=5, metric=metric)
    assert np.allclose(ab.points, ba.points[::-1], atol=1e-7)
    # the default penalty is referenced to the source: with β4 = 0 it is symmetric too
    ab = geodesic_morph(mesh, B, frames=5, beta=(1, 1, 0, 0))
    ba = geodesic_morph(B, mesh, frames=5, beta=(1, 1, 0, 0))
    assert np.allclose(ab.points, ba.points[::-1], atol=1e-7)


# -- errors -----------------------------------------------------------------------------


def test_errors_are_clear(square):
    grid = grid_mesh(3)
    with pytest.raises(InvalidMeshError, match="vertices"):
        geodesic_morph(square, grid)
    flipped = PlanarMesh([[-1, -1], [1, -1], [1, 1], [-1, 1], [0.5, 0.5]],
                         [[0, 1, 3], [1, 2, 3], [0, 1, 4], [1, 2, 4]])
    with pytest.raises(InvalidMeshError, match="connectivity"):
        geodesic_morph(square, flipped)
    inverted = square.with_points(np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [3.0, 0]]))
    with pytest.raises(NotAdmissibleError):
        geodesic_morph(square, inverted)
    mirror = square.with_points(square.points * [-1.0, 1.0])  # every triangle clockwise
    with pytest.raises(InvalidMeshError):
        geodesic_morph(square, mirror)
    with pytest.raises(OptionError, match="frames"):
        geodesic_morph(square, square, frames=1)


def test_flow_that_does_not_arrive_reports_no_admissible_path(disc):
    # without the rigid interpolation the straight path inverts, so the barrier-sliding
    # flow runs; 5 steps cannot arrive
    pen = QualityPenalty(disc, beta=(1, 1, 0, 1))
    with pytest.raises(NotAdmissibleError, match="no admissible path"):
        initial_path(pen, disc.points, twisted(disc).points, 8, max_steps=5, rigid=False)
    path = initial_path(pen, disc.points, twisted(disc).points, 8, rigid=False)
    assert all(np.isfinite(pen.value(p)) for p in path)


def test_twist_initial_path_is_the_rigid_interpolation(disc):
    pen = QualityPenalty(disc, beta=(1, 1, 0, 1))
    Q1 = twisted(disc).points
    path = initial_path(pen, disc.points, Q1, 8)
    assert np.array_equal(path[0], disc.points) and np.array_equal(path[-1], Q1)
    # the straight path inverts; every rigid frame is at least as good as the worse end
    ends = min(aspect_ratios(q, disc.triangles).min() for q in (disc.points, Q1))
    assert min(aspect_ratios(p, disc.triangles).min() for p in path[1:-1]) >= ends
    assert np.array_equal(path[-1], twisted(disc).points)


# -- CLI and filter ---------------------------------------------------------------------


def test_cli_morph_json(tmp_path, capsys):
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import save

    mesh = grid_mesh(4, jitter=0.3)
    save(mesh, tmp_path / "a.msh")
    save(mesh.with_points(bend(mesh)), tmp_path / "b.msh")
    out = tmp_path / "out"
    rc = main(["morph", str(tmp_path / "a.msh"), str(tmp_path / "b.msh"), "-o", str(out),
               "--frames", "4", "--json", "--metric", "scalar"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    for key in ("frames", "target_error", "min_aspect_ratio", "admissible", "linear_min_area"):
        assert key in summary
    rc = main(["morph", str(tmp_path / "a.msh"), str(tmp_path / "b.msh"), "-o", str(out),
               "--frames", "4", "--json", "--force"])  # default: the distortion metric
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["metric"] == "distortion" and summary["converged"]
    for key in ("frames", "target_error", "min_aspect_ratio", "admissible", "linear_inverts"):
        assert key in summary
    for part in ("ours", "linear", "rigid"):  # per frame: min AR, mean Λ, inverted count
        assert set(summary[part]) == {"min_aspect_ratio", "mean_quality", "inverted"}
        assert len(summary[part]["inverted"]) == 4
    assert summary["frames"] == 4 and summary["admissible"]
    for name in ("frame_000.msh", "frame_003.msh", "strip.png", "quality.png", "summary.json"):
        assert (out / name).exists()
    # refuses to overwrite; different vertex counts give one line and exit 1
    assert main(["morph", str(tmp_path / "a.msh"), str(tmp_path / "b.msh"), "-o", str(out)]) == 1
    save(grid_mesh(3), tmp_path / "c.msh")
    assert main(["morph", str(tmp_path / "a.msh"), str(tmp_path / "c.msh"), "-o",
                 str(tmp_path / "o2")]) == 1
    assert "vertices" in capsys.readouterr().err


def test_cli_morph_max_iter_and_callback(tmp_path, capsys, disc):
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import save

    save(disc, tmp_path / "a.msh")
    save(twisted(disc), tmp_path / "b.msh")
    out = tmp_path / "out"
    assert main(["morph", str(tmp_path / "a.msh"), str(tmp_path / "b.msh"), "-o", str(out),
                 "--frames", "3", "--max-iter", "2", "--no-plots", "--json",
                 "--metric", "scalar"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["discrete_iterations"] == 2 and summary["discrete_status"] == "max_iter"
    assert summary["admissible"] and summary["linear_inverts"]
    assert main(["morph", str(tmp_path / "a.msh"), str(tmp_path / "b.msh"), "-o",
                 str(tmp_path / "o3"), "--frames", "3", "--max-iter", "1", "--no-plots",
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["iterations"] == 1 and summary["status"] == "max_iter"
    assert summary["admissible"] and not summary["converged"]
    assert main(["morph", str(tmp_path / "a.msh"), str(tmp_path / "b.msh"), "-o",
                 str(tmp_path / "o2"), "--max-iter", "0"]) == 1
    assert "--max-iterations" in capsys.readouterr().err
    seen = []
    geodesic_morph(disc, twisted(disc), frames=3, max_iterations=3,
                   callback=lambda nit, E, g: seen.append((nit, E, g)))
    assert [n for n, _, _ in seen] == [1, 2, 3]
    energies = [E for _, E, _ in seen]
    assert np.all(np.diff(energies) <= 0)  # the energy never grows


@pytest.mark.parametrize("metric", ["distortion", "scalar"])
def test_filter_generate_geodesic_morph(metric):
    from meshopt_toolkit.motion.planar.morph import distortion_morph
    from meshopt_toolkit.pipeline.document import Document
    from meshopt_toolkit.pipeline.filter import registry
    from meshopt_toolkit.scaling import unit_scale

    mesh = grid_mesh(4, jitter=0.3)
    target = mesh.with_points(bend(mesh))
    doc = Document([mesh, target])
    cls = registry.get("generate_geodesic_morph")
    summary = cls()(doc, frames=3, metric=metric)
    assert len(doc) == 5 and doc.current == 4
    assert np.allclose(doc.mesh.points[:, :2], bend(mesh))
    assert doc.current_entry.face_attributes["quality"].min() > 0
    assert summary["admissible"] and summary["frames"] == 3
    # the filter morphs at unit size (meshopt_toolkit.scaling), as meshopt morph does
    scale = unit_scale(mesh, target)
    a, b = scale.mesh_down(mesh), scale.mesh_down(target)
    library = (distortion_morph(a, b, frames=3) if metric == "distortion"
               else geodesic_morph(a, b, frames=3))
    middle = doc.entries[3].mesh.points[:, :2]
    assert np.allclose(middle, scale.up(library.meshes(like=a)[1].points), atol=1e-9)


@pytest.mark.parametrize("kind", ["json", "mlx"])
def test_filter_through_json_and_mlx_pipelines(kind, tmp_path):
    from meshopt_toolkit.io import save
    from meshopt_toolkit.pipeline import Document, Pipeline, load_pipeline, save_pipeline

    mesh = grid_mesh(4, jitter=0.3)
    save(mesh.with_points(bend(mesh)), tmp_path / "b.msh")
    steps = [{"name": "load_mesh", "params": {"path": str(tmp_path / "b.msh")}},
             {"name": "generate_geodesic_morph",
              "params": {"frames": 3, "metric": "scalar", "penalty": "1,1,0,0.5"}}]
    path = tmp_path / f"morph.{kind}"
    if kind == "json":
        path.write_text(json.dumps({"filters": steps}))
    else:
        save_pipeline(Pipeline.from_dict({"filters": steps}), path)
        assert 'name="Geodesic Morph (meshopt)"' in path.read_text()
    doc = load_pipeline(path).run(Document([mesh]))
    assert len(doc) == 5
    assert [e.name for e in doc.entries[2:]] == ["morph_000", "morph_001", "morph_002"]
    assert np.allclose(doc.entries[2].mesh.points[:, :2], mesh.points)
    assert np.allclose(doc.mesh.points[:, :2], bend(mesh))
    assert doc.results[-1]["admissible"]


def test_auto_method_shoots_or_falls_back():
    mesh = grid_mesh(4, jitter=0.3)
    B = mesh.with_points(bend(mesh, 0.12))
    shot = geodesic_morph(mesh, B, frames=3, method="auto")
    assert shot.method == "shooting" and shot.log.success
    assert shot.target_error <= 1e-8 * mesh.diameter
    starved = geodesic_morph(mesh, B, frames=3, method="auto", shooting={"max_exp": 1})
    assert starved.method == "discrete" and not starved.log.success
    assert starved.summary()["shooting_residual"] > 0
    with pytest.raises(IntegrationError):
        geodesic_morph(mesh, B, frames=3, method="shooting", shooting={"max_exp": 1})


@pytest.mark.slow
def test_normalized_metric_keeps_a_half_turn_rigid(disc):
    # a half turn: straight lines collapse the mesh to a point at t = 1/2; the plain metric
    # of f2 stays close to them on a 146-vertex mesh, the metric of √N·f2 turns it
    target = disc.with_points(-disc.points)
    normalized = geodesic_morph(disc, target, frames=5)
    plain = geodesic_morph(disc, target, frames=5, normalize=False)
    assert normalized.admissible.all() and plain.admissible.all()
    assert normalized.summary()["metric_scale"] == pytest.approx(np.sqrt(disc.n_vertices))
    assert plain.summary()["metric_scale"] == 1.0
    # what normalization changes (the frames' thinnest triangle is not bounded by this
    # scalar metric, so no absolute threshold is asserted): the turn replaces the shrink
    assert normalized.min_aspect_ratio.min() > plain.min_aspect_ratio.min()
    # the middle frame: shrunk far less (rms radius of the source 0.77)
    def rms(P):
        return np.sqrt(np.mean(np.sum(P**2, axis=1)))

    assert rms(normalized.points[2]) > 1.5 * rms(plain.points[2])


def test_log_map_options_object_and_mapping_agree(rng):
    """``options`` as a LogMapOptions or a mapping of its fields gives the same shooting;
    its tolerance and iteration cap are honoured; an unknown field is an OptionError."""
    import meshopt_toolkit as mt
    from meshopt_toolkit.errors import OptionError

    mesh = grid_mesh(4, jitter=0.3)
    metric = CompleteMetric(QualityPenalty(mesh, beta=(1, 1, 0, 1)))
    Q0 = mesh.points
    Q1 = exp_map(metric, Q0, 0.05 * rng.standard_normal(Q0.shape), rtol=SHOOTING_RTOL)
    a = mt.log_map(metric, Q0, Q1, options=mt.LogMapOptions(tolerance=1e-6))
    b = mt.log_map(metric, Q0, Q1, options={"tolerance": 1e-6})
    assert a.tol == b.tol == 1e-6 and a.success and a.residual <= 1e-6
    np.testing.assert_array_equal(a.velocity, b.velocity)
    capped = mt.log_map(metric, Q0, Q1, options={"tolerance": 1e-14, "max_iterations": 1},
                        raise_on_failure=False)
    assert capped.iterations <= 1 and not capped.success
    with pytest.raises(OptionError, match="max_iter.*choose from"):
        mt.log_map(metric, Q0, Q1, options={"max_iter": 3})
