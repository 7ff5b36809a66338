"""Moves in space never pass a tet mesh's boundary or a surface through itself, and
``meshopt info`` reports a surface's self-intersections (``SelfIntersectionGuard``)."""

from __future__ import annotations

import numpy as np
import pytest
from test_tet_cli import WHERE, box_file  # noqa: F401  (a fixture)

import meshopt_toolkit as mt
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import SelfIntersectionError
from meshopt_toolkit.io import load_cells
from meshopt_toolkit.mesh import SurfaceMesh, TetMesh
from meshopt_toolkit.motion.engine.handles import SelfIntersectionGuard

trimesh = pytest.importorskip("trimesh")


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


@pytest.mark.slow
def test_cli_tet_move_through_the_wall_is_refused(box_file, tmp_path, capsys):  # noqa: F811
    """The hole (radius 0.35) moved to x = 1.2 crosses the wall x = 1: every boundary
    vertex is a handle, so the targets alone are refused, before any solve."""
    out = tmp_path / "through.msh"
    assert main(["move", str(box_file), "-o", str(out), "--where", WHERE,
                 "--map", "x + 1.2; y; z"]) == 1
    line = _one_line(capsys)
    assert "the targets make the boundary intersect itself" in line and "pairs" in line
    assert not out.exists()
    frames = tmp_path / "frames"
    assert main(["move", str(box_file), "-o", str(frames), "--where", WHERE,
                 "--map", "x + 1.2; y; z", "--frames", "3"]) == 1
    _one_line(capsys)
    assert not frames.exists()
    # inside the box the same motion is fine
    assert main(["move", str(box_file), "-o", str(out), "--where", WHERE,
                 "--map", "x + 0.3; y; z"]) == 0
    assert out.exists()


def test_tet_mesh_with_a_crossing_boundary_is_refused():
    unit = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    mesh = TetMesh(np.vstack([unit, unit + 0.25]), [[0, 1, 2, 3], [4, 5, 6, 7]])
    with pytest.raises(SelfIntersectionError, match="the boundary intersects itself"):
        mt.move(mesh, [0], [[0.0, 0.0, 0.1]])
    apart = TetMesh(np.vstack([unit, unit + 2.0]), [[0, 1, 2, 3], [4, 5, 6, 7]])
    with pytest.raises(SelfIntersectionError, match="the targets make the boundary"):
        mt.move(apart, np.arange(8), np.vstack([unit, unit + 0.25]))


def _sphere():
    m = trimesh.creation.icosphere(subdivisions=2)
    return SurfaceMesh(np.array(m.vertices), np.array(m.faces))


def test_surface_targets_through_itself_are_refused():
    S = _sphere()
    h = np.arange(S.n_vertices)
    tg = np.array(S.points)
    tg[0] *= -1.5
    with pytest.raises(SelfIntersectionError, match="the targets make the surface"):
        mt.move(S, h, tg)
    with pytest.raises(SelfIntersectionError):  # trimesh in, the same refusal
        mt.move(trimesh.Trimesh(S.points, S.triangles, process=False), h, tg)
    # a surface that intersects itself already is not checked: it moves (one vertex
    # left free: the surface solver wants one)
    crossing = SurfaceMesh(tg, S.triangles)
    res = mt.move(crossing, h[:-1], tg[:-1] + [0.5, 0.0, 0.0])
    np.testing.assert_allclose(res.mesh.points, tg + [0.5, 0.0, 0.0], atol=1e-12)


def test_guard_checks_every_frame_after_the_first():
    S = _sphere()
    guard = SelfIntersectionGuard(S, [0], [S.points[0]])
    bad = np.array(S.points)
    bad[0] *= -1.5
    frames = [S, SurfaceMesh(bad, S.triangles), S]
    with pytest.raises(SelfIntersectionError, match="at frame 1: .* pairs of triangles"):
        guard.check(frames)
    with pytest.raises(SelfIntersectionError, match="at the result"):
        guard.check(frames[:2])
    guard.check([S, S])  # free


def test_cli_surface_move_through_itself_is_refused(tmp_path, capsys):
    src = tmp_path / "ball.obj"
    m = trimesh.creation.icosphere(subdivisions=2)
    m.export(src)
    P = load_cells(src).points
    Q = np.array(P)
    Q[0] *= -1.5  # through the ball and out at the other side
    table = tmp_path / "targets.csv"
    table.write_text("".join(f"{i},{a!r},{b!r},{c!r}\n" for i, (a, b, c) in
                             enumerate(Q.tolist())))
    out = tmp_path / "o.obj"
    assert main(["move", str(src), "-o", str(out), "--targets", str(table)]) == 1
    line = _one_line(capsys)
    assert "the targets make the surface intersect itself" in line and not out.exists()


def test_cli_info_reports_surface_self_intersections(tmp_path, capsys):
    m = trimesh.creation.icosphere(subdivisions=2)
    clean = tmp_path / "clean.obj"
    m.export(clean)
    V = np.array(m.vertices)
    V[0] *= -1.5
    pushed = tmp_path / "pushed.obj"
    trimesh.Trimesh(V, m.faces, process=False).export(pushed)
    assert main(["info", str(clean), str(pushed)]) == 0
    text = capsys.readouterr().out
    rows = [line.split() for line in text.splitlines() if "self-intersecting" in line]
    assert rows[0] == ["self-intersecting", "no"]
    # the pairs: every one holds a triangle of vertex 0 (the only vertex moved)
    n = int(rows[1][1])
    assert rows[1][2:] == ["triangle", "pairs"] and n > 0
    assert "pairs of triangles intersect (e.g. triangles" in text
    assert main(["info", "--json", str(pushed)]) == 0
    import json

    assert json.loads(capsys.readouterr().out)["self_intersecting"] == n


def test_cli_info_reports_a_tet_boundary_crossing(tmp_path, capsys):
    from meshopt_toolkit.io import save_cells
    from meshopt_toolkit.io.cells import CellMesh

    unit = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    cm = CellMesh(np.vstack([unit, unit + 0.25]), [("tetra", np.array([[0, 1, 2, 3],
                                                                          [4, 5, 6, 7]]))])
    path = tmp_path / "two.vtu"
    save_cells(cm, path)
    assert main(["info", str(path)]) == 0
    text = capsys.readouterr().out
    row = next(line.split() for line in text.splitlines() if "self-intersecting" in line)
    assert row[1:] == ["1", "triangle", "pair"] or row[2:] == ["triangle", "pairs"]
    assert "boundary triangles intersect" in text
    assert load_cells(path).points.shape == (8, 3)
