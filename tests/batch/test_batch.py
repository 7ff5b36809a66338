"""Batches in worker processes: isolation per file, order, bounded look-ahead, progress, API."""

from __future__ import annotations

import io
import json
import os
import shutil
import sys
from pathlib import Path

import pytest

import meshopt_toolkit as mt
from conftest import grid_mesh, square5
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import MeshoptError
from meshopt_toolkit.io import load, save
from meshopt_toolkit.batch.progress import BatchProgress
from meshopt_toolkit.batch.run import Job, execute
from meshopt_toolkit.batch.tasks import ConvertTask
from meshopt_toolkit.batch.workers import ProcessPool, WorkerCrash

PIPE = {"filters": [{"name": "meshing_uniform_refinement"},
                    {"name": "apply_coord_shape_optimization",
                     "params": {"variant": "complete-euclidean", "rhs": "1",
                                "penalty": "0.1,0.01,0,0.5", "max_iterations": 2,
                                "tolerance": 0}}]}


def copy_or_fail(src: Path, dst: Path, args) -> None:
    """A per-file step for tests: aborts, runs out of memory or fails by the file's name."""
    if "abort" in src.name:
        os.abort()
    if "oom" in src.name:
        raise MemoryError
    if "bad" in src.name:
        raise MeshoptError(f"{src}: bad on purpose")
    shutil.copyfile(src, dst)
    with open(dst, "a") as f:
        f.write(f"# pid {os.getpid()}\n")


def _pid(path: Path) -> int:
    return int(path.read_text().rsplit("# pid ", 1)[1])


