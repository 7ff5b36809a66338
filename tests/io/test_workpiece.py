"""Workpieces: planar meshes in any plane, and everything a file holds, through every
operation (move, deform, optimize, morph, pipeline refinement and quality)."""

from __future__ import annotations

import json
import logging
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.io import load_cells, save_cells
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.io.workpiece import Workpiece
from meshopt_toolkit.mesh import TriangleMesh, check_mesh
from meshopt_toolkit.orientation import PLANE_RTOL

SIDES = {f"side{i}": 11 + i for i in range(6)}


def _hexagon_msh(path, h=0.35):
    """A gmsh 4.1 hexagon: six boundary curves (physical 11..16, named), two corner
    points (physical 7, vertex cells), the plate (physical 5)."""
    from meshopt_toolkit.gmsh_session import gmsh_session

    with gmsh_session() as gmsh:
        gmsh.model.add("hexagon")
        ang = np.linspace(0, 2 * np.pi, 7)[:-1]
        pts = [gmsh.model.geo.addPoint(np.cos(a), np.sin(a), 0, h) for a in ang]
        curves = [gmsh.model.geo.addLine(pts[i], pts[(i + 1) % 6]) for i in range(6)]
        surf = gmsh.model.geo.addPlaneSurface([gmsh.model.geo.addCurveLoop(curves)])
        gmsh.model.geo.synchronize()
        for i, c in enumerate(curves):
            gmsh.model.addPhysicalGroup(1, [c], 11 + i, name=f"side{i}")
        gmsh.model.addPhysicalGroup(0, [pts[0], pts[3]], 7, name="corners")
        gmsh.model.addPhysicalGroup(2, [surf], 5, name="plate")
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """hex.msh (z = 0), plate_z2.vtu (3× larger, z = 2), tilted.vtu (z = 0.5 x), the
    .vtu files with point data (float and int) and cell data on every block."""
    d = tmp_path_factory.mktemp("workpiece")
    _hexagon_msh(d / "hex.msh")
    cm = load_cells(d / "hex.msh")
    n = len(cm.points)
    data = {"point_data": {"temperature": 2.0 * cm.points[:, 0] + 1.0,
                           "ids": np.arange(n, dtype=np.int32)},
            "cell_data": {**cm.cell_data,
                          "weight": [np.arange(len(c)) + 0.5 for _, c in cm.cells]}}
    plate = cm.points * [3.0, 3.0, 0.0] + [0.0, 0.0, 2.0]
    save_cells(replace(cm, points=plate, **data), d / "plate_z2.vtu")
    tilted = cm.points.copy()
    tilted[:, 2] = 0.5 * tilted[:, 0]
    save_cells(replace(cm, points=tilted, **data), d / "tilted.vtu")
    return d


NAMES = ["hex.msh", "plate_z2.vtu", "tilted.vtu"]


def _assert_same_extras(a: CellMesh, b: CellMesh, points=True):
    """Every block (type, connectivity, order), cell, point and field datum equal."""
    assert [t for t, _ in a.cells] == [t for t, _ in b.cells]
    for (_, x), (_, y) in zip(a.cells, b.cells):
        assert np.array_equal(x, y)
    assert sorted(a.cell_data) == sorted(b.cell_data)
    for k in a.cell_data:
        for x, y in zip(a.cell_data[k], b.cell_data[k]):
            assert np.array_equal(x, y), k
    assert sorted(a.point_data) == sorted(b.point_data)
    for k in a.point_data:
        assert np.array_equal(a.point_data[k], b.point_data[k]), k
    assert {k: np.asarray(v).tolist() for k, v in a.field_data.items()} == \
        {k: np.asarray(v).tolist() for k, v in b.field_data.items()}
    if points:
        assert np.array_equal(a.points, b.points)


def _off_plane(points):
    """Largest distance to the plane z = 0.5 x, relative to the size."""
    p = np.asarray(points)
    return float(np.abs(p[:, 2] - 0.5 * p[:, 0]).max() / np.ptp(p, axis=0).max())


