"""One clean line for bad input: expressions, option values, unwritable outputs, pipelines.

Every error here must be a single line on stderr naming the expression, option or path,
exit status 1, no "internal error", and no output written.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import one_line

from meshopt_toolkit import data_path
from meshopt_toolkit.cli import main

DISC = data_path("disc_25.msh")


@pytest.fixture
def work(tmp_path):
    shutil.copy(DISC, tmp_path / "disc.msh")
    shutil.copy(DISC, tmp_path / "same.msh")
    from meshopt_toolkit.io import load

    P = load(DISC).as_planar().points
    np.save(tmp_path / "v.npy", np.column_stack([0.1 * P[:, 0], 0 * P[:, 1]]))
    (tmp_path / "a_file").write_text("not a directory\n")
    return tmp_path


def _commands(w: Path) -> dict:
    """The argument lists of each subcommand minus the output (appended by the tests)."""
    return {
        "deform": ["deform", str(w / "disc.msh"), "--displacement", str(w / "v.npy")],
        "morph": ["morph", str(w / "disc.msh"), str(w / "same.msh"), "--frames", "3",
                  "--no-plots"],
        "move": ["move", str(w / "disc.msh"), "--map", "x; y"],
    }


# ------------------------------------------------------------------------ expressions
@pytest.mark.parametrize("argv,shown", [
    (["optimize", "{disc}", "--rhs", "1/0", "-o", "{out}"], "'1/0' is not finite (division by zero)"),
    (["optimize", "{disc}", "--rhs", "x + exp(1000)", "-o", "{out}"], "'exp(1000)' is not finite"),
    (["move", "{disc}", "--map", "x*(1/0); y", "-o", "{out}.msh"], "'1/0' is not finite"),
    (["move", "{disc}", "--map", "x/0; y", "-o", "{out}.msh"], "value of 'x/0' is not finite"),
    (["optimize", "{disc}", "--rhs", "x + z", "-o", "{out}"], "z is not defined for a planar mesh"),
])
def test_expression_errors_are_one_line_naming_the_expression(work, capsys, argv, shown):
    argv = [a.format(disc=work / "disc.msh", out=work / "out") for a in argv]
    assert main(argv) == 1
    assert shown in one_line(capsys)
    assert not list(work.glob("out*"))


# ---------------------------------------------------------------------- option values
BAD_OPTIONS = [
    ("deform", ["--time", "nan"], "--time must be a finite number >= 0, got nan"),
    ("deform", ["--time", "inf"], "--time must be a finite number >= 0, got inf"),
    ("deform", ["--time", "-1"], "--time must be a finite number >= 0, got -1"),
    ("deform", ["--rtol", "-1"], "--rtol must be a finite number >= 1e-14 and <= 0.1, got -1"),
    ("deform", ["--rtol", "nan"], "--rtol must be a finite number >= 1e-14 and <= 0.1, got nan"),
    ("deform", ["--rtol", "0"], "--rtol must be a finite number >= 1e-14 and <= 0.1, got 0"),
    ("deform", ["--frames", "1000000"], "--frames must be between 2 and 1000, got 1000000"),
    ("deform", ["--frames", "1"], "--frames must be between 2 and 1000, got 1"),
    ("deform", ["--alpha", "1,nan,1"], "--alpha must be finite numbers >= 0, got 1,nan,1"),
    ("deform", ["--beta", "1,1,-1,1"], "--penalty must be finite numbers >= 0, got 1,1,-1,1"),
    ("morph", ["--frames", "1001"], "--frames must be between 2 and 1000, got 1001"),
    ("morph", ["--max-iter", "0"], "--max-iterations must be between 1 and 100000, got 0"),
    ("morph", ["--weight", "nan"], "--weight must be a finite number > 0, got nan"),
    ("morph", ["--weight", "0"], "--weight must be a finite number > 0, got 0"),
    ("morph", ["--metric", "scalar", "--beta", "1,1,inf,1"],
     "--penalty must be finite numbers >= 0, got 1,1,inf,1"),
    ("move", ["--frames", "1000000"], "--frames must be between 2 and 1000, got 1000000"),
    ("move", ["--steps", "0"], "--steps must be between 1 and 1000, got 0"),
    ("move", ["--weight=-inf"], "--weight must be a finite number > 0, got -inf"),
]


@pytest.mark.parametrize("command,extra,message", BAD_OPTIONS,
                         ids=[f"{c}{' '.join(e)}" for c, e, _ in BAD_OPTIONS])
def test_bad_option_values_are_refused_before_any_work(work, capsys, monkeypatch, command,
                                                       extra, message):
    import meshopt_toolkit.io as mio

    def no_load(*args, **kwargs):
        raise AssertionError("an input was read before the options were checked")

    monkeypatch.setattr(mio, "load", no_load)
    out = work / "out"
    assert main([*_commands(work)[command], *extra, "-o", str(out)]) == 1
    line = one_line(capsys)  # the input named in front (nothing else names a file)
    assert line.startswith(f"meshopt {command}: error: {work / 'disc.msh'}")
    assert line.endswith(f": {message}") and not out.exists()


def test_frames_bound_is_the_filters():
    from meshopt_toolkit.bounds import MAX_FRAMES, MAX_STEPS
    from meshopt_toolkit.pipeline.filter import registry

    frames = {p.name: p for p in registry.get("generate_geodesic_morph").parameters}["frames"]
    steps = {p.name: p for p in registry.get("apply_coord_prescribed_motion").parameters}["steps"]
    assert frames.max == MAX_FRAMES == 1000 and steps.max == MAX_STEPS


# ------------------------------------------------------------------ unwritable outputs
def _outputs(w: Path, base: Path) -> list[tuple[str, list[str]]]:
    """(name, argv) for every subcommand writing into ``base``: files and directories."""
    c = _commands(w)
    return [
        ("deform file", [*c["deform"], "-o", str(base / "out.msh")]),
        ("deform frames", [*c["deform"], "--frames", "3", "--no-png", "-o", str(base / "fr")]),
        ("morph", [*c["morph"], "-o", str(base / "mo")]),
        ("move file", [*c["move"], "-o", str(base / "mv.msh")]),
        ("move frames", [*c["move"], "--frames", "3", "-o", str(base / "mvf")]),
    ]


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a deform, morph or move computation starts."""
    import importlib

    d = importlib.import_module("meshopt_toolkit.deform")  # the module (mt.deform: the call)
    import meshopt_toolkit.motion.planar.morph as mm
    import meshopt_toolkit.motion.move as mv

    def boom(*args, **kwargs):
        raise AssertionError("computed before the output was checked")

    monkeypatch.setattr(d, "deform", boom)
    monkeypatch.setattr(mm, "distortion_morph", boom)
    monkeypatch.setattr(mv, "move", boom)


