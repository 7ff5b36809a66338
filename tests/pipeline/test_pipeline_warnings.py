"""A pipeline's warnings are plain lines in the file's record and on stderr, naming the
user's input and output, never a log-style ``WARNING:...`` line or a path in the batch's
scratch folder."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

from meshopt_toolkit import data_path
from meshopt_toolkit.batch.file_job import kept_warnings, run_file

QUALITY = {"name": "compute_scalar_by_shape_quality_per_face"}
#: what the STL writer says of the data it cannot hold (the face quality among them)
LOST = "STL files cannot hold "


@pytest.fixture
def work(tmp_path):
    (tmp_path / "in" / "sub").mkdir(parents=True)  # a sub-folder not searched: a warning
    (tmp_path / "in" / "disc.msh").write_bytes(data_path("disc_25.msh").read_bytes())
    (tmp_path / "disc.msh").write_bytes(data_path("disc_25.msh").read_bytes())
    (tmp_path / "quality.json").write_text(json.dumps({"filters": [QUALITY]}))
    return tmp_path


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_a_logged_warning_is_one_plain_line_in_the_record(work, jobs):
    """Through the installed command line (a fresh process: its logging as a user's),
    in this process and in worker processes."""
    folder, out = work / "in", work / "out"
    src = folder / "disc.msh"
    code = ("import sys; from meshopt_toolkit.cli import main; "
            "raise SystemExit(main(sys.argv[1:]))")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    done = subprocess.run([sys.executable, "-c", code, "run", str(work / "quality.json"),
                           str(folder), "-o", str(out), "--to", ".stl", "--json", "-j", jobs],
                          capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    record = json.loads(done.stdout)
    assert [w for w in record["warnings"]
            if w.startswith(f"{out / 'disc.stl'}: {LOST}") and "quality" in w], record
    lines = done.stderr.strip().splitlines()
    warned = [ln for ln in lines if "warning" in ln.lower()]
    # the driver's own, as plainly; run has no --recursive, so the hint names what works
    assert f"meshopt run: warning: {folder}: 1 sub-folder(s) not searched (sub); name " \
           "them as inputs to include them" in warned
    assert [ln for ln in warned if ln.startswith(f"meshopt run: warning: {src}: ")]
    assert all(ln.startswith("meshopt run: warning: ") for ln in warned), warned
    assert not [ln for ln in lines if ln.startswith("WARNING")], lines
    assert ".meshopt-staging" not in done.stderr + done.stdout


def test_run_file_keeps_the_warnings_it_logs(work):
    rec = run_file({"filters": [QUALITY]}, work / "disc.msh", work, ext=".stl")
    assert rec["status"] == "ok"
    assert [w for w in rec["warnings"]
            if w.startswith(f"{work / 'disc.stl'}: {LOST}") and "quality" in w], rec


def test_kept_warnings_are_this_threads_and_not_printed(caplog):
    log = logging.getLogger("meshopt_toolkit.test")
    with kept_warnings() as lines:
        log.warning("a %s\nin two lines", "warning")
        log.info("not a warning")
    assert lines == ["a warning in two lines"]
    assert logging.getLogger("meshopt_toolkit").propagate  # printed again afterwards


def test_a_warning_naming_its_input_names_it_once(tmp_path, capsys, monkeypatch):
    """The library's warning about a file (normals recomputed for moved vertices) is printed
    with the input named once, not once by the batch and again by the message."""
    from meshopt_toolkit.cli import main

    trimesh = pytest.importorskip("trimesh")
    (tmp_path / "in").mkdir()
    src = tmp_path / "in" / "ball.obj"
    trimesh.creation.icosphere(2).export(str(src), include_normals=True)
    (tmp_path / "p.json").write_text(json.dumps({"filters": [{
        "name": "apply_coord_prescribed_motion",
        "params": {"where": "z > 0.5", "map": "x; y; z + 0.2"}}]}))
    monkeypatch.chdir(tmp_path)
    assert main(["run", "p.json", "in", "-o", "out"]) == 0
    warned = [ln for ln in capsys.readouterr().err.splitlines() if "normals recomputed" in ln]
    assert len(warned) == 1 and warned[0].count("ball.obj") == 1, warned
