"""Handles chosen by a selection saved with the mesh: ``meshopt move --selection NAME`` and
the move filter's ``selection`` (the vertices whose point datum NAME is nonzero; MeshLab's
``flags`` by its selection bit), on surfaces (.ply from pymeshlab), tets (.msh, .vtu) and
planar meshes, with one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import InvalidMeshError, OptionError
from meshopt_toolkit.io import load_cells, save_cells
from meshopt_toolkit.kernels.tetrahedra import signed_volumes
from meshopt_toolkit.motion.engine.handles import (
    MESHLAB_SELECTED_BIT,
    handles_in_space,
    selected_vertices,
)
from meshopt_toolkit.motion.surface.folds import FoldTest

pymeshlab = pytest.importorskip("pymeshlab")

LIFT = "x; y; z + 0.25"


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def _sphere_set():
    """pymeshlab's icosphere (162 vertices) with its vertices z > 0.5 selected."""
    ms = pymeshlab.MeshSet()
    ms.create_sphere(subdiv=2)
    ms.compute_selection_by_condition_per_vertex(condselect="z > 0.5")
    return ms


# ------------------------------------------------------------------ what pymeshlab saves
def test_pymeshlab_saves_a_selection_in_ply_only_as_vertex_flags(tmp_path):
    """Verified with pymeshlab 2025.7.post1: ``save_current_mesh('x.ply')`` writes no
    selection (no vertex property beyond x, y, z; reloaded, nothing is selected);
    ``save_vertex_flag=True`` writes the integer vertex property ``flags`` in which the
    selected vertices carry bit 32 (VCG's SELECTED) and the others 0, and pymeshlab reads
    the selection back from it; a vertex quality is written as the property ``quality``."""
    ms = _sphere_set()
    chosen = np.flatnonzero(ms.current_mesh().vertex_selection_array())
    V = ms.current_mesh().vertex_matrix()
    np.testing.assert_array_equal(chosen, np.flatnonzero(V[:, 2] > 0.5))
    plain, flagged = tmp_path / "plain.ply", tmp_path / "flagged.ply"
    ms.save_current_mesh(str(plain))
    ms.save_current_mesh(str(flagged), save_vertex_flag=True)
    assert load_cells(plain).point_data == {}
    again = pymeshlab.MeshSet()
    again.load_new_mesh(str(plain))
    assert not again.current_mesh().vertex_selection_array().any()
    flags = load_cells(flagged).point_data["flags"]
    assert flags.dtype.kind == "i" and set(np.unique(flags)) == {0, MESHLAB_SELECTED_BIT}
    np.testing.assert_array_equal(selected_vertices({"flags": flags}, "flags"), chosen)
    again = pymeshlab.MeshSet()
    again.load_new_mesh(str(flagged))
    np.testing.assert_array_equal(
        np.flatnonzero(again.current_mesh().vertex_selection_array()), chosen)
    ms.compute_scalar_by_function_per_vertex(q="z")
    quality = tmp_path / "quality.ply"
    ms.save_current_mesh(str(quality))
    np.testing.assert_array_equal(load_cells(quality).point_data["quality"], V[:, 2])


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 30), st.integers(1, 3)),
              elements=st.sampled_from([0.0, -0.0, 1.0, -2.5, 1e-300])))
def test_selected_vertices_are_those_with_a_nonzero_value(values):
    expected = [i for i, row in enumerate(values.tolist()) if any(v != 0 for v in row)]
    data = {"mark": values if values.shape[1] > 1 else values[:, 0]}
    if not expected:
        with pytest.raises(InvalidMeshError, match="no vertex is selected"):
            selected_vertices(data, "mark")
    else:
        assert selected_vertices(data, "mark").tolist() == expected


def test_a_missing_name_lists_the_point_data():
    with pytest.raises(InvalidMeshError) as err:
        selected_vertices({"quality": np.ones(3), "flags": np.zeros(3, int)}, "selected",
                          source="s.ply")
    assert str(err.value) == ("--selection 'selected': s.ply has no such point data; "
                              "point data: flags, quality")
    with pytest.raises(InvalidMeshError, match="no such point data; point data: none"):
        selected_vertices({}, "q")
    with pytest.raises(OptionError, match="--selection needs --map"):
        handles_in_space(None, targets="t.csv", selection="q")


# ------------------------------------------------------------------ command line: surfaces
@pytest.fixture
def sphere_ply(tmp_path):
    """The icosphere saved by pymeshlab with its selection (flags) and a quality z > 0.5."""
    ms = _sphere_set()
    ms.compute_scalar_by_function_per_vertex(q="z > 0.5 ? 1 : 0")
    path = tmp_path / "sphere.ply"
    ms.save_current_mesh(str(path), save_vertex_flag=True)
    return path


@pytest.mark.parametrize("name", ["quality", "flags"])
def test_cli_moves_the_vertices_meshlab_selected(sphere_ply, tmp_path, capsys, name):
    out = tmp_path / f"lifted_{name}.ply"
    assert main(["move", str(sphere_ply), "-o", str(out), "--selection", name,
                 "--map", LIFT]) == 0
    a, b = load_cells(sphere_ply), load_cells(out)
    top = np.flatnonzero(a.points[:, 2] > 0.5)  # what pymeshlab selected, independently
    assert f"wrote {out}: {len(top)} handles exact, folds 0" in capsys.readouterr().out
    expected = a.points[top].copy()
    expected[:, 2] += 0.25
    np.testing.assert_array_equal(b.points[top], expected)  # bitwise
    assert not np.allclose(b.points, a.points)  # the rest followed
    tri = a.cells[0][1]
    assert not FoldTest(a.points, tri).mask(b.points).any()
    np.testing.assert_array_equal(b.point_data["flags"], a.point_data["flags"])
    np.testing.assert_array_equal(b.point_data["quality"], a.point_data["quality"])


