"""Fuzzing the readers: random bytes and mutated valid files of each format
never give a traceback (only MeshoptError subclasses), never hang (5 s), and a failed
conversion leaves no output and no partial file."""

from __future__ import annotations

import signal
import time
from contextlib import contextmanager

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from meshopt_toolkit.errors import MeshoptError
from meshopt_toolkit.io import CellMesh, load, load_cells, save_cells
from meshopt_toolkit.cli.convert import ConvertOptions, convert_file

EXTS = [".msh", ".obj", ".off", ".ply", ".vtk", ".vtu", ".stl", ".mesh"]
LIMIT_S = 5.0


def _sample() -> CellMesh:
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0.]])
    cells = [("triangle", np.array([[0, 1, 2], [1, 3, 2], [1, 4, 3], [4, 5, 3]]))]
    return CellMesh(pts, cells)


@pytest.fixture(scope="module")
def valid_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("valid")
    out = {}
    for ext in EXTS:
        for binary in ((True, False) if ext not in (".obj", ".off", ".mesh") else (None,)):
            for version in (("4.1", "2.2") if ext == ".msh" else ("4.1",)):
                path = d / f"v{len(out)}{ext}"
                save_cells(_sample(), path, binary=binary, msh_version=version)
                out[path.name] = (ext, path.read_bytes())
    return out


@contextmanager
def deadline(seconds: float):
    def alarm(signum, frame):
        raise TimeoutError(f"reader ran over {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def check_reader(path) -> None:
    """Reading gives a mesh or a MeshoptError, within the limit; converting a file that
    fails leaves nothing behind."""
    start = time.perf_counter()
    with deadline(LIMIT_S):
        for read in (load_cells, load):
            try:
                read(path)
            except MeshoptError:
                pass
        out = path.with_name("out.vtu")
        try:
            convert_file(path, out, ConvertOptions(force=True))
        except MeshoptError:
            assert not out.exists()
        else:
            out.unlink()
    assert time.perf_counter() - start < LIMIT_S
    leftovers = [p.name for p in path.parent.iterdir() if p.name.endswith(".part")]
    assert leftovers == []


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(ext=st.sampled_from(EXTS), data=st.binary(max_size=600))
def test_random_bytes(tmp_path, ext, data):
    path = tmp_path / f"r{ext}"
    path.write_bytes(data)
    check_reader(path)


@st.composite
def mutations(draw, original: bytes) -> bytes:
    data = bytearray(original)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["flip", "cut", "insert", "delete", "digit"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "flip" and data:
            data[at] = draw(st.integers(0, 255))
        elif kind == "cut":
            del data[at:]
        elif kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
        elif kind == "delete":
            del data[at:at + draw(st.integers(1, 16))]
        elif kind == "digit":  # make a count or an index large or negative
            data[at:at] = draw(st.sampled_from([b"9999999999", b"-1", b"1e308", b"nan"]))
    return bytes(data)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_mutated_valid_files(tmp_path, valid_files, data):
    name = data.draw(st.sampled_from(sorted(valid_files)))
    ext, original = valid_files[name]
    path = tmp_path / f"m{ext}"
    path.write_bytes(data.draw(mutations(original)))
    check_reader(path)


def test_fifo_and_device_refused_at_once(tmp_path):
    import os

    fifo = tmp_path / "p.obj"
    os.mkfifo(fifo)
    link = tmp_path / "z.ply"
    link.symlink_to("/dev/zero")
    for path, what in ((fifo, "FIFO"), (link, "character device")):
        start = time.perf_counter()
        with deadline(LIMIT_S), pytest.raises(MeshoptError, match=what):
            load(path)
        assert time.perf_counter() - start < 1.0


def test_size_cap(tmp_path, monkeypatch):
    path = save_cells(_sample(), tmp_path / "s.obj")
    with pytest.raises(MeshoptError, match=r"larger than the limit of 100 bytes.*--max-file-size"):
        load(path, max_bytes=100)
    monkeypatch.setenv("MESHOPT_MAX_FILE_BYTES", "100")
    with pytest.raises(MeshoptError, match="larger than the limit"):
        load(path)
    monkeypatch.setenv("MESHOPT_MAX_FILE_BYTES", "1M")
    assert load(path).n_triangles == 4
