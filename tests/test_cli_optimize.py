"""``meshopt optimize``: the main job from the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load, save


def test_default_run_writes_everything(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["optimize", "-o", str(out), "--max-iter", "3", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    for key in ("status", "iterations", "j", "objective", "mean_shape_quality",
                "min_aspect_ratio", "seconds"):
        assert key in summary
    assert summary["iterations"] == 3 and summary["n_vertices"] == 146
    assert summary["penalty_beta"] == pytest.approx([0.1, 0.01, 0.0, 0.146])  # set 2, β4 = 0.001·N
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
    # a second run into the same directory replaces the previous run's files
    assert main(["optimize", "-o", str(out), "--max-iter", "2", "--no-plots"]) == 0


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
                 "0,0,0,0", "--max-iter", "2", "--no-plots", "-o", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["variant"] == "euclidean-euclidean" and summary["penalty"] == 0.0
    assert np.isfinite(summary["j"])