# -- the plane ----------------------------------------------------------------------------
def test_constant_z_and_2d_points_are_worked_on_as_x_y_bit_for_bit(files):
    cm = load_cells(files / "plate_z2.vtu")
    wp = Workpiece.from_cells(cm)
    assert wp.frame is None and np.array_equal(wp.plane, cm.points[:, :2])
    assert np.array_equal(wp.mesh.points, cm.points[:, :2])  # the file's scale
    back = wp.moved(wp.mesh.points).to_cells()
    _assert_same_extras(cm, back)
    flat = replace(cm, points=cm.points[:, :2].copy())
    assert np.array_equal(Workpiece.from_cells(flat).moved(
        Workpiece.from_cells(flat).mesh.points).cells.points, flat.points)


def test_subnormal_coordinates_come_back_bit_for_bit():
    pts = np.array([[2.225e-313, 3.0, 1.0], [3.0, 0.0, 1.0], [0.0, -3.0, 1.0]])
    wp = Workpiece.from_cells(CellMesh(pts, [("triangle", np.array([[0, 1, 2]]))]))
    assert np.array_equal(wp.mesh.points, pts[:, :2])
    assert np.array_equal(wp.moved(wp.mesh.points).cells.points, pts)


def test_a_moved_vertex_of_a_constant_z_plate_keeps_its_z(files):
    cm = load_cells(files / "plate_z2.vtu")
    wp = Workpiece.from_cells(cm)
    q = wp.mesh.points.copy()
    q[0] += 0.01
    out = wp.moved(q).cells.points
    assert np.all(out[:, 2] == 2.0)
    assert np.array_equal(out[1:], cm.points[1:])
    assert np.array_equal(out[0, :2], q[0])


def test_points_off_every_plane_are_refused_with_the_one_tolerance():
    from meshopt_toolkit.pipeline import orientation as pipeline_orientation

    assert pipeline_orientation.PLANE_RTOL is PLANE_RTOL
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    tri = np.array([[0, 1, 2], [1, 3, 2]])
    for bump, planar in ((1e-3 * PLANE_RTOL, True), (1e3 * PLANE_RTOL, False)):
        p = pts.copy()
        p[3, 2] = bump * np.sqrt(2)
        cm = CellMesh(p, [("triangle", tri)])
        assert TriangleMesh(p, tri).is_planar is planar
        assert (pipeline_orientation.admissible_normal(p, tri) is not None) is planar
        if planar:
            Workpiece.from_cells(cm)
        else:
            with pytest.raises(InvalidMeshError, match="not planar"):
                Workpiece.from_cells(cm)


@settings(max_examples=40, deadline=None)
@given(origin=st.tuples(*[st.floats(-1e3, 1e3)] * 3),
       normal=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1),
       size=st.floats(1e-3, 1e3), moved=st.lists(st.integers(0, 36), max_size=5),
       step=st.floats(-0.05, 0.05))
# a tiny mesh far from the origin: its offsets from the plane are the coordinates' rounding
@example(origin=(744.8829661454572, 0.0, 0.0), normal=(1.0, 0.0, 1.0), size=0.001, moved=[],
         step=0.0)
def test_any_plane_round_trips_bit_for_bit_and_moved_vertices_stay_in_it(
        files, origin, normal, size, moved, step):
    base = load_cells(files / "hex.msh")
    n = np.array(normal) / np.linalg.norm(normal)
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    pts = np.array(origin) + size * (base.points[:, :1] * e1 + base.points[:, 1:2] * e2)
    cm = replace(base, points=pts)
    wp = Workpiece.from_cells(cm)
    assert np.array_equal(wp.moved(wp.mesh.points).cells.points, pts)  # bit for bit
    q = wp.mesh.points.copy()
    q[moved] += step
    out = wp.moved(q).cells.points
    keep = np.setdiff1d(np.arange(len(pts)), moved)
    assert np.array_equal(out[keep], pts[keep])
    dist = np.abs((out - np.array(origin)) @ n).max()
    assert dist <= 1e-12 * max(np.abs(pts).max(), size)  # rounding of the coordinates
    # the plane coordinates of another file with these points are this frame's
    assert np.array_equal(wp.plane_coordinates(pts), wp.plane)


