"""``meshopt optimize``: the main job from the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import grid_mesh

from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load, save


def test_default_run_writes_everything(tmp_path, capsys):
    out = tmp_path / "out"
    # 3 iterations do not converge: exit 1 with one line on stderr, the files still written
    assert main(["optimize", "-o", str(out), "--max-iter", "3", "--json"]) == 1
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert summary["success"] is False and summary["status"] == "max_iterations"
    assert summary["method"] == "lbfgs"
    assert captured.err.count("\n") == 1 and "not converged" in captured.err
    for key in ("status", "iterations", "j", "objective", "mean_shape_quality",
                "min_aspect_ratio", "seconds"):
        assert key in summary
    assert summary["iterations"] == 3 and summary["n_vertices"] == 146
    # set 2 at 146 vertices, β4 fixed, and the contact barrier β3
    assert summary["penalty_weights"] == pytest.approx([0.1, 0.01, 0.01, 0.146])
    for name in ("optimized.msh", "history.csv", "history.json", "summary.json", "mesh.png",
                 "history.png"):
        assert (out / name).stat().st_size > 0, name
    history = json.loads((out / "history.json").read_text())
    assert [h["iteration"] for h in history] == [0, 1, 2, 3]
    objective = [h["objective"] for h in history]
    assert np.all(np.diff(objective) <= 0)
    mesh = load(out / "optimized.msh")
    assert mesh.n_vertices == 146 and mesh.signed_areas().min() > 0
    assert mesh.tag_names  # physical groups survive
    # a second run into the same directory is refused without --force ...
    before = (out / "summary.json").read_text()
    assert main(["optimize", "-o", str(out), "--max-iter", "2", "--no-plots"]) == 1
    assert "exists" in capsys.readouterr().err
    assert (out / "summary.json").read_text() == before
    # ... and with --force replaces the whole previous run (no stale figures beside it)
    assert main(["optimize", "-o", str(out), "--max-iter", "2", "--no-plots", "--force"]) == 1
    printed = capsys.readouterr().out
    assert "png" not in printed  # --no-plots: the PNGs are not claimed
    assert not (out / "mesh.png").exists() and not (out / "history.png").exists()
    assert json.loads((out / "summary.json").read_text())["iterations"] == 2


def test_refuses_unsafe_rhs_without_running_it(tmp_path, capsys):
    marker = tmp_path / "pwned"
    code = main(["optimize", "-o", str(tmp_path / "o"), "--max-iter", "1",
                 "--rhs", f"__import__('os').system('touch {marker}')"])
    err = capsys.readouterr().err
    assert code == 1 and not marker.exists()
    assert err.count("\n") == 1 and "Traceback" not in err


def test_refuses_inverted_mesh_and_foreign_files(tmp_path, capsys, square):
    Q = square.points.copy()
    Q[4] = [3.0, 0.0]
    bad = tmp_path / "bad.msh"
    save(square.with_points(Q), bad)
    assert main(["optimize", str(bad), "-o", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "bad.msh" in err and "inverted" in err
    other = tmp_path / "busy"
    other.mkdir()
    (other / "history.csv").write_text("not ours")
    assert main(["optimize", "-o", str(other), "--max-iter", "1"]) == 1
    assert "exists" in capsys.readouterr().err
    assert (other / "history.csv").read_text() == "not ours"


def test_custom_mesh_rhs_and_variant(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["optimize", "--variant", "euclidean-euclidean", "--rhs", "1", "--penalty",
                 "0,0,0,0", "--max-iter", "2", "--no-plots", "-o", str(out), "--json",
                 "--method", "steepest"]) == 1
    summary = json.loads(capsys.readouterr().out)
    assert summary["variant"] == "euclidean-euclidean" and summary["penalty"] == 0.0
    assert summary["method"] == "steepest"
    assert np.isfinite(summary["j"])


@pytest.mark.parametrize("method", ["lbfgs", "cg"])
def test_default_problem_converges_with_exit_0(tmp_path, capsys, method):
    out = tmp_path / "o"
    assert main(["optimize", "-o", str(out), "--method", method, "--no-plots", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["success"] is True and summary["status"] == "converged"
    assert summary["method"] == method and summary["iterations"] < 200
    assert summary["objective"] < 0.0165  # thesis table 6.4 set 2: j + f2 ≈ 0.019 (initmesh)
    rows = json.loads((out / "history.json").read_text())
    assert {"method", "step", "wolfe", "pair_rejected", "rejected_trials"} <= set(rows[0])


def test_unwritable_output_directory_is_one_clean_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code = main(["optimize", "-o", str(blocker / "sub"), "--max-iter", "1"])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1
    assert "internal error" not in err and "cannot write" in err and str(blocker) in err


@pytest.mark.parametrize("scale", [1e12, 1e-12])
def test_mesh_at_an_extreme_scale_is_optimized_at_unit_size(tmp_path, capsys, square, scale):
    path = tmp_path / "far.msh"
    save(square.with_points(square.points * scale), path)
    code = main(["optimize", str(path), "-o", str(tmp_path / "o"), "--no-plots", "--json"])
    summary = json.loads(capsys.readouterr().out)
    # the right-hand side is given in the file's coordinates: the optimum is where it is
    assert code == 0 and summary["success"] and summary["min_aspect_ratio"] > 0.5
    assert np.isfinite(load(tmp_path / "o" / "optimized.msh").points).all()


def test_two_runs_into_one_directory_cannot_mix(tmp_path, capsys):
    """While one run holds the output directory, a second fails at once with one line and
    writes nothing; the lock is gone when the run ends."""
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.cli._common import LOCK_NAME, exclusive_output_dir

    out = tmp_path / "run"
    out.mkdir()
    with exclusive_output_dir(out):
        assert main(["optimize", "-o", str(out), "--max-iter", "2", "--no-plots"]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "another meshopt run is writing there" in err[0]
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]
    assert not (out / LOCK_NAME).exists()
    main(["optimize", "-o", str(out), "--max-iter", "2", "--no-plots"])
    names = {p.name for p in out.iterdir()}
    assert "summary.json" in names and LOCK_NAME not in names


def test_metric_penalty_is_refused_where_it_has_no_effect(tmp_path, capsys):
    """β^metric belongs to the complete metric: with the default (elasticity) variant it
    would be ignored, so it is refused before any work (one line, no output)."""
    out = tmp_path / "o"
    assert main(["optimize", "-o", str(out), "--metric-penalty", "1,1,0,1"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--metric-penalty" in err and "elasticity-euclidean" in err
    assert not out.exists()
    assert main(["optimize", "-o", str(out), "--variant", "complete-euclidean",
                 "--metric-penalty", "10,1,0,1.46", "--max-iter", "2", "--no-plots"]) == 1
    assert "not converged" in capsys.readouterr().err  # it ran (2 iterations)


def test_retraction_is_refused_where_it_has_no_effect(tmp_path, capsys):
    """--retraction belongs to complete-complete: with a straight-line variant it is
    refused before any work; with complete-complete the exponential map runs."""
    out = tmp_path / "o"
    assert main(["optimize", "-o", str(out), "--retraction", "exp"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--retraction" in err and "elasticity-euclidean" in err
    assert not out.exists()
    assert main(["optimize", "-o", str(out), "--variant", "complete-complete", "--retraction",
                 "exp", "--max-iter", "2", "--no-plots", "--json"]) == 1
    assert "not converged" in capsys.readouterr().err  # it ran (2 iterations)


@pytest.mark.parametrize("method", ["lbfgs", "steepest"])
def test_the_library_default_is_the_commands_default(tmp_path, capsys, method):
    """``mt.optimize(mesh)`` with no penalty given and ``meshopt optimize`` with none give
    the same iterates: the one default β^penalty (DEFAULT_PENALTY_BETA), stopping rules and
    objective. Also on a mesh of the user's with the command's ``--objective-scale 1``."""
    import meshopt_toolkit as mt
    from meshopt_toolkit.optimize import DEFAULT_PENALTY_BETA

    cases = {"disc": (mt.data_path("disc_146.msh"), [])}
    grid = tmp_path / "grid.msh"
    save(grid_mesh(5, jitter=0.15, seed=4), grid)
    cases["grid"] = (grid, [str(grid), "--objective-scale", "1"])
    for name, (path, args) in cases.items():
        out = tmp_path / f"out-{name}"
        main(["optimize", *args, "-o", str(out), "--method", method, "--max-iterations", "6",
              "--no-plots", "--json"])
        summary = json.loads(capsys.readouterr().out)
        assert summary["penalty_weights"] == pytest.approx(DEFAULT_PENALTY_BETA)
        res = mt.optimize(mt.load(path).as_planar(), method=method, max_iterations=6)
        assert res.nit == summary["iterations"] and res.status == summary["status"]
        assert res.fun == pytest.approx(summary["objective"], rel=1e-12)
        written = load(out / f"optimized{path.suffix}").as_planar()
        np.testing.assert_allclose(written.points, res.mesh.points, rtol=0, atol=1e-12)
        unpenalized = mt.optimize(mt.load(path).as_planar(), method=method, max_iterations=6,
                                  penalty=None)
        assert unpenalized.fun != pytest.approx(res.fun, rel=1e-6)  # the default is not "none"
