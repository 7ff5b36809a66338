"""``mt.move`` and ``meshopt move`` on triangle surfaces in 3D: the Result protocol, the
type given kept (SurfaceMesh, trimesh.Trimesh), handles bitwise, no fold, a closed
surface's map choosing among all its vertices, the file written back with only its points
replaced."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import one_line

from gmsh_files import assert_same_but_points

from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load_cells, save_cells
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.mesh import SurfaceMesh
from meshopt_toolkit.motion.surface.folds import FoldTest
from meshopt_toolkit.motion.engine.targets import handles_of
from meshopt_toolkit.results import Result

trimesh = pytest.importorskip("trimesh")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import bench_surface as bench  # noqa: E402

# the bar [0, 6]×[0, 1]×[0, 1] twisted about its axis, 0 at x = 0 to 90° at x = 6
A = "pi/2*x/6"
TWIST = (f"x; 0.5 + (y-0.5)*cos({A}) - (z-0.5)*sin({A}); "
         f"0.5 + (y-0.5)*sin({A}) + (z-0.5)*cos({A})")
ENDS = "x < 0.01 or x > 5.99"

#: the physical names of the CLI tests' file
GROUPS = {"left", "right"}


def twisted(X: np.ndarray) -> np.ndarray:
    """The map TWIST, written out independently."""
    a = np.pi / 2 * X[:, 0] / 6
    y, z = X[:, 1] - 0.5, X[:, 2] - 0.5
    return np.column_stack([X[:, 0], 0.5 + y * np.cos(a) - z * np.sin(a),
                            0.5 + y * np.sin(a) + z * np.cos(a)])


@pytest.fixture(scope="module")
def bar():
    V, F = bench.box_surface([6.0, 1.0, 1.0], 0.25)  # closed, 418 vertices
    tags = np.where(V[F].mean(axis=1)[:, 0] > 3, 2, 1)
    return SurfaceMesh(V, F, triangle_tags=tags, tag_names={"left": (1, 2), "right": (2, 2)})


def _ends(points: np.ndarray) -> np.ndarray:
    return np.flatnonzero((points[:, 0] < 0.01) | (points[:, 0] > 5.99))


def _no_fold(rest, triangles, moved) -> None:
    assert not FoldTest(rest, triangles).mask(np.asarray(moved, float)).any()


# ------------------------------------------------------------------ library
def test_a_closed_surface_map_chooses_among_all_vertices(bar):
    assert bar.is_closed
    h, t = handles_of(bar, mapping=TWIST, where=ENDS)
    np.testing.assert_array_equal(h, _ends(bar.points))  # no boundary added
    np.testing.assert_allclose(t, twisted(bar.points[h]), rtol=0, atol=1e-14)


def test_an_open_surface_keeps_its_boundary():
    V, F = bench.box_surface([6.0, 1.0, 1.0], 0.25)
    lid = V[F].mean(axis=1)[:, 2] > 1 - 1e-9  # the top face removed: an open box
    open_box = SurfaceMesh(V, F[~lid])
    rim = np.unique(open_box.boundary_edges)
    assert len(rim) and not open_box.is_closed
    h, t = handles_of(open_box, mapping="x + 0.5; y; z", where="x > 5.99")
    moving = np.flatnonzero(V[:, 0] > 5.99)
    np.testing.assert_array_equal(h, np.union1d(rim, moving))
    still = ~np.isin(h, moving)
    np.testing.assert_array_equal(t[still], V[h[still]])
    np.testing.assert_array_equal(t[~still, 0], V[h[~still], 0] + 0.5)


def test_mt_move_on_a_surface_mesh_is_a_result(bar):
    import meshopt_toolkit as mt
    from meshopt_toolkit import strict_json

    h, t = handles_of(bar, mapping=TWIST, where=ENDS)
    res = mt.move(bar, h, t, frames=3)
    assert isinstance(res, Result) and res.status == "done" and res.seconds > 0
    assert isinstance(res.mesh, SurfaceMesh) and len(res.frames) == 3
    assert all(isinstance(f, SurfaceMesh) for f in res.frames) and res.frames[-1] is res.mesh
    np.testing.assert_array_equal(res.mesh.points[h], t)  # bitwise
    np.testing.assert_array_equal(res.frames[0].points, bar.points)
    for f in res.frames:
        np.testing.assert_array_equal(f.triangles, bar.triangles)
        np.testing.assert_array_equal(f.triangle_tags, bar.triangle_tags)
        assert f.tag_names == bar.tag_names
        _no_fold(bar.points, bar.triangles, f.points)
    # the free vertices followed: the middle of the bar turned by about 45°
    mid = np.flatnonzero(np.abs(bar.points[:, 0] - 3.0) < 1e-9)
    Y = res.mesh.points[mid, 1:] - 0.5
    X = bar.points[mid, 1:] - 0.5
    cross = X[:, 0] * Y[:, 1] - X[:, 1] * Y[:, 0]
    turn = np.degrees(np.arctan2(cross, np.sum(X * Y, axis=1)))
    assert 30 < np.median(turn) < 60
    summary = json.loads(strict_json.dumps(res.summary()))
    assert summary["status"] == "done" and summary["folds"] == 0


def test_mt_move_keeps_a_trimesh_a_trimesh(bar):
    import meshopt_toolkit as mt

    tm = trimesh.Trimesh(np.array(bar.points), np.array(bar.triangles), process=False)
    h, t = handles_of(bar, mapping=TWIST, where=ENDS)
    res = mt.move(tm, h, t)
    assert isinstance(res.mesh, trimesh.Trimesh) and res.frames[0] is tm
    np.testing.assert_array_equal(res.mesh.faces, bar.triangles)  # not processed
    np.testing.assert_array_equal(np.asarray(res.mesh.vertices)[h], t)
    same = mt.move(bar, h, t)
    np.testing.assert_array_equal(np.asarray(res.mesh.vertices), same.mesh.points)
    _no_fold(bar.points, bar.triangles, res.mesh.vertices)


# ------------------------------------------------------------------ command line
@pytest.fixture
def bar_file(bar, tmp_path):
    """The bar as a gmsh file with physical groups and a point datum of our own."""
    V, F = np.array(bar.points), np.array(bar.triangles)
    tags = np.array(bar.triangle_tags)
    path = tmp_path / "bar.msh"
    save_cells(CellMesh(V, [("triangle", F)], point_data={"temperature": V[:, 0] ** 2},
                        cell_data={"gmsh:physical": [tags], "gmsh:geometrical": [tags]},
                        field_data={"left": np.array([1, 2]), "right": np.array([2, 2])}),
               path)
    return path


def test_cli_turns_an_end_cap_of_an_obj(bar, tmp_path, capsys):
    src = tmp_path / "bar.obj"
    trimesh.Trimesh(np.array(bar.points), np.array(bar.triangles), process=False).export(src)
    out = tmp_path / "turned.obj"
    assert main(["move", str(src), "-o", str(out), "--map", TWIST, "--where", ENDS]) == 0
    assert "handles exact, folds 0" in capsys.readouterr().out
    a, b = load_cells(src), load_cells(out)
    h = _ends(a.points)
    np.testing.assert_allclose(b.points[h], twisted(a.points[h]), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(a.cells[0][1], b.cells[0][1])
    _no_fold(a.points, a.cells[0][1], b.points)


def test_cli_keeps_every_block_and_datum_of_a_msh(bar_file, tmp_path):
    out = tmp_path / "turned.msh"
    assert main(["move", str(bar_file), "-o", str(out), "--map", TWIST, "--where", ENDS]) == 0
    a, b = load_cells(bar_file), load_cells(out)
    assert_same_but_points(a, b, point_data={"temperature"}, groups=GROUPS)
    h, t = handles_of(a.to_surface_mesh(), mapping=TWIST, where=ENDS)
    np.testing.assert_array_equal(b.points[h], t)  # bitwise, as the file holds them


def test_cli_targets_index_x_y_z(bar_file, tmp_path, capsys):
    a = load_cells(bar_file)
    end = np.flatnonzero(a.points[:, 0] > 5.99)
    fixed = np.flatnonzero(a.points[:, 0] < 0.01)
    h = np.concatenate([end, fixed])
    t = np.concatenate([a.points[end] + [0.0, 0.25, 0.0], a.points[fixed]])
    table = tmp_path / "targets.csv"
    table.write_text("index,x,y,z\n" + "".join(
        f"{i},{x!r},{y!r},{z!r}\n" for i, (x, y, z) in zip(h, t.tolist())))
    out = tmp_path / "moved.msh"
    assert main(["move", str(bar_file), "-o", str(out), "--targets", str(table),
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["handles"] == len(h) and summary["folds"] == 0
    b = load_cells(out)
    np.testing.assert_array_equal(b.points[h], t)
    assert_same_but_points(a, b, point_data={"temperature"}, groups=GROUPS)


def test_cli_where_selecting_nothing_is_one_line(bar_file, tmp_path, capsys):
    out = tmp_path / "x.msh"
    assert main(["move", str(bar_file), "-o", str(out), "--map", TWIST,
                 "--where", "x > 7"]) != 0
    assert "selects no vertex" in one_line(capsys) and not out.exists()


def test_mt_move_keeps_a_pymeshlab_mesh_a_pymeshlab_mesh(bar):
    import meshopt_toolkit as mt

    pymeshlab = pytest.importorskip("pymeshlab")
    m = pymeshlab.Mesh(vertex_matrix=np.array(bar.points),
                       face_matrix=np.array(bar.triangles, dtype=np.int32))
    h, t = handles_of(bar, mapping=TWIST, where=ENDS)
    res = mt.move(m, h, t)
    assert isinstance(res.mesh, pymeshlab.Mesh) and res.frames[0] is m
    np.testing.assert_array_equal(res.mesh.face_matrix(), bar.triangles)
    np.testing.assert_array_equal(res.mesh.vertex_matrix()[h], t)
    np.testing.assert_array_equal(res.mesh.vertex_matrix(), mt.move(bar, h, t).mesh.points)


def test_a_rigid_motion_of_the_handles_moves_the_whole_surface_rigidly(bar):
    import meshopt_toolkit as mt

    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    h = _ends(bar.points)
    shift = np.array([0.3, -1.0, 2.0])
    res = mt.move(bar, h, bar.points[h] @ R.T + shift)
    np.testing.assert_allclose(res.mesh.points, bar.points @ R.T + shift, rtol=0, atol=1e-9)


def test_cli_group_of_a_surface(bar_file, tmp_path, capsys):
    a = load_cells(bar_file)
    tri = np.concatenate([c for _, c in a.cells])
    right = np.unique(tri[np.concatenate(a.cell_data["gmsh:physical"]) == 2])
    end = right[a.points[right, 0] > 5.99]
    out = tmp_path / "lifted.msh"
    assert main(["move", str(bar_file), "-o", str(out), "--group", "right",
                 "--where", "x > 5.99", "--map", "x; y; z + 0.25", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["handles"] == len(end) == 25
    b = load_cells(out)
    np.testing.assert_array_equal(b.points[end], a.points[end] + [0.0, 0.0, 0.25])
    assert main(["move", str(bar_file), "-o", str(tmp_path / "x.msh"), "--group", "inlet",
                 "--map", "x; y; z"]) != 0
    assert "it has: left (1), right (2)" in one_line(capsys)


def test_cli_frames_of_a_surface(bar_file, tmp_path):
    out = tmp_path / "motion"
    assert main(["move", str(bar_file), "-o", str(out), "--map", TWIST, "--where", ENDS,
                 "--frames", "3"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "frame_000.msh", "frame_001.msh", "frame_002.msh", "frames.csv"]
    rows = (out / "frames.csv").read_text().splitlines()
    assert rows[0] == "frame,path_fraction"
    assert [float(r.split(",")[1]) for r in rows[1:]] == [0.0, 0.5, 1.0]
    a = load_cells(bar_file)
    np.testing.assert_array_equal(load_cells(out / "frame_000.msh").points, a.points)
    h, t = handles_of(a.to_surface_mesh(), mapping=TWIST, where=ENDS)
    last = load_cells(out / "frame_002.msh")
    np.testing.assert_array_equal(last.points[h], t)
    assert_same_but_points(a, last, point_data={"temperature"}, groups=GROUPS)