# -- the commands ------------------------------------------------------------------------
@pytest.mark.parametrize("name", NAMES)
def test_identity_move_is_bit_for_bit_and_keeps_everything(files, tmp_path, name):
    out = tmp_path / f"out{name[name.index('.'):]}"
    assert main(["move", str(files / name), "-o", str(out), "--map", "x; y"]) == 0
    _assert_same_extras(load_cells(files / name), load_cells(out))


@pytest.mark.parametrize("name", NAMES)
def test_identity_deform_is_bit_for_bit_and_keeps_everything(files, tmp_path, name):
    src = load_cells(files / name)
    np.save(tmp_path / "zero.npy", np.zeros((len(src.points), 2)))
    out = tmp_path / f"out{name[name.index('.'):]}"
    assert main(["deform", str(files / name), "-o", str(out), "--displacement",
                 str(tmp_path / "zero.npy")]) == 0
    _assert_same_extras(src, load_cells(out))


def _turn(files, tmp_path, name, angle="0.3"):
    """``meshopt move`` turning the boundary by ``angle`` about the plane's origin."""
    out = tmp_path / f"turned{name[name.index('.'):]}"
    rot = f"x*cos({angle}) - y*sin({angle}); x*sin({angle}) + y*cos({angle})"
    assert main(["move", str(files / name), "-o", str(out), "--map", rot]) == 0
    return out


@pytest.mark.parametrize("name", NAMES)
def test_a_motion_keeps_everything_and_stays_in_the_plane(files, tmp_path, name):
    src = load_cells(files / name)
    out = load_cells(_turn(files, tmp_path, name))
    _assert_same_extras(src, out, points=False)
    assert not np.array_equal(src.points, out.points)
    if name == "plate_z2.vtu":
        assert np.all(out.points[:, 2] == 2.0)  # never scaled or shifted
    if name == "tilted.vtu":
        assert _off_plane(out.points) <= 1e-12
    wp = Workpiece.from_cells(out)
    assert check_mesh(wp.mesh).admissible


@pytest.mark.parametrize("name", NAMES)
def test_optimize_keeps_everything(files, tmp_path, name):
    src = load_cells(files / name)
    assert main(["optimize", str(files / name), "-o", str(tmp_path / "opt"),
                 "--max-iter", "3", "--no-plots"]) in (0, 1)
    out = load_cells(tmp_path / "opt" / f"optimized{name[name.index('.'):]}")
    _assert_same_extras(src, out, points=False)
    if name == "plate_z2.vtu":
        assert np.all(out.points[:, 2] == 2.0)
    if name == "tilted.vtu":
        assert _off_plane(out.points) <= 1e-12
    assert check_mesh(Workpiece.from_cells(out).mesh).admissible


@pytest.mark.parametrize("name", NAMES)
def test_morph_frames_carry_the_source_extras(files, tmp_path, name):
    src = load_cells(files / name)
    target = _turn(files, tmp_path, name, "0.2")
    outdir = tmp_path / "morph"
    assert main(["morph", str(files / name), str(target), "-o", str(outdir), "--frames", "3",
                 "--no-plots"]) == 0
    ext = name[name.index("."):]
    frames = [load_cells(outdir / f"frame_{k:03d}{ext}") for k in range(3)]
    for f in frames:
        _assert_same_extras(src, f, points=False)
        if name == "plate_z2.vtu":
            assert np.all(f.points[:, 2] == 2.0)
        if name == "tilted.vtu":
            assert _off_plane(f.points) <= 1e-12
    assert np.array_equal(frames[0].points, src.points)


def test_an_output_format_that_cannot_hold_everything_says_what_it_left_out(files, tmp_path,
                                                                           caplog):
    out = tmp_path / "out.obj"
    with caplog.at_level(logging.WARNING):
        assert main(["move", str(files / "plate_z2.vtu"), "-o", str(out), "--map", "x; y"]) == 0
    assert "out.obj" in caplog.text and "only the triangle mesh" in caplog.text
    assert np.array_equal(load_cells(out).points, load_cells(files / "plate_z2.vtu").points)