def test_cli_selection_errors_are_one_line(sphere_ply, tmp_path, capsys):
    out = tmp_path / "x.ply"
    assert main(["move", str(sphere_ply), "-o", str(out), "--selection", "selected",
                 "--map", LIFT]) != 0
    line = _one_line(capsys)
    assert "--selection 'selected'" in line and "point data: flags, quality" in line
    assert main(["move", str(sphere_ply), "-o", str(out), "--selection", "quality",
                 "--targets", str(tmp_path / "t.csv")]) != 0
    assert "--selection needs --map" in _one_line(capsys)
    assert main(["move", str(sphere_ply), "-o", str(out), "--selection", "quality",
                 "--group", "1", "--map", LIFT]) != 0
    assert "one of --group and --selection" in _one_line(capsys)
    assert not out.exists()


# ------------------------------------------------------------------ command line: tets
@pytest.fixture(scope="module")
def box_msh(tmp_path_factory):
    """gmsh tets of [-1, 1]³ minus a ball of radius 0.4 (physical group ``hole``), with the
    point datum ``on_hole`` marking the hole's nodes (found by their distance)."""
    pytest.importorskip("gmsh")
    from gmsh_files import box_with_hole_msh

    path = box_with_hole_msh(tmp_path_factory.mktemp("sel") / "box.msh", radius=0.4, size=0.5)
    cm = load_cells(path)
    cm.point_data["on_hole"] = (np.linalg.norm(cm.points, axis=1) < 0.4 + 1e-9) * 1.0
    save_cells(cm, path)
    return path


@pytest.mark.parametrize("ext", [".msh", ".vtu"])
def test_cli_tet_selection_is_the_group_it_marks(box_msh, tmp_path, ext):
    src = box_msh if ext == ".msh" else tmp_path / "box.vtu"
    if ext == ".vtu":
        save_cells(load_cells(box_msh), src)
    by_group, by_selection = tmp_path / f"g{ext}", tmp_path / f"s{ext}"
    assert main(["move", str(src), "-o", str(by_group), "--group", "hole",
                 "--map", "x + 0.1; y; z"]) == 0
    assert main(["move", str(src), "-o", str(by_selection), "--selection", "on_hole",
                 "--map", "x + 0.1; y; z"]) == 0
    a, g, s = load_cells(src), load_cells(by_group), load_cells(by_selection)
    hole = np.flatnonzero(a.point_data["on_hole"])
    assert len(hole) > 10
    np.testing.assert_array_equal(s.points, g.points)  # the same handles, the same motion
    np.testing.assert_array_equal(s.points[hole], a.points[hole] + [0.1, 0.0, 0.0])
    tets = np.concatenate([c for t, c in s.cells if t == "tetra"])
    assert signed_volumes(s.points, tets).min() > 0
    np.testing.assert_array_equal(s.point_data["on_hole"], a.point_data["on_hole"])


# ------------------------------------------------------------------ planar and filter
def test_planar_selection_moves_the_marked_boundary(tmp_path):
    from conftest import grid_mesh

    from meshopt_toolkit.io.cells import CellMesh

    mesh = grid_mesh(6)
    right = (mesh.points[:, 0] == 1.0).astype(float)
    src = tmp_path / "grid.vtu"
    save_cells(CellMesh.from_triangle_mesh(mesh), src)
    cm = load_cells(src)
    cm.point_data["right"] = right
    save_cells(cm, src)
    out = tmp_path / "moved.vtu"
    assert main(["move", str(src), "-o", str(out), "--selection", "right",
                 "--map", "x + 0.2; y"]) == 0
    b = load_cells(out)
    h = np.flatnonzero(right)
    np.testing.assert_array_equal(b.points[h, :2], mesh.points[h] + [0.2, 0.0])
    left = np.flatnonzero(mesh.points[:, 0] == 0.0)
    np.testing.assert_array_equal(b.points[left, :2], mesh.points[left])  # boundary kept


def test_filter_selection_reads_a_meshlab_selection_step(sphere_ply):
    """A MeshLab selection step's ``selected`` attribute picks the filter's handles."""
    from meshopt_toolkit.pipeline.document import Document, load_entry
    from meshopt_toolkit.pipeline.runner import Pipeline

    doc = Document()
    doc.add(load_entry(sphere_ply))
    before = np.array(doc.mesh.points)
    Pipeline.from_dict({"filters": [
        {"name": "compute_selection_by_condition_per_vertex",
         "params": {"condselect": "x < -0.5"}},
        {"name": "apply_coord_prescribed_motion",
         "params": {"selection": "selected", "map": "x - 0.25; y; z"}},
    ]}).run(doc)
    h = np.flatnonzero(before[:, 0] < -0.5)
    assert doc.results[-1]["handles"] == len(h)
    np.testing.assert_array_equal(doc.mesh.points[h], before[h] - [0.25, 0.0, 0.0])
