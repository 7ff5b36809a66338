"""Inputs that are not regular files (a device, a FIFO, a socket) are refused quickly by
every command, with one line naming the file and the cause; none is ever read."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import grid_mesh
from meshopt_toolkit.errors import ReadError
from meshopt_toolkit.io import save
from meshopt_toolkit.io import _files

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX special files")

MESHOPT = [sys.executable, "-c", "import sys; from meshopt_toolkit.cli import main; "
           "sys.exit(main(sys.argv[1:]))"]
CAUSE = {"zero": "is a character device, not a regular file",
         "fifo": "is a FIFO (named pipe), not a regular file",
         "socket": "is a socket, not a regular file"}


@pytest.fixture
def special(tmp_path, monkeypatch):
    """``{kind: path}`` of a symlink to /dev/zero, a FIFO and a bound Unix socket, all
    named ``.msh``, and a good mesh and a pipeline in ``tmp_path`` (the cwd)."""
    monkeypatch.chdir(tmp_path)
    os.symlink("/dev/zero", "zero.msh")
    os.mkfifo("fifo.msh")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.bind("socket.msh")  # relative: a Unix socket path is limited to ~100 bytes
    save(grid_mesh(2), "good.msh")
    Path("p.json").write_text(json.dumps({"filters": []}))
    yield {"zero": Path("zero.msh"), "fifo": Path("fifo.msh"), "socket": Path("socket.msh")}
    sock.close()


def _meshopt(*args) -> subprocess.CompletedProcess:
    """Run the CLI in a child; a hang fails the test (TimeoutExpired) instead of blocking."""
    return subprocess.run([*MESHOPT, *args], capture_output=True, text=True, timeout=60)


def _expected(kind: str, path: Path) -> str:
    link = f" (-> {os.path.realpath(path)})" if kind == "zero" else ""
    return f"{path}{link}: {CAUSE[kind]}"


@pytest.mark.parametrize("kind", ["zero", "fifo", "socket"])
def test_run_info_convert_refuse_special_files(special, kind):
    path = special[kind]
    t0 = time.perf_counter()
    run = _meshopt("run", "p.json", str(path), "-o", "out")
    info = _meshopt("info", str(path))
    conv = _meshopt("convert", str(path), "-o", "o.vtu")
    assert time.perf_counter() - t0 < 60
    msg = _expected(kind, path)
    assert run.returncode == 1
    assert run.stderr.splitlines()[0] == f"meshopt run: error: {msg}"
    assert run.stderr.splitlines()[1].startswith("meshopt run: 0 done, 0 skipped, 1 failed")
    assert (info.returncode, info.stderr) == (1, f"meshopt info: error: {msg}\n")
    assert (conv.returncode, conv.stderr) == (1, f"meshopt convert: error: {msg}\n")
    assert "Traceback" not in run.stderr + info.stderr + conv.stderr
    assert not Path("o.vtu").exists()
    assert [p.name for p in Path("out").iterdir()] == [".meshopt-journal.db"]


def test_batches_fail_the_special_files_only(special):
    """In a batch (several inputs, worker processes) each special file fails alone."""
    names = ["good.msh", *map(str, special.values())]
    conv = _meshopt("convert", *names, "-o", "conv", "--to", "vtu", "-j", "2")
    assert conv.returncode == 1, conv.stderr
    assert sorted(p.name for p in Path("conv").iterdir()) == [".meshopt-journal.db", "good.vtu"]
    for kind, path in special.items():
        assert _expected(kind, path) in conv.stderr
    assert conv.stderr.splitlines()[-1].startswith("meshopt convert: 1 done, 0 skipped, 3 failed")
    run = _meshopt("run", "p.json", *names, "-o", "out", "--json", "--resume")
    recs = [json.loads(line) for line in run.stdout.splitlines()]
    assert run.returncode == 1
    assert [r["status"] for r in recs] == ["ok", "failed", "failed", "failed"]
    assert [r["error"] for r in recs[1:]] == [_expected(k, p) for k, p in special.items()]


def test_open_input_never_opens_a_fifo_and_reads_regular_files(tmp_path):
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    with pytest.raises(ReadError, match="is a FIFO"):
        _files.open_input(fifo)  # stat first: no open, so no block
    regular = tmp_path / "r.bin"
    regular.write_bytes(b"abc")
    with _files.open_input(regular) as fh:
        assert fh.read() == b"abc"
    assert _files.read_input(regular) == b"abc"
    with pytest.raises(ReadError, match="larger than the limit of 2 bytes"):
        _files.read_input(regular, max_bytes=2)
    with pytest.raises(ReadError, match="no such file"):
        _files.open_input(tmp_path / "missing")


def test_open_input_refuses_a_file_swapped_after_its_stat(tmp_path, monkeypatch):
    """The descriptor is checked again: another file behind the name is refused."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.write_bytes(b"a")
    b.write_bytes(b"b")
    real = _files._stat_regular
    monkeypatch.setattr(_files, "_stat_regular", lambda p, m: real(b, m))
    with pytest.raises(ReadError, match="changed while being opened"):
        _files.open_input(a)


def test_a_pipeline_file_that_is_a_fifo_is_refused(special):
    os.mkfifo("pipe.json")
    run = _meshopt("run", "pipe.json", "good.msh", "-o", "out")
    assert (run.returncode, run.stderr) == (
        1, "meshopt run: error: pipe.json: is a FIFO (named pipe), not a regular file\n")


def test_special_files_in_an_input_directory_are_named_not_skipped(special):
    os.mkdir("in")
    os.rename("good.msh", "in/good.msh")
    os.mkfifo("in/pipe.msh")
    run = _meshopt("run", "p.json", "in", "-o", "out", "--json")
    recs = [json.loads(line) for line in run.stdout.splitlines()]
    assert run.returncode == 1
    assert [(r["input"], r["status"]) for r in recs] == [("in/good.msh", "ok"),
                                                         ("in/pipe.msh", "failed")]
    assert recs[1]["error"] == "in/pipe.msh: is a FIFO (named pipe), not a regular file"