# -- refinement --------------------------------------------------------------------------
def _check_refined(src: CellMesh, fine: CellMesh):
    n = len(src.points)
    assert np.array_equal(fine.points[:n], src.points)
    assert [t for t, _ in fine.cells] == [t for t, _ in src.cells]
    for k, ((t, c), (_, f)) in enumerate(zip(src.cells, fine.cells)):
        factor = {"triangle": 4, "line": 2, "vertex": 1}[t]
        assert len(f) == factor * len(c)
        for name, blocks in src.cell_data.items():
            assert np.array_equal(fine.cell_data[name][k], np.repeat(blocks[k], factor, axis=0))
        if t == "line":  # each half of a line runs from an end to the edge's midpoint
            assert np.array_equal(f[0::2, 0], c[:, 0]) and np.array_equal(f[1::2, 1], c[:, 1])
            assert np.array_equal(f[0::2, 1], f[1::2, 0]) and np.all(f[0::2, 1] >= n)
            mid = 0.5 * (fine.points[c[:, 0]] + fine.points[c[:, 1]])
            assert np.allclose(fine.points[f[0::2, 1]], mid, rtol=0, atol=1e-14)
        if t == "vertex":
            assert np.array_equal(f, c)
    _assert_same_extras(replace(src, cells=[], cell_data={}, point_data={}),
                        replace(fine, cells=[], cell_data={}, point_data={}), points=False)


@pytest.mark.parametrize("name", ["plate_z2.vtu", "tilted.vtu"])
def test_pipeline_refinement_and_quality_keep_everything(files, tmp_path, name, caplog):
    from meshopt_toolkit.pipeline import Document
    from meshopt_toolkit.pipeline.document import load_entry, save_entry
    from meshopt_toolkit.pipeline.filter import registry

    src = load_cells(files / name)
    doc = Document()
    doc.add(load_entry(files / name))
    with caplog.at_level(logging.WARNING):
        registry.get("meshing_uniform_refinement")()(doc, iterations=1)
    assert "'ids'" in caplog.text  # integer point data cannot be interpolated: said so
    registry.get("compute_scalar_by_shape_quality_per_face")()(doc)
    save_entry(doc.current_entry, tmp_path / "fine.vtu")
    fine = load_cells(tmp_path / "fine.vtu")
    _check_refined(src, fine)
    assert sorted(fine.point_data) == ["temperature"]
    # a linear field interpolated at the midpoints is the field there
    t = 2.0 * fine.points[:, 0] / (3.0 if name == "plate_z2.vtu" else 1.0) + 1.0
    assert np.allclose(fine.point_data["temperature"], t, rtol=0, atol=1e-12)
    q = dict(zip([t for t, _ in fine.cells], fine.cell_data["quality"]))
    assert np.all(q["triangle"] >= 1.0 - 1e-12) and np.all(np.isnan(q["line"]))
    if name == "tilted.vtu":
        assert _off_plane(fine.points) <= 1e-15
    else:
        assert np.all(fine.points[:, 2] == 2.0)


def test_meshopt_run_refinement_of_a_gmsh_file_keeps_curves_and_groups(files, tmp_path):
    pipeline = tmp_path / "refine.json"
    pipeline.write_text(json.dumps({"filters": [
        {"name": "meshing_uniform_refinement", "params": {"iterations": 2}}]}))
    assert main(["run", str(pipeline), str(files / "hex.msh"), "-o", str(tmp_path / "o")]) == 0
    (out,) = (tmp_path / "o").glob("*.msh")
    src, fine = load_cells(files / "hex.msh"), load_cells(out)
    assert [t for t, _ in fine.cells] == [t for t, _ in src.cells]
    counts = {"vertex": 1, "line": 4, "triangle": 16}
    for k, ((t, c), (_, f)) in enumerate(zip(src.cells, fine.cells)):
        assert len(f) == counts[t] * len(c)
        for key in ("gmsh:physical", "gmsh:geometrical"):
            assert set(fine.cell_data[key][k]) == set(src.cell_data[key][k])
    assert {k: v.tolist() for k, v in fine.field_data.items()} == \
        {k: v.tolist() for k, v in src.field_data.items()}
    assert sorted(np.unique(np.concatenate(
        [p for (t, _), p in zip(fine.cells, fine.cell_data["gmsh:physical"]) if t == "line"]
    )).tolist()) == sorted(SIDES.values())


