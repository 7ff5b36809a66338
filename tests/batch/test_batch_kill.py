"""``kill -9`` of a batch with worker processes: the workers die with it, and a ``--resume``
started at once finishes every file with the bytes of a clean run."""

from __future__ import annotations

import contextlib
import json
import os
import queue
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import grid_mesh
from gmsh_files import box_with_hole_msh
from meshopt_toolkit.batch.journal import JOURNAL_NAME
from meshopt_toolkit.io import load_cells, save

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(),
                                reason="reads the process table from /proc")

CODE = "import sys; from meshopt_toolkit.cli import main; sys.exit(main(sys.argv[1:]))"
#: each file's farthest vertex from its centroid moves outward by 2 % of its size
PIPE = {"filters": [{"name": "apply_coord_prescribed_motion",
                     "params": {"targets": "../targets/{stem}.csv"}}]}


def _inputs(root: Path) -> None:
    """Seven small meshes: planar (three grids, a gmsh disc), two closed surfaces in
    space, one tet mesh; and each one's target CSV."""
    import trimesh

    from meshopt_toolkit import data

    pytest.importorskip("gmsh")

    src, targets = root / "in", root / "targets"
    src.mkdir()
    targets.mkdir()
    for i in range(3):
        save(grid_mesh(5, jitter=0.3, seed=i), src / f"plane{i}.msh")
    (src / "disc.msh").write_bytes((Path(data.__file__).parent / "disc_77.msh").read_bytes())
    trimesh.creation.icosphere(subdivisions=2).export(src / "ball.obj")
    trimesh.creation.cylinder(radius=1, height=2, sections=16).export(src / "can.off")
    box_with_hole_msh(src / "body.msh", radius=0.4, size=0.5)
    for p in src.iterdir():
        pts = np.asarray(load_cells(p).points, dtype=float)
        if pts.shape[1] == 3 and not pts[:, 2].any():
            pts = pts[:, :2]
        away = pts - pts.mean(axis=0)
        i = int(np.argmax(np.linalg.norm(away, axis=1)))
        q = pts[i] + 0.02 * np.ptp(pts, axis=0).max() * away[i] / np.linalg.norm(away[i])
        (targets / f"{p.stem}.csv").write_text(",".join([str(i), *map(repr, q.tolist())]))
    (root / "p.json").write_text(json.dumps(PIPE))


def _children(pid: int) -> set[tuple[int, str]]:
    """``(pid, start time)`` of the live children of ``pid`` (the start time tells a
    reused pid apart)."""
    kids = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            fields = _stat(int(entry))
            if fields is not None and int(fields[1]) == pid and fields[0] != "Z":
                kids.add((int(entry), fields[19]))
    return kids


def _stat(pid: int) -> list[str] | None:
    """The fields of ``/proc/PID/stat`` after the command name (state first), or None."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()
    except OSError:
        return None


def _alive(kid: tuple[int, str]) -> bool:
    fields = _stat(kid[0])
    return fields is not None and fields[0] != "Z" and fields[19] == kid[1]


def _lines(stream) -> queue.Queue:
    """The lines of ``stream`` as they come (None at its end), read by a thread."""
    q: queue.Queue = queue.Queue()

    def pump():
        for line in stream:
            q.put(line)
        q.put(None)

    threading.Thread(target=pump, daemon=True).start()
    return q


@pytest.mark.slow
def test_workers_die_with_a_killed_batch_and_resume_finishes_every_file(tmp_path,
                                                                        monkeypatch):
    monkeypatch.chdir(tmp_path)
    _inputs(tmp_path)
    n = len(list(Path("in").iterdir()))
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    cmd = [sys.executable, "-c", CODE, "run", "p.json", "in", "--allow-read", "targets",
           "-j", "2", "--json", "-o"]
    clean = subprocess.run(cmd + ["clean"], capture_output=True, text=True, env=env)
    assert clean.returncode == 0, clean.stderr

    with open("killed.err", "w") as err:
        proc = subprocess.Popen(cmd + ["out"], stdout=subprocess.PIPE, stderr=err, text=True,
                                env=env)
    lines = _lines(proc.stdout)
    # kill when one file is done (its record comes after the journal has it) and the
    # others are not: the journal itself is locked while the batch runs
    first = lines.get(timeout=600)
    assert first is not None and json.loads(first)["status"] == "ok", first
    workers = _children(proc.pid)
    proc.send_signal(signal.SIGKILL)
    killed_at = time.monotonic()
    proc.wait()
    assert len(workers) >= 2  # both workers (and multiprocessing's resource tracker)

    # immediately: a resume, while the workers would still be running if they could
    resume = subprocess.Popen(cmd + ["out", "--resume"], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, env=env)
    while any(map(_alive, workers)) and time.monotonic() - killed_at < 2.5:
        time.sleep(0.01)
    lived = time.monotonic() - killed_at
    alive = [kid[0] for kid in workers if _alive(kid)]
    out, err = resume.communicate(timeout=600)
    assert not alive, f"workers {alive} still run {lived:.1f} s after the batch was killed"
    # a worker that outlived its batch and then ended says so on stderr: none did
    assert "Traceback" not in Path("killed.err").read_text()

    assert resume.returncode == 0, err
    recs = [json.loads(x) for x in out.splitlines()]
    status = [r["status"] for r in recs]
    assert len(recs) == n and "skipped" in status and "ok" in status, status
    assert err.splitlines()[-1].startswith(f"meshopt run: {status.count('ok')} done, "
                                           f"{status.count('skipped')} skipped, 0 failed")
    made = sorted(p.name for p in Path("clean").iterdir() if not p.name.startswith("."))
    assert len(made) == n
    assert sorted(p.name for p in Path("out").iterdir()) == sorted([JOURNAL_NAME, *made])
    for name in made:
        assert (Path("out") / name).read_bytes() == (Path("clean") / name).read_bytes(), name
    with contextlib.closing(sqlite3.connect(Path("out") / JOURNAL_NAME)) as db:
        assert db.execute("SELECT count(*) FROM done").fetchone()[0] == n


WATCHED = '''
import multiprocessing, os, sys, time


def busy(parent_pid):
    sys.platform = "elsewhere"  # no kernel death signal: the portable watch alone
    from meshopt_toolkit.batch.workers import _die_with_parent

    _die_with_parent(parent_pid)
    print("watching", flush=True)
    while True:  # Python code holding the GIL
        sum(range(10000))


if __name__ == "__main__":
    child = multiprocessing.get_context("spawn").Process(target=busy, args=(os.getpid(),))
    child.start()
    print(child.pid, flush=True)
    time.sleep(600)
'''


def test_without_the_kernel_signal_a_worker_still_ends_with_its_parent(tmp_path):
    (tmp_path / "watched.py").write_text(WATCHED)
    proc = subprocess.Popen([sys.executable, str(tmp_path / "watched.py")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=tmp_path)
    lines = _lines(proc.stdout)
    kid = (0, "")
    try:
        pid = int(lines.get(timeout=300))
        kid = next((k for k in _children(proc.pid) if k[0] == pid), kid)
        deadline = time.monotonic() + 300
        while lines.empty():  # until the watch is in place, or the child ended
            assert _alive(kid) and time.monotonic() < deadline
            time.sleep(0.01)
        assert lines.get() == "watching\n"
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        killed_at = time.monotonic()
        while _alive(kid) and time.monotonic() - killed_at < 2.5:
            time.sleep(0.01)
        assert not _alive(kid)
        assert proc.stderr.read() == ""
    finally:
        proc.kill()
        if _alive(kid):
            os.kill(kid[0], signal.SIGKILL)
