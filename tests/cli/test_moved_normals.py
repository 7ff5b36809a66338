"""Normals of OBJ/PLY files follow the vertices: a file written with moved points carries
the moved surface's normals (against trimesh's own vertex normals), oriented as the
file's, and one warning line; unmoved files keep their normals bit for bit."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import pytest

from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load_cells, save_cells
from meshopt_toolkit.io.cells import NORMALS, CellMesh

trimesh = pytest.importorskip("trimesh")


def sphere_file(path, subdivisions: int = 3, inward: bool = False):
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    normals = s.vertices / np.linalg.norm(s.vertices, axis=1)[:, None]
    cm = CellMesh(np.array(s.vertices), [("triangle", np.array(s.faces))],
                  point_data={NORMALS: -normals if inward else normals})
    return save_cells(cm, path)


def twisted(points: np.ndarray) -> np.ndarray:
    """A smooth non-rigid map: (x, y) turned by 0.8 z, then stretched along z."""
    a = 0.8 * points[:, 2]
    c, s = np.cos(a), np.sin(a)
    x, y, z = points.T
    return np.column_stack([c * x - s * y, s * x + c * y, 1.5 * z])


def true_normals(points, triangles) -> np.ndarray:
    return trimesh.Trimesh(points, triangles, process=False).vertex_normals


@pytest.mark.parametrize("ext", ["obj", "ply"])
@pytest.mark.parametrize("inward", [False, True])
def test_moved_points_get_the_moved_surface_normals(tmp_path, caplog, ext, inward):
    cm = load_cells(sphere_file(tmp_path / f"s.{ext}", inward=inward))
    moved = replace(cm, points=twisted(cm.points))
    with caplog.at_level(logging.WARNING):
        back = load_cells(save_cells(moved, tmp_path / f"out.{ext}"))
    tri = back.cells[0][1]
    cos = np.einsum("ij,ij->i", back.point_data[NORMALS], true_normals(back.points, tri))
    assert (-cos if inward else cos).min() > 0.99
    stale = np.einsum("ij,ij->i", cm.point_data[NORMALS], true_normals(back.points, tri))
    assert np.abs(stale).min() < 0.95  # the file's normals no longer fit
    lines = [r.getMessage() for r in caplog.records if "normals recomputed" in r.getMessage()]
    assert len(lines) == 1 and str(cm.source) in lines[0]


@pytest.mark.parametrize("ext", ["obj", "ply"])
def test_unmoved_and_replaced_normals_are_written_as_given(tmp_path, ext):
    cm = load_cells(sphere_file(tmp_path / f"s.{ext}"))
    same = load_cells(save_cells(cm, tmp_path / f"same.{ext}"))
    np.testing.assert_array_equal(same.point_data[NORMALS], cm.point_data[NORMALS])
    mine = np.tile([0.0, 0.0, 1.0], (cm.n_points, 1))
    given = replace(cm, points=twisted(cm.points), point_data={NORMALS: mine})
    back = load_cells(save_cells(given, tmp_path / f"given.{ext}"))
    np.testing.assert_array_equal(back.point_data[NORMALS], mine)


@pytest.mark.slow
def test_meshopt_move_writes_fresh_normals(tmp_path, caplog):
    src = sphere_file(tmp_path / "s.obj", subdivisions=2)
    out = tmp_path / "out.obj"
    assert main(["move", str(src), "-o", str(out), "--where", "z > 0.7", "--map",
                 "x; y*cos(0.5) - z*sin(0.5); y*sin(0.5) + z*cos(0.5)"]) == 0
    back = load_cells(out)
    cos = np.einsum("ij,ij->i", back.point_data[NORMALS],
                    true_normals(back.points, back.cells[0][1]))
    assert cos.min() > 0.99
    assert sum("normals recomputed" in r.getMessage() for r in caplog.records) == 1


def test_per_corner_normals_a_move_cannot_keep_are_named(tmp_path, caplog):
    """Normals given per face corner (not per vertex) are not held by the moved file: the
    move says so in one line naming the input."""
    s = trimesh.creation.icosphere(subdivisions=1)
    lines = [f"v {x} {y} {z}" for x, y, z in s.vertices]
    lines += [f"vn {x} {y} {z}" for x, y, z in s.face_normals]
    lines += [f"f {a + 1}//{k + 1} {b + 1}//{k + 1} {c + 1}//{k + 1}"
              for k, (a, b, c) in enumerate(s.faces)]
    src = tmp_path / "corners.obj"
    src.write_text("\n".join(lines) + "\n")
    assert main(["move", str(src), "-o", str(tmp_path / "out.obj"), "--where", "z > 0.5",
                 "--map", "x; y; z + 0.1"]) == 0
    warned = [r.getMessage() for r in caplog.records if "not kept" in r.getMessage()]
    assert len(warned) == 1 and str(src) in warned[0] and "normals 'vn'" in warned[0]
