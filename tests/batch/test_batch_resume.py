"""--resume: the journal skips complete work only; a killed run leaves nothing partial."""

from __future__ import annotations

import json
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import grid_mesh
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import MeshoptError
from meshopt_toolkit.io import save
from meshopt_toolkit.batch.journal import (
    JOURNAL_NAME,
    STAGING_NAME,
    Journal,
    config_sha256,
    file_sha256,
)

PIPE = {"filters": [{"name": "meshing_uniform_refinement"}]}


@pytest.fixture
def batch(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    for i in range(3):
        save(grid_mesh(2, jitter=0.3, seed=i), tmp_path / "in" / f"m{i}.msh")
    (tmp_path / "p.json").write_text(json.dumps(PIPE))
    return tmp_path


def _run(capsys, *extra) -> tuple[int, list[dict], str]:
    status = main(["run", "p.json", "in", "-o", "out", "--json", *extra])
    cap = capsys.readouterr()
    return status, [json.loads(x) for x in cap.out.splitlines()], cap.err


def test_resume_skips_what_is_done_and_says_so(batch, capsys):
    assert _run(capsys)[0] == 0
    stamps = {p.name: p.stat().st_mtime_ns for p in Path("out").glob("*.msh")}
    status, recs, err = _run(capsys, "--resume")
    assert status == 0
    assert [r["status"] for r in recs] == ["skipped"] * 3
    assert recs[0]["outputs"] == [str(Path("out") / "m0.msh")]
    assert err.splitlines()[-1].startswith("meshopt run: 0 done, 3 skipped, 0 failed in ")
    assert {p.name: p.stat().st_mtime_ns for p in Path("out").glob("*.msh")} == stamps
    # without --resume an existing output is refused as always
    status, recs, err = _run(capsys)
    assert status == 1 and "already exists" in recs[0]["error"]


def test_a_changed_input_or_pipeline_is_not_skipped(batch, capsys):
    assert _run(capsys)[0] == 0
    save(grid_mesh(3), Path("in/m1.msh"))  # changed content
    status, recs, err = _run(capsys, "--resume")
    assert [r["status"] for r in recs] == ["skipped", "failed", "skipped"]
    assert "out/m1.msh: already exists (use --force to overwrite)" in recs[1]["error"]
    status, recs, err = _run(capsys, "--resume", "--force")
    assert status == 0 and [r["status"] for r in recs] == ["skipped", "ok", "skipped"]
    Path("p.json").write_text(json.dumps({"filters": PIPE["filters"] * 2}))
    status, recs, err = _run(capsys, "--resume", "--force")
    assert [r["status"] for r in recs] == ["ok", "ok", "ok"]


def test_a_changed_or_missing_output_is_redone(batch, capsys):
    assert _run(capsys)[0] == 0
    Path("out/m0.msh").unlink()
    with open("out/m2.msh", "ab") as f:
        f.write(b"\n")  # changed by the user: not skipped, and not replaced without --force
    status, recs, err = _run(capsys, "--resume")
    assert [r["status"] for r in recs] == ["ok", "skipped", "failed"]
    assert Path("out/m0.msh").exists() and Path("out/m2.msh").read_bytes().endswith(b"\n\n")


def test_leftovers_of_a_killed_run_are_removed(batch, capsys):
    """A killed run's temporaries (recorded in the journal before they were made) are
    removed; files that merely look like temporaries are the user's and survive."""
    out = Path("out")
    out.mkdir()
    with Journal(out) as journal:  # what a run does before it makes them, then killed
        journal.will_create(STAGING_NAME)
        (out / STAGING_NAME / "7").mkdir(parents=True)
        (out / STAGING_NAME / "7" / "m0.msh").write_text("partial")
        journal.will_create(".m1.msh.ab_cd1234.part")
        (out / ".m1.msh.ab_cd1234.part").write_text("partial")
    (out / "notes.part").write_text("the user's")
    (out / ".thesis.2024_v01.part").write_text("the user's")  # named like a temporary
    (out / "sub").mkdir()
    (out / "sub" / ".notes.ABCDEFGH.part").write_text("the user's")
    status, recs, err = _run(capsys, "--resume")
    assert status == 0 and [r["status"] for r in recs] == ["ok"] * 3
    names = sorted(p.name for p in out.iterdir())
    assert names == [".meshopt-journal.db", ".thesis.2024_v01.part", "m0.msh", "m1.msh",
                     "m2.msh", "notes.part", "sub"]
    assert (out / "sub" / ".notes.ABCDEFGH.part").read_text() == "the user's"
    assert (out / ".thesis.2024_v01.part").read_text() == "the user's"
    with Journal(out) as journal:
        assert journal.temporaries() == []
    # a second resume skips everything and still touches none of the user's files
    status, recs, _ = _run(capsys, "--resume")
    assert status == 0 and [r["status"] for r in recs] == ["skipped"] * 3
    assert sorted(p.name for p in out.iterdir()) == names


def test_a_staging_folder_the_journal_did_not_make_is_refused_not_removed(batch, capsys):
    out = Path("out")
    (out / STAGING_NAME).mkdir(parents=True)
    (out / STAGING_NAME / "mine.txt").write_text("the user's")
    status, recs, err = _run(capsys, "--resume")
    assert status == 1 and recs == []
    assert err.strip() == (f"meshopt run: error: {out / STAGING_NAME}: exists but was not "
                           "made by a batch in this directory (not removed); move it away")
    assert (out / STAGING_NAME / "mine.txt").read_text() == "the user's"
    with Journal(out):  # the refused batch let go of its journal's lock
        pass


def test_a_staging_folder_of_an_older_journal_is_adopted(batch, capsys):
    """A journal from before temporaries were recorded: its staging folder is its own."""
    out = Path("out")
    out.mkdir()
    with Journal(out):
        pass
    db = sqlite3.connect(out / JOURNAL_NAME)
    db.execute("DROP TABLE temporaries")
    db.commit()
    db.close()
    (out / STAGING_NAME / "3").mkdir(parents=True)
    status, recs, _ = _run(capsys, "--resume")
    assert status == 0 and [r["status"] for r in recs] == ["ok"] * 3
    assert not (out / STAGING_NAME).exists()


def test_temporaries_outside_the_output_directory_are_refused(tmp_path):
    with Journal(tmp_path) as journal:
        for bad in ("../x.part", str(tmp_path / "x.part")):
            with pytest.raises(MeshoptError, match="outside the output directory"):
                journal.will_create(bad)
        assert journal.temporaries() == []


def test_output_moved_but_not_journaled_is_taken_over(batch, capsys):
    """Killed between moving an output into place and journaling it done: the rerun may
    replace that output (the journal knows it as its own), and nothing else."""
    from meshopt_toolkit.pipeline import Pipeline
    from meshopt_toolkit.batch.file_job import RunOptions
    from meshopt_toolkit.batch.tasks import RunTask

    Path("out").mkdir()
    task = RunTask(Pipeline.from_dict(PIPE), RunOptions())
    src = Path("in/m0.msh")
    key = Journal.key(src, file_sha256(src), config_sha256(task.config()))
    with Journal(Path("out")) as journal:
        journal.will_publish(key, ["m0.msh"])
    Path("out/m0.msh").write_text("an earlier attempt's output")
    Path("out/m1.msh").write_text("the user's own file")
    status, recs, err = _run(capsys, "--resume")
    assert [r["status"] for r in recs] == ["ok", "failed", "ok"]
    assert Path("out/m1.msh").read_text() == "the user's own file"
    assert Path("out/m0.msh").read_bytes()[:4] != b"an e"


def test_the_journal_is_locked_while_a_batch_runs(tmp_path):
    with Journal(tmp_path):
        with pytest.raises(MeshoptError, match="another batch is writing to this directory"):
            Journal(tmp_path)
    Journal(tmp_path).close()  # free again
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / JOURNAL_NAME).write_text("not a database")
    with pytest.raises(MeshoptError, match="not a batch journal"):
        Journal(tmp_path / "x")