def test_output_under_a_file_is_one_line_before_any_work(work, capsys, no_work):
    for name, argv in _outputs(work, work / "a_file"):
        assert main(argv) == 1, name
        line = one_line(capsys)
        assert str(work / "a_file") in line, (name, line)
    assert main(["run", str(_empty_pipeline(work)), str(work / "disc.msh"),
                 "-o", str(work / "a_file" / "run")]) == 1
    line = capsys.readouterr().err.strip().splitlines()[0]
    assert str(work / "a_file" / "run") in line and "internal error" not in line


def _empty_pipeline(w: Path) -> Path:
    p = w / "p.json"
    p.write_text(json.dumps({"filters": [
        {"name": "compute_scalar_by_shape_quality_per_face", "params": {}}]}))
    return p


@pytest.fixture
def read_only(work, monkeypatch):
    """A directory in which nothing can be created (PermissionError), even as root."""
    ro = work / "ro"
    ro.mkdir()
    denied = PermissionError(13, "Permission denied")
    real_mkstemp, real_mkdir = tempfile.mkstemp, Path.mkdir

    def mkstemp(*args, dir=None, **kwargs):
        if dir is not None and Path(dir).resolve().is_relative_to(ro.resolve()):
            raise denied
        return real_mkstemp(*args, dir=dir, **kwargs)

    def mkdir(self, mode=0o777, parents=False, exist_ok=False):
        if self.is_dir() and exist_ok:
            return None  # as os.mkdir: EEXIST comes before EACCES
        if self.resolve().is_relative_to(ro.resolve()):
            raise denied
        return real_mkdir(self, mode, parents, exist_ok)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    monkeypatch.setattr(Path, "mkdir", mkdir)
    return ro


