"""Quality-preserving deformation: deform() and the ``meshopt deform`` command."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from conftest import square5

from meshopt_toolkit import data_path, load
from meshopt_toolkit.cli import main
from meshopt_toolkit.deform import DEFAULT_ALPHA, deform
from meshopt_toolkit.errors import InvalidMeshError, NotAdmissibleError, OptionError
from meshopt_toolkit.kernels.triangles import aspect_ratios, signed_areas
from meshopt_toolkit.penalties import HeightPenalty, QualityPenalty


def squeeze(mesh) -> np.ndarray:
    """Boundary-only velocity on the unit disc: squeeze in x, stretch in y."""
    P = mesh.points
    V = np.zeros_like(P)
    b = mesh.boundary_vertices
    V[b, 0] = -0.6 * P[b, 0]
    V[b, 1] = 0.3 * P[b, 1]
    return V


@pytest.fixture(scope="module")
def disc():
    return load(data_path("disc_25.msh")).as_planar()


def test_boundary_velocity_keeps_the_disc_admissible_where_euclid_inverts(disc):
    V = squeeze(disc)
    euclid = deform(disc, V, time=2.0, frames=5, metric="euclidean")
    assert euclid.aspect_ratio[-1] < 0  # the boundary crosses the fixed interior
    res = deform(disc, V, time=2.0, frames=5)
    assert res.penalty.alpha == DEFAULT_ALPHA
    assert np.all(res.aspect_ratio > 0.05)
    for p in res.points:
        assert signed_areas(p, disc.triangles).min() > 0
    # interior vertices moved although their initial velocity is zero
    interior = np.setdiff1d(np.arange(disc.n_vertices), disc.boundary_vertices)
    assert np.abs(res.points[-1][interior] - disc.points[interior]).max() > 0.05
    # aspect ratio column is the min of 2r/R of each frame (independent recomputation)
    for p, ar in zip(res.points, res.aspect_ratio):
        assert ar == pytest.approx(aspect_ratios(p, disc.triangles).min())
    assert res.mesh.n_triangles == disc.n_triangles
    assert np.array_equal(res.meshes()[-1].points, res.points[-1])
    assert np.array_equal(res.times, np.linspace(0, 2, 5))


def test_penalty_choices(disc):
    V = squeeze(disc)
    f2 = deform(disc, V, penalty=(10, 1, 0, 0.1 * disc.n_vertices))
    assert isinstance(f2.penalty, QualityPenalty)
    pen = HeightPenalty(disc, alpha=(0.5, 0, 0.5))
    own = deform(disc, V, penalty=pen)
    assert own.penalty is pen
    assert own.times.tolist() == [0.0, 1.0]
    with pytest.raises(OptionError, match="at most one"):
        deform(disc, V, alpha=(1, 0, 1), penalty=(1, 1, 0, 1))


def test_refusals():
    m = square5()
    with pytest.raises(InvalidMeshError, match="shape"):
        deform(m, np.zeros((4, 2)))
    with pytest.raises(OptionError, match="frames"):
        deform(m, np.zeros((5, 2)), frames=1)
    pts = m.points.copy()
    pts[4] = [3.0, 0.0]  # centre outside: two triangles inverted
    with pytest.raises(NotAdmissibleError):
        deform(m.with_points(pts), np.zeros((5, 2)))
    with pytest.raises(OptionError, match="metric"):
        deform(m, np.zeros((5, 2)), metric="elastic")


# -- command line ---------------------------------------------------------------------


@pytest.fixture
def workdir(tmp_path, disc):
    shutil.copy(data_path("disc_25.msh"), tmp_path / "disc.msh")
    V = squeeze(disc)
    np.save(tmp_path / "v.npy", V)
    np.savetxt(tmp_path / "v.csv", V, delimiter=",")
    return tmp_path


def test_cli_single_output_and_no_overwrite(workdir, capsys, disc):
    out = workdir / "out.msh"
    assert main(["deform", str(workdir / "disc.msh"), "-o", str(out),
                 "--displacement", str(workdir / "v.npy")]) == 0
    moved = load(out).as_planar()
    assert np.array_equal(moved.triangles, disc.triangles)
    assert signed_areas(moved.points, moved.triangles).min() > 0
    ref = deform(disc, squeeze(disc)).mesh.points
    assert np.abs(moved.points - ref).max() < 1e-9
    assert main(["deform", str(workdir / "disc.msh"), "-o", str(out),
                 "--displacement", str(workdir / "v.csv")]) == 1
    assert "--force" in capsys.readouterr().err
    assert main(["deform", str(workdir / "disc.msh"), "-o", str(out), "--force",
                 "--displacement", str(workdir / "v.csv"), "--time", "0.5"]) == 0


def test_cli_frames_pngs_and_displacement_mesh(workdir, capsys):
    out = workdir / "frames"
    assert main(["deform", str(workdir / "disc.msh"), "-o", str(out), "--frames", "4",
                 "--time", "2", "--displacement", str(workdir / "v.npy")]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["aspect_ratio.png", "frame_000.msh", "frame_001.msh", "frame_002.msh",
                     "frame_003.msh", "quality.csv", "snapshots.png"]
    for png in ("aspect_ratio.png", "snapshots.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    table = np.loadtxt(out / "quality.csv", delimiter=",", skiprows=1)
    assert table.shape == (4, 4) and np.all(table[:, 1] > 0)
    # non-empty directory refused; a mesh as displacement works (V = its points − input's)
    assert main(["deform", str(workdir / "disc.msh"), "-o", str(out), "--frames", "3",
                 "--displacement", str(workdir / "v.npy")]) == 1
    assert "not empty" in capsys.readouterr().err
    out2 = workdir / "frames2"
    assert main(["deform", str(workdir / "disc.msh"), "-o", str(out2), "--frames", "2",
                 "--no-png", "--beta", "10,1,0,2.5",
                 "--displacement", str(out / "frame_001.msh")]) == 0
    assert not (out2 / "snapshots.png").exists()


def test_cli_refuses_bad_displacements(workdir, capsys):
    np.save(workdir / "short.npy", np.zeros((3, 2)))
    rc = main(["deform", str(workdir / "disc.msh"), "-o", str(workdir / "o.msh"),
               "--displacement", str(workdir / "short.npy")])
    assert rc == 1 and "shape" in capsys.readouterr().err
    shutil.copy(data_path("square5.msh"), workdir / "sq.msh")
    rc = main(["deform", str(workdir / "disc.msh"), "-o", str(workdir / "o.msh"),
               "--displacement", str(workdir / "sq.msh")])
    assert rc == 1 and "same connectivity" in capsys.readouterr().err
    rc = main(["deform", str(workdir / "disc.msh"), "-o", str(workdir / "o.msh"),
               "--displacement", str(workdir / "missing.npy")])
    assert rc == 1 and "no such file" in capsys.readouterr().err
    assert not (workdir / "o.msh").exists()
    with pytest.raises(SystemExit):  # --alpha and --beta are exclusive (usage error)
        main(["deform", str(workdir / "disc.msh"), "-o", "x.msh", "--displacement", "v.npy",
              "--alpha", "1,0,1", "--beta", "1,1,0,1"])


def test_cli_refuses_inverted_input(workdir, capsys):
    from meshopt_toolkit.io import save

    m = square5()
    pts = m.points.copy()
    pts[4] = [3.0, 0.0]
    save(m.with_points(pts), workdir / "bad.msh")
    np.save(workdir / "v5.npy", np.zeros((5, 2)))
    rc = main(["deform", str(workdir / "bad.msh"), "-o", str(workdir / "o.msh"),
               "--displacement", str(workdir / "v5.npy")])
    assert rc == 1
    assert "error" in capsys.readouterr().err
    assert not (workdir / "o.msh").exists()