def test_planar_mesh_refine_splits_lines_in_place_and_keeps_non_edges():
    from meshopt_toolkit.mesh import PlanarMesh

    m = PlanarMesh([[0, 0], [1, 0], [0, 1], [1, 1]], [[0, 1, 2], [1, 3, 2]],
                   lines=[[0, 1], [0, 3], [3, 2]], line_tags=[4, 5, 6])
    r = m.refine()
    assert r.line_tags.tolist() == [4, 4, 5, 6, 6]
    assert r.lines[2].tolist() == [0, 3]  # not an edge: kept as it is
    mid = r.lines[0, 1]
    assert r.lines[1].tolist() == [mid, 1] and r.points[mid].tolist() == [0.5, 0.0]


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("metric", ["distortion", "scalar"])
def test_identity_morph_is_bit_for_bit(files, tmp_path, name, metric):
    src = load_cells(files / name)
    outdir = tmp_path / "m"
    assert main(["morph", str(files / name), str(files / name), "-o", str(outdir),
                 "--frames", "3", "--no-plots", "--metric", metric]) == 0
    for k in range(3):
        _assert_same_extras(src, load_cells(outdir / f"frame_{k:03d}{name[name.index('.'):]}"))


@pytest.mark.parametrize("name", NAMES)
def test_pipeline_motion_filters_keep_everything(files, tmp_path, name):
    from meshopt_toolkit.pipeline import Document
    from meshopt_toolkit.pipeline.document import load_entry, save_entry
    from meshopt_toolkit.pipeline.filter import registry

    src = load_cells(files / name)
    doc = Document()
    doc.add(load_entry(files / name))
    registry.get("apply_coord_prescribed_motion")()(doc, map="x; y")
    np.save(tmp_path / "zero.npy", np.zeros((len(src.points), 2)))
    registry.get("apply_coord_quality_preserving_deformation")()(
        doc, displacement=str(tmp_path / "zero.npy"))
    out = tmp_path / f"out{name[name.index('.'):]}"
    save_entry(doc.current_entry, out)
    _assert_same_extras(src, load_cells(out))  # both identities: bit for bit
    registry.get("apply_coord_prescribed_motion")()(doc, map="x + 0.05*y; y", where="x > 0.5")
    registry.get("apply_coord_shape_optimization")()(doc, max_iterations=2)
    save_entry(doc.current_entry, out)
    moved = load_cells(out)
    _assert_same_extras(src, moved, points=False)
    assert not np.array_equal(moved.points, src.points)
    if name == "tilted.vtu":
        assert _off_plane(moved.points) <= 1e-12


def test_unit_scaling_never_scales_z():
    from meshopt_toolkit.scaling import UnitScale

    mesh = TriangleMesh([[0, 0, 2.0], [8, 0, 2.0], [0, 8, 2.0]], [[0, 1, 2]])
    with pytest.raises(InvalidMeshError, match="plane's coordinates"):
        UnitScale(3).mesh_down(mesh)


@pytest.mark.parametrize("name", ["plate_z2.vtu", "tilted.vtu"])
def test_a_meshlab_step_that_keeps_the_faces_keeps_the_extras_and_the_plane(files, tmp_path,
                                                                         name):
    from meshopt_toolkit.pipeline import Document
    from meshopt_toolkit.pipeline.document import load_entry, save_entry
    from meshopt_toolkit.pipeline.runner import Pipeline

    pytest.importorskip("pymeshlab")
    src = load_cells(files / name)
    doc = Document()
    doc.add(load_entry(files / name))
    Pipeline.from_dict({"filters": [
        {"name": "apply_coord_laplacian_smoothing", "params": {"stepsmoothnum": 1}},
        {"name": "meshing_uniform_refinement"}]}).run(doc)
    save_entry(doc.current_entry, tmp_path / "out.vtu")
    out = load_cells(tmp_path / "out.vtu")
    assert [t for t, _ in out.cells] == [t for t, _ in src.cells]
    assert set(src.cell_data) <= set(out.cell_data) and "temperature" in out.point_data
    if name == "tilted.vtu":
        assert _off_plane(out.points) <= 1e-12
    else:
        assert np.all(out.points[:, 2] == 2.0)