def test_permission_denied_is_one_line_naming_the_path(work, read_only, capsys, no_work):
    for name, argv in _outputs(work, read_only):
        assert main(argv) == 1, name
        line = one_line(capsys)
        assert str(read_only) in line and "Permission denied" in line, (name, line)
    assert list(read_only.iterdir()) == []


def test_permission_denied_in_an_existing_output_directory(work, read_only, capsys, no_work):
    c = _commands(work)
    run = ["run", str(_empty_pipeline(work)), str(work / "disc.msh")]
    for argv in ([*c["deform"], "--frames", "3", "-o", str(read_only)],
                 [*c["move"], "--frames", "3", "-o", str(read_only)],
                 [*c["morph"], "-o", str(read_only)],
                 [*run, "-o", str(read_only)]):  # refused before the first file
        assert main(argv) == 1
        line = one_line(capsys)
        assert f"{read_only}: cannot write in {read_only}: Permission denied" in line


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="root may write into a read-only directory")
def test_real_read_only_directory(work, capsys):  # pragma: no cover - not run as root
    ro = work / "real_ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        for name, argv in _outputs(work, ro):
            assert main(argv) == 1, name
            assert "Permission denied" in one_line(capsys)
    finally:
        ro.chmod(0o755)


# ------------------------------------------------------------------------- pipelines
def test_pipeline_steps_count_from_one_and_dry_run_needs_no_output(work, capsys):
    bad = work / "bad.json"
    bad.write_text(json.dumps({"filters": [
        {"name": "compute_scalar_by_shape_quality_per_face", "params": {}},
        {"name": "apply_coord_shape_optimization", "params": {"penalty": "1,1,1e999,1"}}]}))
    assert main(["run", str(bad), str(work / "disc.msh"), "--dry-run"]) == 1
    err = capsys.readouterr().err
    assert "step 2 (apply_coord_shape_optimization)" in err and "finite" in err
    assert "internal error" not in err
    assert main(["run", str(_empty_pipeline(work)), str(work / "disc.msh"), "--dry-run"]) == 0
    captured = capsys.readouterr()
    assert "dry run: 1 checked, 0 failed, nothing written in " in captured.err
    assert "done" not in captured.err + captured.out
    assert main(["run", str(_empty_pipeline(work)), str(work / "disc.msh")]) == 1
    assert "-o/--output OUTDIR is required" in capsys.readouterr().err


# -------------------------------------------------------------------------- progress
class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_deform_shows_progress_on_a_terminal_only(work, capsys, monkeypatch):
    argv = [*_commands(work)["deform"], "-o", str(work / "a.msh")]
    assert main(argv) == 0
    assert capsys.readouterr().err == ""  # not a terminal (a pipe): no bar
    term = _Terminal()
    monkeypatch.setattr("sys.stderr", term)
    argv[-1] = str(work / "b.msh")
    assert main(argv) == 0
    shown = term.getvalue()
    assert "\rdeform [" in shown and "1000/1000" in shown


def test_deform_progress_callback_reaches_the_end(work):
    from meshopt_toolkit.deform import deform
    from meshopt_toolkit.io import load

    mesh = load(work / "disc.msh").as_planar()
    seen = []
    res = deform(mesh, np.load(work / "v.npy"), time=0.5, progress=seen.append)
    assert len(seen) >= 2 and seen[-1] == 1.0
    assert np.all(np.diff(seen) > 0) and 0 < seen[0]
    plain = deform(mesh, np.load(work / "v.npy"), time=0.5)
    assert np.array_equal(res.mesh.points, plain.mesh.points)