@pytest.fixture
def meshes(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    for i in range(5):
        save(grid_mesh(2, jitter=0.3, seed=i), tmp_path / "in" / f"m{i}.msh")
    (tmp_path / "p.json").write_text(json.dumps(PIPE))
    return sorted((tmp_path / "in").glob("*.msh"))


def _records(out: str) -> list[dict]:
    recs = [json.loads(line) for line in out.splitlines()]
    for r in recs:
        r.pop("seconds")
        for step in r["results"]:
            step.pop("seconds", None)
    return recs


def test_jobs_2_gives_the_same_records_and_files_as_jobs_1(meshes, capsys):
    assert main(["run", "p.json", "in", "-o", "one", "--json"]) == 0
    one = _records(capsys.readouterr().out)
    assert main(["run", "p.json", "in", "-o", "two", "--json", "-j", "2"]) == 0
    cap = capsys.readouterr()
    two = _records(cap.out)
    assert [r["input"] for r in two] == [str(Path("in") / p.name) for p in meshes]  # in order
    assert [{**r, "outputs": [o.replace("two", "one") for o in r["outputs"]]} for r in two] == one
    for p in meshes:
        assert (Path("two") / p.name).read_bytes() == (Path("one") / p.name).read_bytes()
    assert "5 done, 0 skipped, 0 failed in " in cap.err.splitlines()[-1]
    assert not (Path("two") / ".meshopt-staging").exists()


def test_a_crash_or_a_memory_error_fails_only_its_file(tmp_path):
    names = ["a.txt", "b_abort.txt", "c.txt", "d_oom.txt", "e.txt", "f_bad.txt", "g.txt"]
    for n in names:
        (tmp_path / n).write_text(n)
    task = ConvertTask(copy_or_fail, __import__("argparse").Namespace(), ".out")
    jobs = (Job(i, tmp_path / n) for i, n in enumerate(names, 1))
    res = execute(task, jobs, tmp_path / "out", workers=2)
    assert [r["input"] for r in res.records] == [str(tmp_path / n) for n in names]
    status = {Path(r["input"]).name: r["status"] for r in res.records}
    assert status == {"a.txt": "ok", "b_abort.txt": "failed", "c.txt": "ok",
                      "d_oom.txt": "failed", "e.txt": "ok", "f_bad.txt": "failed",
                      "g.txt": "ok"}
    errors = {Path(r["input"]).name: r["error"] for r in res.records if r["error"]}
    assert "crashed (killed by SIGABRT" in errors["b_abort.txt"]
    assert "out of memory" in errors["d_oom.txt"]
    assert errors["f_bad.txt"].endswith("bad on purpose")
    assert (res.done, res.skipped, res.failed) == (4, 0, 3)
    outs = sorted(p.name for p in (tmp_path / "out").iterdir() if not p.name.startswith("."))
    assert outs == ["a.out", "c.out", "e.out", "g.out"]
    assert (tmp_path / "out" / "a.out").read_text().startswith("a.txt")


def test_a_memory_error_retires_its_worker(tmp_path):
    """The worker that ran out of memory is replaced: the next file runs in a new process."""
    for n in ("a_oom.txt", "b.txt"):
        (tmp_path / n).write_text(n)
    pool = ProcessPool(ConvertTask(copy_or_fail, __import__("argparse").Namespace()), 1)
    try:
        (tmp_path / "o").mkdir()
        pool.submit(0, (str(tmp_path / "b.txt"), 1, "b1", str(tmp_path / "o")))
        [(_, rec)] = pool.wait()
        pool.submit(1, (str(tmp_path / "a_oom.txt"), 2, "a", str(tmp_path / "o")))
        [(_, rec)] = pool.wait()
        assert rec["status"] == "failed" and "out of memory" in rec["error"]
        pool.submit(2, (str(tmp_path / "b.txt"), 3, "b2", str(tmp_path / "o")))
        [(_, rec)] = pool.wait()
        assert _pid(tmp_path / "o" / "b1") != _pid(tmp_path / "o" / "b2")
    finally:
        pool.close()


def test_crash_description_names_the_signal():
    assert "SIGABRT" in WorkerCrash(-6).describe()
    assert "out of memory?" in WorkerCrash(-9).describe()
    assert "exit status 3" in WorkerCrash(3).describe()


def test_inputs_are_consumed_lazily_with_a_bounded_look_ahead(tmp_path):
    """100,000 inputs must not be read up front: at most a window is in flight."""
    (tmp_path / "a.txt").write_text("x")
    pulled = 0

    def jobs():
        nonlocal pulled
        for i in range(1, 201):
            pulled += 1
            yield Job(i, tmp_path / "a.txt", f"{i}.out")

    ahead = []
    task = ConvertTask(copy_or_fail, __import__("argparse").Namespace())
    res = execute(task, jobs(), tmp_path / "out", workers=1,
                  on_record=lambda rec: ahead.append(pulled - len(ahead)))
    assert res.records is None and res.done == 200
    assert max(ahead) <= 4 * 1 + 8  # the window of one executor slot
    assert ahead[0] < 20


def test_jobs_option(meshes, capsys):
    from meshopt_toolkit.batch.workers import cpu_count

    with pytest.raises(SystemExit) as exc:
        main(["run", "p.json", "in", "-o", "o", "-j", "-1"])
    assert exc.value.code == 2
    assert "expected 0 (all cores)" in capsys.readouterr().err
    from meshopt_toolkit.cli import build_parser

    args = build_parser().parse_args(["run", "p.json", "in", "-o", "o", "-j", "0"])
    assert args.jobs == cpu_count()
    assert main(["run", "p.json", "in", "-o", "o", "-j", "2", "--isolate", "never"]) == 1
    assert "--isolate never needs --jobs 1" in capsys.readouterr().err
    assert main(["convert", "in", "-o", "o", "--to", "vtu", "--shared-inputs"]) == 1
    assert "--shared-inputs is for --scheduler" in capsys.readouterr().err


def test_convert_in_parallel_and_a_bad_file(meshes, capsys):
    Path("in/bad.obj").write_text("v 0 0 0\nf 1 2 3\n")
    assert main(["convert", "in", "-o", "vtu", "--to", "vtu", "-j", "2"]) == 1
    err = capsys.readouterr().err
    assert "bad.obj" in err and err.splitlines()[-1].startswith(
        "meshopt convert: 5 done, 0 skipped, 1 failed in ")
    for p in meshes:
        assert load(Path("vtu") / (p.stem + ".vtu")) == load(p)


def test_cli_crash_with_two_workers(tmp_path, capsys, monkeypatch):
    from test_pipeline_plugin import make_plugin_dir
    from meshopt_toolkit.pipeline import registry

    site = make_plugin_dir(tmp_path, broken=False)
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.setattr(registry, "_plugins_loaded", False)
    monkeypatch.chdir(tmp_path)
    try:
        for name in ("a", "b_bad", "c", "d"):
            save(square5(), tmp_path / f"{name}.msh")
        (tmp_path / "p.json").write_text(json.dumps({"filters": [
            {"name": "demo_crash", "params": {"marker": "bad"}},
            {"name": "meshing_uniform_refinement"}]}))
        assert main(["run", "p.json", "a.msh", "b_bad.msh", "c.msh", "d.msh", "-o", "out",
                     "-j", "2", "--json"]) == 1
        cap = capsys.readouterr()
        assert [json.loads(x)["status"] for x in cap.out.splitlines()] == [
            "ok", "failed", "ok", "ok"]
        assert "b_bad.msh: the worker process crashed" in cap.err
        assert "3 done, 0 skipped, 1 failed in " in cap.err
        assert load(tmp_path / "out" / "d.msh") == square5().refine()
    finally:
        for name in ("demo_scale", "demo_crash"):
            registry.unregister(name)
        for mod in [m for m in sys.modules if m.startswith("meshopt_demo_plugin")]:
            del sys.modules[mod]


def test_progress_bar_counts_and_stays_out_of_pipes(meshes, capsys):
    stream = io.StringIO()
    bar = BatchProgress(4, "run", stream=stream, enabled=True)
    for status in ("ok", "failed", "skipped"):
        bar._last = 0.0
        bar.record(status)
    text = stream.getvalue().rsplit("\r", 1)[-1]
    assert "3/4" in text and "1 done" in text and "1 skipped" in text and "1 failed" in text
    assert "files/s" in text and "left" in text
    bar.close()
    quiet = io.StringIO()  # not a terminal: nothing at all
    bar = BatchProgress(2, "run", stream=quiet)
    bar.record("ok")
    bar.close()
    assert quiet.getvalue() == ""
    assert main(["run", "p.json", "in", "-o", "o"]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err and err.count("\n") == 1


def test_run_batch_api(meshes, tmp_path):
    res = mt.run_batch(PIPE, (p for p in meshes), tmp_path / "api", jobs=2,
                       options={"ext": "vtu"})
    assert (res.done, res.skipped, res.failed) == (5, 0, 0) and res.ok
    assert [r["outputs"] for r in res.records] == [[str(tmp_path / "api" / f"{p.stem}.vtu")]
                                                   for p in meshes]
    again = mt.run_batch(tmp_path / "p.json", meshes, tmp_path / "api", options={"ext": ".vtu"},
                         resume=True,
                         on_record=lambda r: None)
    assert again.records is None and (again.done, again.skipped) == (0, 5)
    assert again.report().startswith("0 done, 5 skipped, 0 failed in ")
    with pytest.raises(MeshoptError, match="jobs=-2"):
        mt.run_batch(PIPE, meshes, tmp_path / "x", jobs=-2)


def test_missing_dask_is_one_line(meshes, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    assert main(["run", "p.json", "in", "-o", "o", "--scheduler", "tcp://127.0.0.1:1"]) == 1
    err = capsys.readouterr().err
    assert err.strip() == ("meshopt run: error: p.json: a Dask cluster needs dask.distributed: "
                           "pip install 'meshopt-toolkit[dask]'")


def test_convert_recursive_in_parallel_then_resume(meshes, capsys):
    Path("in/sub").mkdir()
    save(grid_mesh(3), Path("in/sub/deep.msh"))
    assert main(["convert", "in", "-r", "-o", "out", "--to", "vtu", "-j", "2"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith(f"wrote {Path('out') / 'sub' / 'deep.vtu'} (16 vertices, ")
    assert len(out) == 6 and load(Path("out/sub/deep.vtu")) == grid_mesh(3)
    assert main(["convert", "in", "-r", "-o", "out", "--to", "vtu", "--resume"]) == 0
    cap = capsys.readouterr()
    assert cap.out == "" and "0 done, 6 skipped, 0 failed in " in cap.err