def test_convert_resume(batch, capsys):
    assert main(["convert", "in", "-o", "vtu", "--to", "vtu"]) == 0
    assert main(["convert", "in", "-o", "vtu", "--to", "vtu", "--resume", "-j", "2"]) == 0
    assert capsys.readouterr().err.splitlines()[-1].startswith(
        "meshopt convert: 0 done, 3 skipped, 0 failed in ")
    # a different setting is another configuration
    assert main(["convert", "in", "-o", "vtu", "--to", "vtu", "--ascii", "--resume"]) == 1


def test_kill_9_then_resume_does_the_rest_once(batch):
    """A real ``kill -9`` in the middle of a batch, then ``--resume``."""
    for i in range(3, 16):
        save(grid_mesh(2, jitter=0.3, seed=i), batch / "in" / f"m{i:02d}.msh")
    slow = {"filters": [{"name": "meshing_uniform_refinement"}] * 3}
    Path("p.json").write_text(json.dumps(slow))
    cmd = [sys.executable, "-m", "meshopt_toolkit.cli", "run", "p.json", "in", "-o", "out"]
    code = "import sys; from meshopt_toolkit.cli import main; sys.exit(main(sys.argv[1:]))"
    cmd = [sys.executable, "-c", code, *cmd[3:]]
    proc = subprocess.Popen(cmd, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and len(list(Path("out").glob("*.msh"))) < 3:
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = {p.name for p in Path("out").glob("*.msh")}
    assert 3 <= len(before) < 16, "the batch was not killed in the middle"
    done = subprocess.run(cmd + ["--resume", "--json"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    recs = [json.loads(x) for x in done.stdout.splitlines()]
    skipped = {Path(r["input"]).name for r in recs if r["status"] == "skipped"}
    redone = {Path(r["input"]).name for r in recs if r["status"] == "ok"}
    assert len(skipped) + len(redone) == 16 and not skipped & redone
    assert skipped <= before and len(skipped) >= len(before) - 1  # at most one in flight
    assert sorted(p.name for p in Path("out").iterdir() if p.name.startswith(".")) == [
        JOURNAL_NAME]
    assert main(["run", "p.json", "in", "-o", "clean"]) == 0
    for p in Path("clean").glob("*.msh"):
        assert (Path("out") / p.name).read_bytes() == p.read_bytes()
    with sqlite3.connect(Path("out") / JOURNAL_NAME) as db:
        assert db.execute("SELECT count(*) FROM done").fetchone()[0] == 16
        assert db.execute("SELECT count(*) FROM published").fetchone()[0] == 0


def test_one_input_under_two_output_names_is_two_jobs(tmp_path):
    import argparse

    from test_batch import copy_or_fail
    from meshopt_toolkit.batch.run import Job, execute
    from meshopt_toolkit.batch.tasks import ConvertTask

    (tmp_path / "a.txt").write_text("a")
    task = ConvertTask(copy_or_fail, argparse.Namespace())

    def jobs():
        return (Job(i, tmp_path / "a.txt", name) for i, name in enumerate(["x", "y"], 1))

    assert execute(task, jobs(), tmp_path / "out").done == 2
    (tmp_path / "out" / "x").unlink()
    res = execute(task, jobs(), tmp_path / "out", resume=True)
    assert [r["status"] for r in res.records] == ["ok", "skipped"]
