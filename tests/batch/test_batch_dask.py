"""--scheduler / run_batch(client=): a Dask cluster on loopback gives the local results."""

from __future__ import annotations

import json
import socket
from pathlib import Path

import pytest

from conftest import grid_mesh
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import MeshoptError
from meshopt_toolkit.io import save

distributed = pytest.importorskip("distributed")

PIPE = {"filters": [{"name": "meshing_uniform_refinement"},
                    {"name": "apply_coord_shape_optimization",
                     "params": {"variant": "complete-euclidean", "rhs": "1",
                                "penalty": "0.1,0.01,0,0.5", "max_iterations": 2,
                                "tolerance": 0}}]}


@pytest.fixture(scope="module")
def cluster():
    """A scheduler and two worker processes on loopback, shared by the module's tests."""
    import dask

    # a crashing file kills 2 workers (not 4) before it fails: keeps the crash test short
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                     host="127.0.0.1", dashboard_address=None) as c:
        yield c.scheduler_address


@pytest.fixture
def batch(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    for i in range(4):
        save(grid_mesh(2, jitter=0.3, seed=i), tmp_path / "in" / f"m{i}.msh")
    (tmp_path / "in" / "bad.msh").write_text("garbage")
    (tmp_path / "p.json").write_text(json.dumps(PIPE))
    return tmp_path


def _run(capsys, out: str, *extra) -> tuple[int, list[dict], str]:
    status = main(["run", "p.json", "in", "-o", out, "--to", "vtu", "--json", *extra])
    cap = capsys.readouterr()
    recs = [json.loads(x) for x in cap.out.splitlines()]
    for r in recs:
        r.pop("seconds")
        r["outputs"] = [Path(o).name for o in r["outputs"]]
        for step in r["results"]:
            step.pop("seconds", None)
    return status, recs, cap.err


@pytest.mark.parametrize("how", [[], ["--shared-inputs"]], ids=["bytes", "shared-path"])
def test_cluster_gives_the_local_results(batch, cluster, capsys, how):
    status, local, _ = _run(capsys, "local")
    assert status == 1 and [r["status"] for r in local] == ["failed"] + ["ok"] * 4
    status, remote, err = _run(capsys, "remote", "--scheduler", cluster, *how)
    assert status == 1
    assert remote == local  # inputs, statuses, errors, step results, output names
    for name in (f"m{i}.vtu" for i in range(4)):
        assert (Path("remote") / name).read_bytes() == (Path("local") / name).read_bytes()
    assert err.splitlines()[-1].startswith("meshopt run: 4 done, 0 skipped, 1 failed in ")
    status, again, err = _run(capsys, "remote", "--scheduler", cluster, "--resume", *how)
    assert [r["status"] for r in again] == ["failed"] + ["skipped"] * 4


def test_run_batch_with_a_notebook_client(batch, cluster):
    import meshopt_toolkit as mt

    inputs = sorted(Path("in").glob("m*.msh"))
    with distributed.Client(cluster, set_as_default=False) as client:
        res = mt.run_batch(PIPE, inputs, "out", client=client)
    local = mt.run_batch(PIPE, inputs, "out_local")
    assert (res.done, res.failed) == (4, 0)
    assert [r["results"][1]["objective"] for r in res.records] == \
        [r["results"][1]["objective"] for r in local.records]
    for p in inputs:
        assert (Path("out") / p.name).read_bytes() == (Path("out_local") / p.name).read_bytes()


def test_a_dry_run_is_checked_here(batch, cluster, capsys):
    """A dry run runs no filter: it is checked by the client, against the real outputs."""
    assert main(["run", "p.json", "in/m0.msh", "-o", "out", "--to", "vtu"]) == 0
    status = main(["run", "p.json", "in/m0.msh", "in/m1.msh", "-o", "out", "--to", "vtu",
                   "--dry-run", "--scheduler", cluster])
    err = capsys.readouterr().err
    assert status == 1 and "m0.vtu: already exists" in err
    assert "dry run: 1 checked, 1 failed, nothing written in " in err


def test_allow_read_needs_shared_inputs(batch, cluster, capsys):
    status = main(["run", "p.json", "in", "-o", "o", "--scheduler", cluster,
                   "--allow-read", "in"])
    assert status == 1
    err = capsys.readouterr().err
    assert "--allow-read" in err and "add --shared-inputs" in err


def test_unreachable_scheduler_is_one_line(batch, capsys, monkeypatch):
    from meshopt_toolkit.batch import cluster as backend

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setattr(backend, "CONNECT_TIMEOUT", 0.5)
    assert main(["run", "p.json", "in", "-o", "o", "--scheduler", f"tcp://127.0.0.1:{port}"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"meshopt run: error: p.json: cannot reach the Dask scheduler at "
                          f"tcp://127.0.0.1:{port}: ") and err.count("\n") == 1
    with pytest.raises(MeshoptError, match="cannot reach"):
        backend.connect("tcp://127.0.0.1:%d" % port, timeout=0.5)


def test_a_crash_on_the_cluster_fails_only_its_file(tmp_path, cluster):
    """Last in this module: it kills workers (their nannies restart them)."""
    import argparse

    from test_batch import copy_or_fail
    from meshopt_toolkit.batch.run import Job, execute
    from meshopt_toolkit.batch.tasks import ConvertTask

    names = ["a.txt", "b_abort.txt", "c.txt", "d_oom.txt", "e.txt", "f.txt"]
    for n in names:
        (tmp_path / n).write_text(n)
    task = ConvertTask(copy_or_fail, argparse.Namespace(), ".out")
    with distributed.Client(cluster, set_as_default=False) as client:
        res = execute(task, (Job(i, tmp_path / n) for i, n in enumerate(names, 1)),
                      tmp_path / "out", client=client)
    assert [r["status"] for r in res.records] == ["ok", "failed", "ok", "failed", "ok", "ok"]
    assert "each Dask worker that ran it died (KilledWorker" in res.records[1]["error"]
    assert res.records[3]["error"].endswith("out of memory (MemoryError)")
    assert (tmp_path / "out" / "c.out").read_text().startswith("c.txt")
