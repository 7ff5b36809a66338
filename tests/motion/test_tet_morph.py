"""The morph of tetrahedral meshes (motion/tets/morph.py, its path model motion/tets/path.py,
``mt.morph`` and ``meshopt morph`` on tet files)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from test_tet_move import box_with_hole, cube_tets, sphere_turn

from gmsh_files import assert_same_but_points

from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.errors import InvalidMeshError, NotAdmissibleError, OptionError
from meshopt_toolkit.kernels.tetrahedra import mean_ratios, signed_volumes
from meshopt_toolkit.mesh import TetMesh
from meshopt_toolkit.motion.engine.similarity_3d import tet_boundary_faces
from meshopt_toolkit.motion.tets.metric import TetGraphMetric
from meshopt_toolkit.motion.tets.morph import morph_tets
from meshopt_toolkit.motion.tets.move import move_tets
from meshopt_toolkit.motion.tets.path import TetPath
from meshopt_toolkit.results import Result

#: the physical names of the CLI tests' file
GROUPS = {"hole", "walls", "solid"}


def twisted_cube(n=4, degrees=60.0, jitter=0.2, seed=0):
    """A jittered cube and its image with the boundary twisted about z by ``degrees·z``
    (the interior placed by move_tets)."""
    P, T = cube_tets(n, jitter, seed)
    b = np.unique(tet_boundary_faces(T))
    c = np.array([0.5, 0.5, 0.0])
    tg = np.array([(P[v] - c) @ Rotation.from_euler("z", P[v, 2] * degrees, degrees=True)
                   .as_matrix().T + c for v in b])
    return TetMesh(P, T), TetMesh(move_tets(P, T, b, tg).points, T)


def admissible_frames(res) -> bool:
    return all((signed_volumes(F, res.source.tets) > 0).all() for F in res.points)


def worst_of_ends(src: TetMesh, tgt: TetMesh) -> float:
    return min(mean_ratios(src.points, src.tets).min(), mean_ratios(tgt.points, tgt.tets).min())


# ------------------------------------------------------------------ the path model
def _path(newton_frames=4, seed=0):
    src, tgt = twisted_cube(2, degrees=40.0, seed=seed)
    metric = TetGraphMetric(src.points, src.tets, 0.7)
    t = np.linspace(0, 1, newton_frames)[:, None, None]
    frames = (1 - t) * src.points + t * tgt.points
    rng = np.random.default_rng(seed)
    frames[1:-1] += 0.01 * rng.standard_normal(frames[1:-1].shape)
    return TetPath(metric, frames), frames


def test_path_normal_equations_agree_with_the_sparse_jacobian():
    path, frames = _path(5)
    r, J = path.evaluate(frames, jacobian=True)
    r2, g, H, d = path.normal_equations(frames)
    np.testing.assert_allclose(r2, r, rtol=0, atol=1e-13 * np.abs(r).max())
    np.testing.assert_allclose(g, J.T @ r, rtol=1e-11, atol=1e-11 * np.abs(g).max())
    JtJ = (J.T @ J).toarray()
    np.testing.assert_allclose(H.tocsr().toarray(), JtJ, rtol=1e-11, atol=1e-11 * np.abs(JtJ).max())
    np.testing.assert_allclose(d, np.diag(JtJ), rtol=1e-11)
    x = np.random.default_rng(1).standard_normal(path.n_unknowns)
    np.testing.assert_allclose(H @ x, JtJ @ x, rtol=1e-10, atol=1e-10 * np.abs(JtJ @ x).max())
    assert path.unknowns(path.with_unknowns(path.unknowns(frames))).tolist() == \
        path.unknowns(frames).tolist()


def test_path_energy_taylor_gradient_and_newton_hessian():
    path, frames = _path(4, seed=2)
    x0 = path.unknowns(frames)

    def f(x):
        r, _ = path.evaluate(path.with_unknowns(x), jacobian=False)
        return 0.5 * float(r @ r)

    def grad(x):
        return path.normal_equations(path.with_unknowns(x))[1]

    def hvp(x, v):
        return path.normal_equations(path.with_unknowns(x), newton=True)[2] @ v

    assert check_gradient(f, grad, x0, rng=0, eps0=1e-3).passed
    assert check_hvp(f, grad, hvp, x0, rng=0, eps0=1e-3).passed


def test_path_admissibility_and_a_single_segment():
    path, frames = _path(4)
    assert path.admissible(frames)
    bad = frames.copy()
    bad[1, :, 0] *= -1.0  # a mirrored interior frame: every tet inverted
    assert not path.admissible(bad)
    src, tgt = twisted_cube(2, degrees=30.0)
    res = morph_tets(src, tgt, 2)
    assert np.array_equal(res.points[0], src.points) and np.array_equal(res.points[1],
                                                                        tgt.points)


# ------------------------------------------------------------------ quality of the frames
@pytest.fixture(scope="module")
def hole_pair():
    """gmsh box with a ball hole (~2k tets) and its image under move_tets with the ball
    turned 90° about z (every boundary vertex a handle)."""
    P, T = box_with_hole(0.3)
    handles, at = sphere_turn(P, T, degrees=90.0, push=0.0)
    return TetMesh(P, T), TetMesh(move_tets(P, T, handles, at(1.0)).points, T)


def test_sphere_turn_frames_admissible_and_as_good_as_the_ends(hole_pair):
    src, tgt = hole_pair
    res = morph_tets(src, tgt, 7)
    assert res.converged and admissible_frames(res)
    assert np.array_equal(res.points[0], src.points) and np.array_equal(res.points[-1],
                                                                        tgt.points)
    worst = worst_of_ends(src, tgt)
    assert res.min_mean_ratio.min() >= 0.9 * worst, (res.min_mean_ratio, worst)
    # the independent check of the frames' quality (not the result's own numbers)
    assert min(mean_ratios(F, src.tets).min() for F in res.points) == pytest.approx(
        res.summary()["min_mean_ratio"])


def test_sphere_shifted_pair_from_the_continuation_start(hole_pair):
    src, _ = hole_pair
    P, T = src.points, src.tets
    handles = np.unique(tet_boundary_faces(T))
    tg = P[handles].copy()
    tg[np.linalg.norm(tg, axis=1) < 0.6] += [0.3, 0.0, 0.2]
    tgt = TetMesh(move_tets(P, T, handles, tg).points, T)
    res = morph_tets(src, tgt, 5, initial="continuation")
    assert res.initial_path == "continuation" and res.converged and admissible_frames(res)
    assert res.min_mean_ratio.min() >= 0.9 * worst_of_ends(src, tgt)


def test_twisted_cube_frames_and_both_starts_agree():
    src, tgt = twisted_cube(4, degrees=60.0)
    a = morph_tets(src, tgt, 6, initial="linear")
    b = morph_tets(src, tgt, 6, initial="continuation")
    for res in (a, b):
        assert res.converged and admissible_frames(res)
        assert res.min_mean_ratio.min() >= 0.9 * worst_of_ends(src, tgt)
    # the same minimizer from two starts
    np.testing.assert_allclose(a.points, b.points, atol=1e-6)


def test_half_turn_twist_where_linear_interpolation_inverts():
    src, tgt = twisted_cube(4, degrees=180.0)
    res = morph_tets(src, tgt, 7)
    assert res.converged and admissible_frames(res)
    assert res.min_mean_ratio.min() >= 0.9 * worst_of_ends(src, tgt)
    # the vertices' straight lines flatten the cube's middle (measured: 62 tets at s = 1/2)
    middle = 0.5 * (src.points + tgt.points)
    assert (signed_volumes(middle, src.tets) <= 0).sum() > 0
    assert res.summary()["linear_inverts"]


def test_strain_bound_holds_per_tet():
    src, tgt = twisted_cube(3, degrees=50.0)
    res = morph_tets(src, tgt, 5, weight=0.5)
    metric = TetGraphMetric(src.points, src.tets, 0.5)
    phis = [metric.strain.values(F) for F in res.points]
    walked = np.cumsum([np.linalg.norm(b - a, axis=1) for a, b in zip(phis[:-1], phis[1:])],
                       axis=0)
    assert (walked.max(axis=1) <= res.strain_bound[1:] * (1 + 1e-9)).all()


# ------------------------------------------------------------------ exact cases
def test_rigid_pair_follows_the_rigid_interpolation():
    P, T = cube_tets(3, 0.25, seed=4)
    rot = Rotation.from_rotvec([0.3, -1.1, 1.6])  # 112°
    shift = np.array([2.0, -1.0, 0.5])
    src, tgt = TetMesh(P, T), TetMesh(P @ rot.as_matrix().T + shift, T)
    res = morph_tets(src, tgt, 6)
    assert res.initial_path == "similarity" and res.nit == 0
    # reference: the screw about the boundary's centroid, angle linear in time
    c = P[np.unique(tet_boundary_faces(T))].mean(axis=0)
    for s, F in zip(np.linspace(0, 1, 6), res.points):
        Rs = Rotation.from_rotvec(s * rot.as_rotvec()).as_matrix()
        expected = c + s * (rot.apply(c) + shift - c) + (P - c) @ Rs.T
        np.testing.assert_allclose(F, expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(mean_ratios(F, T), mean_ratios(P, T), rtol=1e-10)
    assert np.array_equal(res.points[-1], tgt.points)


def test_similarity_pair_keeps_every_shape():
    P, T = cube_tets(2, 0.3, seed=5)
    src = TetMesh(P, T)
    tgt = TetMesh(1.7 * Rotation.from_euler("x", 70, degrees=True).apply(P) + 3.0, T)
    res = morph_tets(src, tgt, 4)
    for F in res.points:
        np.testing.assert_allclose(mean_ratios(F, T), mean_ratios(P, T), rtol=1e-10)
    assert res.strain_bound[-1] == pytest.approx(np.sqrt(3) * np.log(1.7))


def test_a_mesh_to_itself_stays_bit_for_bit(hole_pair):
    src, _ = hole_pair
    res = morph_tets(src, src, 5)
    assert res.initial_path == "identity"
    for F in res.points:
        assert np.array_equal(F, src.points)


# ------------------------------------------------------------------ random meshes
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), amplitude=st.floats(0.02, 0.3),
       frames=st.integers(2, 5))
def test_random_small_pairs_every_frame_admissible(seed, amplitude, frames):
    rng = np.random.default_rng(seed)
    P, T = cube_tets(2, 0.3, seed)
    A = np.eye(3) + amplitude * rng.standard_normal((3, 3))
    Q = P @ A.T + 0.3 * amplitude * rng.standard_normal(P.shape) * 0.5
    assume((signed_volumes(Q, T) > 0).all() and np.linalg.det(A) > 0)
    src, tgt = TetMesh(P, T), TetMesh(Q, T)
    res = morph_tets(src, tgt, frames, max_iterations=60)
    assert admissible_frames(res)
    assert np.array_equal(res.points[0], P) and np.array_equal(res.points[-1], Q)
    assert res.status in ("converged", "stalled", "max_iter")
    assert res.min_mean_ratio.min() > 0


# ------------------------------------------------------------------ bad input, mt.morph
def test_bad_pairs_are_refused():
    P, T = cube_tets(2, 0.2)
    src = TetMesh(P, T)
    with pytest.raises(InvalidMeshError, match="same vertices and tetrahedra"):
        morph_tets(src, TetMesh(P, T[:, [1, 0, 3, 2]]))
    with pytest.raises(InvalidMeshError, match="same vertices and tetrahedra"):
        morph_tets(src, TetMesh(P, T[:-1]))
    flipped = P.copy()
    flipped[:, 0] *= -1.0
    with pytest.raises(NotAdmissibleError, match="target.*inverted"):
        morph_tets(src, TetMesh(flipped, T))
    with pytest.raises(OptionError):
        morph_tets(src, src, 1)
    with pytest.raises(OptionError):
        morph_tets(src, src, 3, initial="straight")


def test_mt_morph_on_tet_meshes_is_a_result():
    import meshopt_toolkit as mt

    src, tgt = twisted_cube(3, degrees=45.0)
    src = TetMesh(src.points, src.tets, tet_tags=np.arange(src.n_tets) % 3)
    seen = []
    res = mt.morph(src, tgt, 4, callback=lambda it: seen.append(it.iteration))
    assert isinstance(res, Result) and res.status == "converged" and seen
    assert len(res.frames) == 4 and all(isinstance(F, TetMesh) for F in res.frames)
    assert np.array_equal(res.frames[1].tet_tags, src.tet_tags)
    assert np.array_equal(res.mesh.points, tgt.points)
    json.dumps(res.summary())
    with pytest.raises(OptionError, match="distortion"):
        mt.morph(src, tgt, 4, metric="complete")


# ------------------------------------------------------------------ command line
@pytest.fixture(scope="module")
def tet_files(tmp_path_factory):
    """A gmsh box-with-hole file with physical groups and a point datum of our own, and
    the file of its image with the ball turned 60°."""
    pytest.importorskip("gmsh")
    from gmsh_files import box_with_hole_msh

    from meshopt_toolkit.io import load_cells, save_cells

    d = tmp_path_factory.mktemp("tet_morph")
    src = d / "box.msh"
    box_with_hole_msh(src, radius=0.35, size=0.35, size_min=0.35 / 3)
    cm = load_cells(src)
    cm.point_data["temperature"] = np.linalg.norm(cm.points, axis=1)
    save_cells(cm, src, overwrite=True)
    mesh = cm.to_tet_mesh()
    handles = mesh.boundary_vertices
    tg = mesh.points[handles].copy()
    inner = np.linalg.norm(tg, axis=1) < 0.6
    tg[inner] = Rotation.from_euler("z", 60, degrees=True).apply(tg[inner])
    used = np.unique(mesh.tets)  # gmsh files may hold points in no tet
    local = np.full(mesh.n_vertices, -1)
    local[used] = np.arange(len(used))
    keep = local[handles] >= 0
    moved = move_tets(mesh.points[used], local[mesh.tets], local[handles[keep]], tg[keep])
    Q = mesh.points.copy()
    Q[used] = moved.points
    tgt = d / "turned.msh"
    save_cells(replace(cm, points=Q), tgt)
    return src, tgt, cm, Q


def test_cli_morph_of_tet_files_keeps_groups_and_data(tet_files, tmp_path, capsys):
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import load_cells

    src, tgt, cm, Q = tet_files
    out = tmp_path / "frames"
    assert main(["morph", str(src), str(tgt), "-o", str(out), "--frames", "5"]) == 0
    line = capsys.readouterr().out
    assert "all admissible: True" in line
    names = sorted(p.name for p in out.iterdir())
    assert names == [f"frame_00{k}.msh" for k in range(5)] + ["quality.csv", "summary.json"]
    frames = [load_cells(out / f"frame_00{k}.msh") for k in range(5)]
    for F in frames:
        assert_same_but_points(cm, F, point_data={"temperature"}, groups=GROUPS)
    assert np.array_equal(frames[0].points, cm.points)
    assert np.array_equal(frames[-1].points, Q)
    tets = np.concatenate([c for t, c in cm.cells if t == "tetra"])
    worst = min(mean_ratios(cm.points, tets).min(), mean_ratios(Q, tets).min())
    for F in frames:
        assert (signed_volumes(F.points, tets) > 0).all()
        assert mean_ratios(F.points, tets).min() >= 0.9 * worst
    summary = json.loads((out / "summary.json").read_text())
    assert summary["admissible"] and summary["frames"] == 5
    rows = (out / "quality.csv").read_text().splitlines()
    assert rows[0].startswith("frame,min_mean_ratio") and len(rows) == 6
    # an existing output is not overwritten without --force
    assert main(["morph", str(src), str(tgt), "-o", str(out), "--frames", "5"]) == 1
    assert "exists" in capsys.readouterr().err


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_cli_bad_tet_pairs_are_one_line_errors(tet_files, tmp_path, capsys):
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import save_cells

    src, tgt, cm, Q = tet_files
    # different connectivity: one tet's corners swapped
    cells = [(t, c.copy()) for t, c in cm.cells]
    k = next(i for i, (t, _) in enumerate(cells) if t == "tetra")
    cells[k][1][0] = cells[k][1][0][[1, 0, 3, 2]]
    other = tmp_path / "other.msh"
    save_cells(replace(cm, cells=cells), other)
    assert main(["morph", str(src), str(other), "-o", str(tmp_path / "a")]) == 1
    assert "not the same vertices and tetrahedra" in _one_line(capsys)
    # an inverted end
    flipped = tmp_path / "flipped.msh"
    save_cells(replace(cm, points=cm.points * [-1.0, 1.0, 1.0]), flipped)
    assert main(["morph", str(src), str(flipped), "-o", str(tmp_path / "b")]) == 1
    assert "flipped.msh" in _one_line(capsys)
    # the complete metric is planar only
    assert main(["morph", str(src), str(tgt), "-o", str(tmp_path / "c"), "--metric",
                 "scalar"]) == 1
    assert "distortion metric only" in _one_line(capsys)
    assert not any((tmp_path / n).exists() for n in "abc")
