"""``mt.move`` and ``meshopt move`` on tetrahedral meshes: the Result protocol, 3D handles
(tables, maps in x, y, z, physical groups), the file written back with only its points
replaced, one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import grid_mesh

from gmsh_files import assert_same_but_points

from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import ExpressionError, InvalidMeshError
from meshopt_toolkit.io import load_cells, save_cells
from meshopt_toolkit.kernels.tetrahedra import signed_volumes
from meshopt_toolkit.mesh import TetMesh
from meshopt_toolkit.motion.engine.targets import handles_of
from meshopt_toolkit.results import Result

pytest.importorskip("gmsh")

RADIUS = 0.35
C, S = np.cos(np.pi / 4), np.sin(np.pi / 4)
TURN = "x*cos(pi/4) - y*sin(pi/4); x*sin(pi/4) + y*cos(pi/4); z"
WHERE = "x**2+y**2+z**2 < 0.2"

#: the physical names of the CLI tests' file
GROUPS = {"hole", "walls", "solid"}


@pytest.fixture(scope="module")
def box_file(tmp_path_factory):
    """gmsh tets of [-1, 1]³ minus a ball (~1.2k tets), physical groups ``hole``, ``walls``
    (surfaces) and ``solid`` (volume), plus a point datum of our own."""
    from gmsh_files import box_with_hole_msh

    path = box_with_hole_msh(tmp_path_factory.mktemp("tets") / "box.msh", radius=RADIUS,
                             size=0.35, size_min=0.35 / 3)
    cm = load_cells(path)
    cm.point_data["temperature"] = np.linalg.norm(cm.points, axis=1)
    save_cells(cm, path)
    return path


def _tets(cm):
    return np.concatenate([c for t, c in cm.cells if t == "tetra"])


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0] and "internal error" not in err[0], err
    return err[0]


# ------------------------------------------------------------------ library
def test_mt_move_on_a_tet_mesh_is_a_result(box_file):
    import meshopt_toolkit as mt
    from meshopt_toolkit import strict_json

    mesh = load_cells(box_file).to_tet_mesh()
    h = mesh.boundary_vertices
    X = mesh.points[h]
    inner = np.linalg.norm(X, axis=1) < 0.6
    targets = X.copy()
    targets[inner] = X[inner] @ np.array([[C, S, 0], [-S, C, 0], [0, 0, 1]])
    res = mt.move(mesh, h, targets, frames=3)
    assert isinstance(res, Result) and res.status == "done" and res.seconds > 0
    assert isinstance(res.mesh, TetMesh) and len(res.frames) == 3
    assert all(isinstance(f, TetMesh) for f in res.frames) and res.frames[-1] is res.mesh
    np.testing.assert_array_equal(res.mesh.points[h], targets)  # bitwise
    for f in res.frames:
        assert signed_volumes(f.points, f.tets).min() > 0
        np.testing.assert_array_equal(f.tets, mesh.tets)
        assert f.tag_names == mesh.tag_names
    np.testing.assert_allclose(res.frames[0].points, mesh.points, atol=1e-12)
    summary = json.loads(strict_json.dumps(res.summary()))
    assert summary["inverted"] == 0 and summary["status"] == "done"
    assert summary["min_mean_ratio"] == pytest.approx(
        float(res.mesh.mean_ratios().min()), rel=1e-12)


def test_mt_move_keeps_vertices_in_no_tet_and_refuses_inverted(box_file):
    import meshopt_toolkit as mt

    mesh = load_cells(box_file).to_tet_mesh()
    lone = TetMesh(np.vstack([mesh.points, [[5.0, 5.0, 5.0]]]), mesh.tets)
    h = np.append(mesh.tagged_vertices("hole"), len(mesh.points))
    targets = lone.points[h] + [0.1, 0.0, 0.0]
    res = mt.move(lone, h, targets)
    np.testing.assert_array_equal(res.mesh.points[h], targets)
    assert signed_volumes(res.mesh.points, res.mesh.tets).min() > 0
    flipped = mesh.tets.copy()
    flipped[[3, 7]] = flipped[[3, 7]][:, [1, 0, 2, 3]]
    with pytest.raises(InvalidMeshError, match="2 tetrahedra are inverted"):
        mt.move(TetMesh(mesh.points, flipped), h[:-1], targets[:-1])


def test_tagged_vertices_by_name_take_the_group_dimension_only():
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    mesh = TetMesh(P, [[0, 1, 2, 3], [1, 2, 3, 4]], tet_tags=[7, 5],
                   triangles=[[1, 2, 4]], triangle_tags=[5],
                   tag_names={"lid": (5, 2), "core": (7, 3), "back": (5, 3)})
    np.testing.assert_array_equal(mesh.tagged_vertices("lid"), [1, 2, 4])
    np.testing.assert_array_equal(mesh.tagged_vertices("back"), [1, 2, 3, 4])
    np.testing.assert_array_equal(mesh.tagged_vertices("core"), [0, 1, 2, 3])
    np.testing.assert_array_equal(mesh.tagged_vertices(5), [1, 2, 3, 4])
    with pytest.raises(InvalidMeshError, match="no physical group named 'nope'"):
        mesh.tagged_vertices("nope")
    with pytest.raises(InvalidMeshError, match="no element carries physical tag 9"):
        mesh.tagged_vertices(9)


def test_a_planar_map_or_where_in_z_is_an_expression_error():
    mesh = grid_mesh(3)
    with pytest.raises(ExpressionError, match="z is not defined for a planar mesh"):
        handles_of(mesh, mapping="x; y + z")
    with pytest.raises(ExpressionError, match="z is not defined for a planar mesh"):
        handles_of(mesh, mapping="x; y", where="z < 1")
    # the planar map is unchanged: two expressions, boundary vertices
    h, t = handles_of(mesh, mapping="x; y + 0.5", where="x < 0.5")
    np.testing.assert_array_equal(h, np.unique(mesh.boundary_edges))


# ------------------------------------------------------------------ command line
def test_cli_map_turns_the_hole_and_keeps_every_block(box_file, tmp_path, capsys):
    out = tmp_path / "turned.msh"
    assert main(["move", str(box_file), "-o", str(out), "--where", WHERE, "--map", TURN,
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    src, dst = load_cells(box_file), load_cells(out)
    assert_same_but_points(src, dst, point_data={"temperature"}, groups=GROUPS)
    P, Q = src.points, dst.points
    boundary = TetMesh(P, _tets(src)).boundary_vertices
    on_hole = boundary[np.sum(P[boundary] ** 2, axis=1) < 0.2]
    walls = np.setdiff1d(boundary, on_hole)
    assert len(on_hole) and summary["inverted"] == 0 and summary["handles"] == len(boundary)
    x, y, z = P[on_hole].T
    expected = np.column_stack([x * np.cos(np.pi / 4) - y * np.sin(np.pi / 4),
                                x * np.sin(np.pi / 4) + y * np.cos(np.pi / 4), z])
    np.testing.assert_array_equal(Q[on_hole], expected)  # bitwise at the map's values
    np.testing.assert_array_equal(Q[walls], P[walls])  # the other boundary stays
    inner = np.setdiff1d(np.arange(len(P)), boundary)
    assert np.mean(np.any(Q[inner] != P[inner], axis=1)) > 0.5  # the interior follows
    assert signed_volumes(Q, _tets(dst)).min() > 0
    # never overwritten without --force
    assert main(["move", str(box_file), "-o", str(out), "--map", TURN]) == 1
    assert "exists" in _one_line(capsys)


def test_cli_group_moves_the_hole_nodes(box_file, tmp_path, capsys):
    out = tmp_path / "shifted.msh"
    assert main(["move", str(box_file), "-o", str(out), "--group", "hole",
                 "--map", "x + 0.1; y; z - 0.05"]) == 0
    assert "handles exact" in capsys.readouterr().out
    src, dst = load_cells(box_file), load_cells(out)
    assert_same_but_points(src, dst, point_data={"temperature"}, groups=GROUPS)
    tm = src.to_tet_mesh()
    hole = tm.tagged_vertices("hole")
    walls = np.setdiff1d(tm.boundary_vertices, hole)
    np.testing.assert_array_equal(dst.points[hole], src.points[hole] + [0.1, 0.0, -0.05])
    np.testing.assert_array_equal(dst.points[walls], src.points[walls])
    assert signed_volumes(dst.points, _tets(dst)).min() > 0


def test_cli_unknown_group_is_one_line_listing_the_groups(box_file, tmp_path, capsys):
    out = tmp_path / "o.msh"
    assert main(["move", str(box_file), "-o", str(out), "--group", "rim",
                 "--map", "x; y; z"]) == 1
    line = _one_line(capsys)
    assert "--group 'rim'" in line and "hole (1)" in line and "solid (3)" in line
    assert not out.exists()


@pytest.mark.parametrize("kind", ["csv", "npy"])
def test_cli_targets_table_in_3d(box_file, tmp_path, capsys, kind):
    src = load_cells(box_file)
    tm = src.to_tet_mesh()
    hole = tm.tagged_vertices("hole")
    targets = 1.2 * src.points[hole]  # the hole grows by 20 %
    table = tmp_path / f"handles.{kind}"
    if kind == "csv":
        table.write_text("index,x,y,z\n" + "".join(
            f"{i},{a!r},{b!r},{c!r}\n" for i, (a, b, c) in zip(hole, targets.tolist())))
    else:
        np.save(table, np.column_stack([hole, targets]))
    out = tmp_path / "grown.msh"
    assert main(["move", str(box_file), "-o", str(out), "--targets", str(table)]) == 0
    dst = load_cells(out)
    assert_same_but_points(src, dst, point_data={"temperature"}, groups=GROUPS)
    np.testing.assert_array_equal(dst.points[hole], targets)
    walls = np.setdiff1d(tm.boundary_vertices, hole)
    np.testing.assert_array_equal(dst.points[walls], src.points[walls])  # kept by default
    assert signed_volumes(dst.points, _tets(dst)).min() > 0
    # a planar table for a tet mesh: one line naming the expected rows
    flat = tmp_path / "flat.csv"
    flat.write_text("".join(f"{i},0.0,0.0\n" for i in hole))
    assert main(["move", str(box_file), "-o", str(tmp_path / "x.msh"),
                 "--targets", str(flat)]) == 1
    assert "index,x,y,z" in _one_line(capsys)


def test_cli_frames_write_the_motion(box_file, tmp_path, capsys):
    out = tmp_path / "motion"
    assert main(["move", str(box_file), "-o", str(out), "--group", "hole",
                 "--map", "x + 0.1; y; z", "--frames", "3"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["frame_000.msh", "frame_001.msh", "frame_002.msh", "quality.csv"]
    src = load_cells(box_file)
    for name in names[:-1]:
        frame = load_cells(out / name)
        assert_same_but_points(src, frame, point_data={"temperature"}, groups=GROUPS)
        assert signed_volumes(frame.points, _tets(frame)).min() > 0
    rows = (out / "quality.csv").read_text().splitlines()
    assert rows[0] == "frame,min_mean_ratio" and len(rows) == 4


def test_cli_refuses_an_inverted_input_in_one_line(box_file, tmp_path, capsys):
    cm = load_cells(box_file)
    k = next(i for i, (t, _) in enumerate(cm.cells) if t == "tetra")
    cm.cells[k][1][[0, 5, 9]] = cm.cells[k][1][[0, 5, 9]][:, [1, 0, 2, 3]]
    bad = tmp_path / "bad.msh"
    save_cells(cm, bad)
    out = tmp_path / "o.msh"
    assert main(["move", str(bad), "-o", str(out), "--where", WHERE, "--map", TURN]) == 1
    assert "3 tetrahedra are inverted" in _one_line(capsys) and not out.exists()


def test_cli_planar_map_in_z_is_one_line(tmp_path, capsys):
    from meshopt_toolkit.io import save

    src = tmp_path / "square.msh"
    save(grid_mesh(3), src)
    assert main(["move", str(src), "-o", str(tmp_path / "o.msh"),
                 "--map", "x; y + z"]) == 1
    assert "z is not defined for a planar mesh" in _one_line(capsys)


def test_cli_free_boundary_lets_the_unlisted_walls_follow(box_file, tmp_path):
    src = load_cells(box_file)
    hole = src.to_tet_mesh().tagged_vertices("hole")
    table = tmp_path / "shift.csv"
    shifted = src.points[hole] + [0.1, 0.0, 0.0]
    table.write_text("".join(f"{i},{a!r},{b!r},{c!r}\n"
                             for i, (a, b, c) in zip(hole, shifted.tolist())))
    out = tmp_path / "free.msh"
    assert main(["move", str(box_file), "-o", str(out), "--targets", str(table),
                 "--free-boundary"]) == 0
    # the handles translate: so does the whole mesh (the similarity factored out)
    np.testing.assert_allclose(load_cells(out).points, src.points + [0.1, 0.0, 0.0],
                               atol=1e-12)
