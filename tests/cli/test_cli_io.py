"""``meshopt info`` and ``meshopt convert``: output, exit codes, overwrite refusal."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import grid_mesh, square5

from meshopt_toolkit import io
from meshopt_toolkit.cli import main
from meshopt_toolkit.kernels.triangles import quality_summary
from meshopt_toolkit.mesh import PlanarMesh, TriangleMesh


@pytest.fixture
def files(tmp_path) -> dict[str, Path]:
    """A good .msh, a good .ply, a 3D .obj, a clockwise .off and a bad .obj."""
    grid = grid_mesh(4, jitter=0.3)
    out = {
        "msh": io.save(grid, tmp_path / "grid.msh"),
        "ply": io.save(square5(), tmp_path / "square.ply"),
        "cw": io.save(square5().flipped(), tmp_path / "cw.off"),
        "surf": io.save(TriangleMesh([[0, 0, 0], [1, 0, 1], [0, 1, 2], [1, 1, 0]],
                                     [[0, 1, 2], [1, 3, 2]]),
                        tmp_path / "surf.obj"),
    }
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
    out["bad"] = tmp_path / "bad.obj"
    return out


def test_info_json_lines(files, capsys):
    assert main(["info", "--json", str(files["msh"]), str(files["surf"]), str(files["cw"])]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 3
    grid, surf, cw = map(json.loads, lines)
    ref = grid_mesh(4, jitter=0.3)
    q = quality_summary(ref.points, ref.triangles)
    assert grid["path"] == str(files["msh"])
    assert (grid["n_vertices"], grid["n_triangles"], grid["n_boundary_vertices"]) == (25, 32, 16)
    assert grid["planar"] and grid["manifold"] and grid["admissible"] and not grid["reoriented"]
    assert grid["min_aspect_ratio"] == q.min_aspect_ratio
    assert grid["mean_shape_quality"] == q.mean_shape_quality
    assert grid["min_angle_deg"] == q.min_angle_deg and grid["min_area"] == q.min_area
    assert grid["problems"] == []
    # not on one plane: described as a surface in 3D
    assert surf["cell_kind"] == "surface triangles" and not surf["planar"]
    assert surf["n_triangles"] == 2 and 0 < surf["min_aspect_ratio"] < 1
    assert not surf["closed"] and surf["boundary_loops"] == 1 and surf["genus"] == [0]
    assert surf["manifold"] and surf["oriented"] and surf["problems"] == []
    assert cw["reoriented"] and cw["admissible"] and cw["min_area"] == 1.0


def test_info_text_and_bad_file(files, capsys):
    assert main(["info", str(files["ply"]), str(files["bad"])]) == 1
    captured = capsys.readouterr()
    assert "square.ply" in captured.out and "admissible" in captured.out
    assert "n triangles          4" in captured.out
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and str(files["bad"]) in err[0] and "out of range" in err[0]
    assert "Traceback" not in captured.err


def test_convert_single(files, tmp_path, capsys):
    out = tmp_path / "grid.vtu"
    assert main(["convert", str(files["msh"]), "-o", str(out)]) == 0
    assert io.load(out) == io.load(files["msh"])
    # refuses to overwrite the output, then the input, unless --force
    assert main(["convert", str(files["msh"]), "-o", str(out)]) == 1
    assert main(["convert", str(files["msh"]), "-o", str(files["msh"])]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "already exists" in err[0] and "is the input" in err[1]
    assert str(out) in err[0]
    assert main(["convert", str(files["ply"]), "-o", str(out), "--force"]) == 0
    assert io.load(out) == square5()


def test_convert_single_into_directory(files, tmp_path):
    assert main(["convert", str(files["msh"]), "-o", str(tmp_path / "new"), "--to", "obj"]) == 0
    assert io.load(tmp_path / "new" / "grid.obj") == io.load(files["msh"])


def test_convert_ascii_msh22(files, tmp_path):
    out = tmp_path / "g22.msh"
    argv = ["convert", str(files["msh"]), "-o", str(out), "--ascii", "--msh-version", "2.2"]
    assert main(argv) == 0
    assert out.read_text().startswith("$MeshFormat\n2.2 0 8")
    assert io.load(out) == io.load(files["msh"])


def test_convert_error_writes_nothing(files, tmp_path, capsys):
    out = tmp_path / "x.ply"
    assert main(["convert", str(files["bad"]), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(files["bad"]) in err and "Traceback" not in err
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_convert_batch_with_bad_file(files, tmp_path, capsys):
    outdir = tmp_path / "out"
    status = main(["convert", str(tmp_path / "*.obj"), str(files["msh"]), str(files["ply"]),
                   "-o", str(outdir), "--to", "ply"])
    assert status == 1
    err = capsys.readouterr().err
    assert str(files["bad"]) in err and "3 done, 0 skipped, 1 failed in " in err
    assert sorted(p.name for p in outdir.iterdir() if p.name != ".meshopt-journal.db") == [
        "grid.ply", "square.ply", "surf.ply"]
    assert io.load(outdir / "grid.ply") == io.load(files["msh"])
    assert isinstance(io.load(outdir / "surf.ply"), TriangleMesh)
    # a second run refuses every existing output
    assert main(["convert", str(files["msh"]), str(files["ply"]), "-o", str(outdir),
                 "--to", ".ply"]) == 1
    assert capsys.readouterr().err.count("already exists") == 2


def test_convert_directory_input(files, tmp_path):
    outdir = tmp_path / "vtk"
    good = tmp_path / "good"
    good.mkdir()
    for key in ("msh", "ply"):
        files[key].rename(good / files[key].name)
    assert main(["convert", str(good), "-o", str(outdir), "--to", "vtk"]) == 0
    assert sorted(p.name for p in outdir.iterdir() if p.name != ".meshopt-journal.db") == [
        "grid.vtk", "square.vtk"]
    assert isinstance(io.load(outdir / "square.vtk"), PlanarMesh)


@pytest.mark.parametrize("argv", [
    ["a.msh", "b.msh", "-o", "out"],          # several inputs need --to
    ["a.msh", "-o", "out.xyz"],               # unknown output format
    ["a.msh", "-o", "out.vtu", "--to", "xyz"],
    ["a.msh", "-o", "out.vtu", "--to", "ply"],  # contradiction
])
def test_convert_usage_errors(files, tmp_path, monkeypatch, capsys, argv):
    monkeypatch.chdir(tmp_path)
    io.save(grid_mesh(2), tmp_path / "a.msh")
    io.save(grid_mesh(2), tmp_path / "b.msh")
    assert main(["convert", *argv]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert not any(p.name.startswith("out") for p in tmp_path.iterdir())


def test_convert_missing_output_option_is_usage_error(files):
    with pytest.raises(SystemExit) as info:
        main(["convert", str(files["msh"])])
    assert info.value.code == 2


def test_convert_missing_input(tmp_path, capsys):
    assert main(["convert", str(tmp_path / "nope.msh"), "-o", str(tmp_path / "x.vtu")]) == 1
    assert "nope.msh" in capsys.readouterr().err


def test_console_script(files):
    import subprocess
    import sys

    res = subprocess.run(
        [sys.executable, "-c", "import sys; from meshopt_toolkit.cli import main; "
         f"sys.exit(main(['info', '--json', {str(files['ply'])!r}]))"],
        capture_output=True, text=True)
    assert res.returncode == 0
    assert json.loads(res.stdout)["n_triangles"] == 4
    assert np.isclose(json.loads(res.stdout)["total_area"], 4.0)


def test_info_and_convert_import_no_heavy_package(tmp_path):
    """`meshopt info`/`convert` on a small file load neither scipy nor pymeshlab,
    gmsh or matplotlib (the parser builds only the chosen subcommand)."""
    import subprocess
    import sys

    obj = tmp_path / "s.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    code = (
        "import sys\nfrom meshopt_toolkit.cli import main\n"
        f"assert main(['info', {str(obj)!r}]) == 0\n"
        f"assert main(['convert', {str(obj)!r}, '-o', {str(tmp_path / 's.ply')!r}]) == 0\n"
        "print(sorted(m for m in ('scipy', 'pymeshlab', 'gmsh', 'matplotlib', 'trimesh') "
        "if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_loading_the_builtin_filters_imports_no_scipy():
    """Every pipeline run and batch worker loads the built-in filters: their modules import
    the library lazily (the filters' defaults come from scipy-free modules)."""
    import subprocess
    import sys

    code = ("import sys\nfrom meshopt_toolkit.pipeline.filter import registry\n"
            "registry._load_builtins()\nprint('scipy' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "False"


def test_files_named_like_temporaries_are_never_removed(tmp_path):
    """A save never deletes a file for its name: ``.NAME.PID.RANDOM.part`` of a dead
    process may be the user's."""
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    lookalikes = [tmp_path / f".m.msh.{dead}.abc123.part", tmp_path / ".thesis.2024_v01.part"]
    for p in lookalikes:
        p.write_text("the user's")
    io.save(TriangleMesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]]), tmp_path / "other.obj")
    assert all(p.read_text() == "the user's" for p in lookalikes)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [p.name for p in lookalikes] + ["other.obj"])


