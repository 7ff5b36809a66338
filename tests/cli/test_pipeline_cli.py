"""``meshopt filters`` and ``meshopt run``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conftest import grid_mesh, square5
from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load, save

pytest.importorskip("pymeshlab")

MIXED_MLX = """<!DOCTYPE FilterScript>
<FilterScript>
 <filter name="Uniform Refinement (meshopt)">
  <Param type="RichInt" name="iterations" value="1" description="Iterations" tooltip=""/>
 </filter>
 <filter name="Laplacian Smooth">
  <Param type="RichInt" name="stepSmoothNum" value="1" description="Smoothing steps" tooltip=""/>
  <Param type="RichBool" name="Boundary" value="false" description="1D Boundary Smoothing" tooltip=""/>
  <Param type="RichBool" name="cotangentWeight" value="false" description="Cotangent" tooltip=""/>
  <Param type="RichBool" name="Selected" value="false" description="Affect only selection" tooltip=""/>
 </filter>
 <filter name="Per Face Shape Quality (meshopt)">
  <Param type="RichEnum" name="metric" value="1" enum_cardinality="2" enum_val0="inverse shape quality 1/psi" enum_val1="aspect ratio 2r/R" description="Metric" tooltip=""/>
 </filter>
</FilterScript>
"""


def test_filters_list_and_describe(capsys):
    assert main(["filters"]) == 0
    out = capsys.readouterr().out
    assert "compute_scalar_by_shape_quality_per_face" in out and "meshing_uniform_refinement" in out
    assert "apply_coord_laplacian_smoothing" not in out
    assert main(["filters", "--json"]) == 0
    specs = json.loads(capsys.readouterr().out)
    for s in specs:
        assert {"name", "label", "description", "parameters"} <= set(s)
    assert main(["filters", "--all", "--json"]) == 0
    specs = {s["name"]: s for s in json.loads(capsys.readouterr().out)}
    lap = specs["apply_coord_laplacian_smoothing"]
    assert lap["origin"] == "pymeshlab"
    assert [p["name"] for p in lap["parameters"]][:2] == ["stepsmoothnum", "boundary"]
    assert specs["compute_scalar_ambient_occlusion_gpu"]["unsafe"] is True
    assert main(["filters", "Laplacian Smooth"]) == 0
    assert "stepsmoothnum : int" in capsys.readouterr().out
    assert main(["filters", "meshing_uniform_refinement", "--json"]) == 0
    spec = json.loads(capsys.readouterr().out)
    assert spec["parameters"][0] == {**spec["parameters"][0], "name": "iterations", "min": 1}


def test_filters_unknown_name(capsys):
    assert main(["filters", "meshing_uniform_refinment"]) == 1
    assert "did you mean 'meshing_uniform_refinement'" in capsys.readouterr().err


def test_run_mixed_mlx_batch_with_a_bad_file(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.mlx").write_text(MIXED_MLX)
    inputs = tmp_path / "in"
    inputs.mkdir()
    save(square5(), inputs / "a.msh")
    save(grid_mesh(3, jitter=0.2), inputs / "b.obj")
    (inputs / "c.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")  # truncated
    args = ["run", "p.mlx", "in", "-o", "out", "--isolate", "never", "--to", "ply", "--json"]
    assert main(args) == 1
    cap = capsys.readouterr()
    assert "c.off" in cap.err and "2 done, 0 skipped, 1 failed in " in cap.err
    records = [json.loads(line) for line in cap.out.splitlines()]
    assert [r["status"] for r in records] == ["ok", "ok", "failed"]
    quality = records[0]["results"][-1]
    assert quality["filter"] == "compute_scalar_by_shape_quality_per_face"
    assert quality["metric"] == "aspect ratio 2r/R"
    out = load(tmp_path / "out" / "a.ply")
    assert out.n_triangles == 16 and out.n_vertices == 13
    # an existing output is never overwritten without --force
    before = (tmp_path / "out" / "a.ply").read_bytes()
    assert main(["run", "p.mlx", "in/a.msh", "-o", "out", "--to", "ply", "--isolate", "never"]) == 1
    assert "already exists" in capsys.readouterr().err
    assert (tmp_path / "out" / "a.ply").read_bytes() == before
    assert main(["run", "p.mlx", "in/a.msh", "-o", "out", "--to", "ply", "--force",
                 "--isolate", "never"]) == 0


def test_dry_run_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.json").write_text(json.dumps({"filters": [
        {"name": "meshing_uniform_refinement"},
        {"name": "Laplacian Smooth", "params": {"stepsmoothnum": 2}}]}))
    save(square5(), tmp_path / "a.msh")
    (tmp_path / "bad.msh").write_text("garbage")
    assert main(["run", "p.json", "a.msh", "bad.msh", "-o", "out", "--dry-run"]) == 1
    err = capsys.readouterr().err
    assert "bad.msh" in err and "dry run: 1 checked, 1 failed, nothing written in " in err
    assert not (tmp_path / "out").exists()
    assert main(["run", "p.json", "a.msh", "-o", "out", "--dry-run"]) == 0
    cap = capsys.readouterr()
    lines = cap.out.splitlines()  # the steps, then each input and its output
    assert lines[0].startswith("dry run of p.json: 2 step(s): 1. meshing_uniform_refinement; "
                               "2. apply_coord_laplacian_smoothing;")
    assert lines[1] == f"checked a.msh -> would write {Path('out') / 'a.msh'}"
    assert "done" not in cap.out + cap.err and not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "pipeline, fragment",
    [
        ({"filters": [{"name": "meshing_uniform_refinement", "params": {"iterations": 0}}]},
         "below the minimum"),
        ({"filters": [{"name": "Laplacian Smooth", "params": {"stepsmoothnumber": 2}}]},
         "did you mean 'stepsmoothnum'"),
        ({"filters": [{"name": "no_such_filter_anywhere"}]}, "unknown filter"),
        ({"steps": []}, '{"filters": [...]}'),
    ],
)
def test_invalid_pipeline_fails_before_any_file(tmp_path, capsys, monkeypatch, pipeline, fragment):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.json").write_text(json.dumps(pipeline))
    save(square5(), tmp_path / "a.msh")
    assert main(["run", "p.json", "a.msh", "-o", "out"]) == 1
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_run_bad_json_and_missing_pipeline(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.json").write_text('{"filters": [}')
    save(square5(), tmp_path / "a.msh")
    assert main(["run", "p.json", "a.msh", "-o", "out"]) == 1
    assert "not valid JSON" in capsys.readouterr().err
    assert main(["run", "nope.json", "a.msh", "-o", "out"]) == 1
    assert "no such pipeline file" in capsys.readouterr().err
