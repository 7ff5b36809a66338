"""A write that fails is reported as the failure it is (the file and the OS error, or the
existing file); only a format that cannot hold the cells leads to writing less."""

from __future__ import annotations

import errno
import itertools
import json
import logging
from pathlib import Path

import numpy as np
import pytest

from conftest import grid_mesh
from meshopt_toolkit import io as mio
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import FileWriteError, WriteError
from meshopt_toolkit.io import gmsh
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.io.workpiece import save_workpiece


def cube_tets() -> CellMesh:
    """The unit cube as six tetrahedra around its diagonal (Kuhn)."""
    pts = np.array(list(itertools.product([0.0, 1.0], repeat=3)))
    tets = []
    for perm in itertools.permutations(range(3)):
        v = [0]
        for axis in perm:
            v.append(v[-1] | 1 << (2 - axis))
        tets.append(v)
    return CellMesh(pts, [("tetra", np.array(tets))])


def plane_with_quality() -> tuple[CellMesh, tuple[str, ...]]:
    """A planar grid with a computed ``quality`` cell datum."""
    mesh = grid_mesh(2)
    cm = CellMesh.from_triangle_mesh(mesh)
    cm = CellMesh(cm.points, cm.cells, cell_data={"quality": [np.ones(mesh.n_triangles)]})
    return cm, ("quality",)


@pytest.fixture
def disk_full(monkeypatch):
    """Every cell writer of .msh fails as a full disk does."""

    def full(path, data, binary=None, **kwargs):
        Path(path).write_bytes(b"$MeshFormat\n")  # a partial file, then the refusal
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setitem(mio.CELL_WRITERS, ".msh", full)


@pytest.mark.parametrize("which", ["tets", "plane"])
def test_an_os_error_is_reported_as_itself_not_retried(tmp_path, disk_full, caplog, which):
    cells, computed = (cube_tets(), ()) if which == "tets" else plane_with_quality()
    path = tmp_path / "m.msh"
    with caplog.at_level(logging.WARNING), pytest.raises(FileWriteError) as err:
        save_workpiece(cells, path, computed=computed)
    assert str(err.value) == f"{path}: cannot write: No space left on device"
    assert not caplog.records  # nothing written with less, nothing said about loss
    assert list(tmp_path.iterdir()) == []  # no partial file, no temporary


def test_an_existing_file_is_refused_as_existing(tmp_path, caplog):
    path = tmp_path / "body.msh"
    path.write_text("the user's")
    for cells, computed in [(cube_tets(), ()), plane_with_quality()]:
        with caplog.at_level(logging.WARNING), pytest.raises(FileWriteError) as err:
            save_workpiece(cells, path, computed=computed, overwrite=False)
        assert str(err.value) == f"{path}: already exists (not overwriting)"
        assert not caplog.records
    assert path.read_text() == "the user's"


def test_a_format_that_cannot_hold_the_cells_still_writes_less_or_says_why(tmp_path,
                                                                         caplog):
    cells, computed = plane_with_quality()
    with caplog.at_level(logging.WARNING):
        save_workpiece(cells, tmp_path / "m.off", computed=computed)
    assert "OFF files cannot hold quality cell data" in caplog.text
    assert "written without them" in caplog.text
    assert mio.load(tmp_path / "m.off").n_triangles == cells.cells[0][1].shape[0]
    # tetrahedra in a surface format: the format's refusal, not "only triangles"
    with pytest.raises(WriteError, match=r"m\.obj: OBJ files cannot hold 6 tetra cells"):
        save_workpiece(cube_tets(), tmp_path / "m.obj")
    assert not (tmp_path / "m.obj").exists()


def test_a_batch_reports_the_write_error_of_each_file(tmp_path, monkeypatch, capsys,
                                                      disk_full):
    monkeypatch.chdir(tmp_path)
    Path("in").mkdir()
    gmsh.write_cells(Path("in/body.msh"), cube_tets(), None)  # the writer itself works
    gmsh.write(Path("in/plane.msh"), grid_mesh(2), None)
    Path("p.json").write_text(json.dumps({"filters": []}))
    status = main(["run", "p.json", "in", "-o", "out", "--json"])
    cap = capsys.readouterr()
    assert status == 1
    recs = [json.loads(x) for x in cap.out.splitlines()]
    out = Path("out")
    assert [r["error"] for r in recs] == [
        f"{out / name}: cannot write: No space left on device"
        for name in ("body.msh", "plane.msh")]
    # each line names the input, then the output the file system refused
    assert [x for x in cap.err.splitlines() if "error" in x] == [
        f"meshopt run: error: {r['input']}: {r['error']}" for r in recs]
    assert sorted(p.name for p in out.iterdir()) == [".meshopt-journal.db"]