def test_directory_input_names_skipped_subfolders_or_recurses(files, tmp_path, caplog):
    src = tmp_path / "in"
    (src / "sub").mkdir(parents=True)
    io.save(io.load(files["msh"]), src / "a.msh")
    io.save(io.load(files["msh"]), src / "sub" / "b.msh")
    with caplog.at_level("WARNING"):
        assert main(["convert", str(src), "-o", str(tmp_path / "o1"), "--to", "vtu"]) == 0
    assert "1 sub-folder(s) not searched (sub); use --recursive" in caplog.text
    assert sorted(p.name for p in (tmp_path / "o1").rglob("*.vtu")) == ["a.vtu"]
    assert main(["convert", str(src), "-o", str(tmp_path / "o2"), "--to", "vtu", "-r"]) == 0
    assert (tmp_path / "o2" / "sub" / "b.vtu").exists() and (tmp_path / "o2" / "a.vtu").exists()


def test_csv_table_keeps_integers_and_ten_digits_of_floats():
    from meshopt_toolkit.cli._common import csv_table

    rng = np.random.default_rng(3)
    x, k = rng.normal(size=5) * 10.0 ** rng.integers(-20, 20, 5), rng.integers(0, 9, 5)
    text = csv_table({"frame": range(5), "value": x, "count": k})
    lines = text.splitlines()
    assert lines[0] == "frame,value,count" and len(lines) == 6 and text.endswith("\n")
    for i, line in enumerate(lines[1:]):
        frame, value, count = line.split(",")
        assert frame == str(i) and count == str(k[i])
        assert float(value) == float(f"{x[i]:.10g}")
        assert abs(float(value) - x[i]) <= 1e-9 * abs(x[i])


@pytest.mark.parametrize("argv, words", [
    (["run", "p.json", "m.msh", "--max-triangles", "0"], "expected a positive integer, got '0'"),
    (["run", "p.json", "m.msh", "--max-triangles", "x"], "expected a positive integer, got 'x'"),
    (["convert", "m.msh", "-o", "o.vtu", "-j", "-1"],
     "expected 0 (all cores) or a positive integer, got '-1'"),
    (["convert", "m.msh", "-o", "o.vtu", "--jobs", "2.5"],
     "expected 0 (all cores) or a positive integer, got '2.5'"),
])
def test_integer_options_below_their_range_are_usage_errors(argv, words, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1].endswith(words)
