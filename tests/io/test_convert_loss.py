"""Conversions users can finish: OBJ/PLY normals and texture coordinates travel as point
data, ``--allow-loss`` writes what a format holds and names the rest in one line, ASCII
STL keeps float64 exactly, and every reader refuses a huge index with one line."""

from __future__ import annotations

import warnings

import meshio
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.cli import main
from meshopt_toolkit.datasets import data_path
from meshopt_toolkit.errors import ReadError
from meshopt_toolkit.io import CellMesh, load_cells, save_cells
from meshopt_toolkit.io.cells import NORMALS, TEXCOORDS

FLOATS = st.floats(allow_nan=False, allow_infinity=False, width=64, min_value=-1e300,
                   max_value=1e300)


def obj_text(pts, uv, nrm, faces, perm_t, perm_n) -> str:
    """OBJ text whose ``vt``/``vn`` lists are stored in another order than the vertices
    (row ``perm[i]`` belongs to vertex ``i``): per vertex, yet indices differ per corner."""
    vt = np.empty_like(uv)
    vt[perm_t] = uv
    vn = np.empty_like(nrm)
    vn[perm_n] = nrm
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in pts.tolist()]
    lines += [f"vt {u!r} {v!r}" for u, v in vt.tolist()]
    lines += [f"vn {a!r} {b!r} {c!r}" for a, b, c in vn.tolist()]
    lines += ["f " + " ".join(f"{i + 1}/{perm_t[i] + 1}/{perm_n[i] + 1}" for i in f)
              for f in faces.tolist()]
    return "\n".join(lines) + "\n"


FACES = np.array([[0, 1, 2], [1, 3, 2], [2, 3, 4]])


@settings(max_examples=25, deadline=None)
@given(st.lists(FLOATS, min_size=5 * 8, max_size=5 * 8), st.permutations(range(5)),
       st.permutations(range(5)))
def test_obj_normals_and_uv_through_ply_and_back_are_bitwise_equal(tmp_path_factory, values,
                                                                   perm_t, perm_n):
    tmp = tmp_path_factory.mktemp("nt")
    a = np.array(values).reshape(5, 8)
    pts, uv, nrm = a[:, :3], a[:, 3:5], a[:, 5:]
    src = tmp / "m.obj"
    src.write_text(obj_text(pts, uv, nrm, FACES, np.array(perm_t), np.array(perm_n)))
    cm = load_cells(src)
    assert cm.dropped == []
    # the reference is the generated arrays themselves, not our reader's output
    for got, want in ((cm.points, pts), (cm.point_data[TEXCOORDS], uv),
                      (cm.point_data[NORMALS], nrm)):
        assert got.tobytes() == want.tobytes()
    for binary in ("--binary", "--ascii"):
        ply, back = tmp / f"m{binary}.ply", tmp / f"b{binary}.obj"
        assert main(["convert", str(src), "-o", str(ply), binary]) == 0
        assert main(["convert", str(ply), "-o", str(back)]) == 0
        out = load_cells(back)
        assert [(t, c.tolist()) for t, c in out.cells] == [("triangle", FACES.tolist())]
        for got, want in ((out.points, pts), (out.point_data[TEXCOORDS], uv),
                          (out.point_data[NORMALS], nrm)):
            assert got.tobytes() == want.tobytes()


def _normals_obj(tmp_path):
    rng = np.random.default_rng(3)
    pts, uv = rng.random((5, 3)), rng.random((5, 2))
    nrm = rng.normal(size=(5, 3))
    src = tmp_path / "n.obj"
    src.write_text(obj_text(pts, uv, nrm, FACES, np.arange(5), np.arange(5)[::-1]))
    return src, pts, uv, nrm


@pytest.mark.parametrize("ext", [".vtu", ".vtk"])
def test_obj_normals_kept_by_vtk_formats(tmp_path, ext, capsys):
    src, pts, uv, nrm = _normals_obj(tmp_path)
    out = tmp_path / f"n{ext}"
    assert main(["convert", str(src), "-o", str(out)]) == 0
    assert capsys.readouterr().err == ""
    m = meshio.read(out)  # an independent reader
    np.testing.assert_array_equal(m.point_data[NORMALS], nrm)
    tex = m.point_data[TEXCOORDS]
    if ext == ".vtk":  # legacy VTK vectors have 3 components: meshio pads u, v with 0
        assert not tex[:, 2].any()
        tex = tex[:, :2]
    np.testing.assert_array_equal(tex, uv)
    np.testing.assert_array_equal(m.points, pts)


def test_ply_normals_and_uv_are_what_trimesh_and_meshlab_read(tmp_path):
    src, pts, uv, nrm = _normals_obj(tmp_path)
    ply = tmp_path / "n.ply"
    assert main(["convert", str(src), "-o", str(ply)]) == 0
    trimesh = pytest.importorskip("trimesh")
    tm = trimesh.load(ply, process=False)
    np.testing.assert_array_equal(tm.vertices, pts)
    np.testing.assert_array_equal(tm.vertex_normals, nrm)  # no re-normalization asked
    np.testing.assert_array_equal(tm.visual.uv, uv)
    pymeshlab = pytest.importorskip("pymeshlab")
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(ply))
    m = ms.current_mesh()
    assert m.has_vertex_tex_coord()  # MeshLab reads texture_u/texture_v
    np.testing.assert_allclose(m.vertex_tex_coord_matrix(), uv, rtol=1e-6)
    np.testing.assert_allclose(m.vertex_normal_matrix(), nrm, rtol=1e-6)


def test_normals_only_obj_round_trip(tmp_path):
    cm = CellMesh(np.eye(3), [("triangle", np.array([[0, 1, 2]]))],
                  point_data={NORMALS: np.array([[0.0, 0, 1], [0, 0.6, 0.8], [1e-300, 0, 1]])})
    path = save_cells(cm, tmp_path / "n.obj")
    assert "f 1//1 2//2 3//3" in path.read_text()
    back = load_cells(path)
    assert back.point_data[NORMALS].tobytes() == cm.point_data[NORMALS].tobytes()


def test_normals_that_are_not_per_vertex_need_allow_loss(tmp_path, capsys):
    src = tmp_path / "s.obj"  # vertex 2 has normal 1 in one face and 2 in the other
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvn 0 1 0\n"
                   "f 1//1 2//1 3//1\nf 2//2 4//2 3//2\n")
    out = tmp_path / "s.ply"
    assert main(["convert", str(src), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err == (f"meshopt convert: error: {src}: cannot convert without loss: normals 'vn' "
                   "(not per vertex: a vertex has different ones in different faces) would "
                   "not be kept; --allow-loss writes the rest and names what it drops\n")
    assert not out.exists()
    assert main(["convert", str(src), "-o", str(out), "--allow-loss"]) == 0
    cap = capsys.readouterr()
    assert cap.err == (f"meshopt convert: warning: {src}: dropped: normals 'vn' (not per "
                       "vertex: a vertex has different ones in different faces)\n")
    assert cap.out == f"wrote {out} (4 vertices, 2 cells)\n"
    assert load_cells(out).point_data == {}


def _reference(path):
    """What meshio (an independent reader) finds in a gmsh file."""
    m = meshio.read(path)
    counts = {}
    for block in m.cells:
        counts[block.type] = counts.get(block.type, 0) + len(block.data)
    return m, counts


@pytest.mark.parametrize("ext", [".obj", ".ply", ".off", ".stl"])
def test_gmsh_groups_to_surface_formats(tmp_path, capsys, ext):
    src = data_path("disc_77.msh")
    m, counts = _reference(src)
    names = ", ".join(m.field_data)
    groups = "gmsh:physical, gmsh:geometrical cell data; "
    dropped = {".obj": f"{groups}{names} field data",
               ".ply": f"{names} field data; {counts['line']} line cells",
               ".off": f"{groups}{names} field data; {counts['line']} line cells",
               ".stl": f"{groups}{names} field data; {counts['line']} line cells"}[ext]
    out = tmp_path / f"d{ext}"
    assert main(["convert", str(src), "-o", str(out)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"meshopt convert: error: {out}: ")
    assert err[0].endswith("; --allow-loss writes the rest and names what it drops")
    assert not out.exists()
    assert main(["convert", str(src), "-o", str(out), "--allow-loss"]) == 0
    cap = capsys.readouterr()
    assert cap.err == f"meshopt convert: warning: {src}: dropped: {dropped}\n"
    back = load_cells(out)
    tris = [c for t, c in back.cells if t == "triangle"]
    want = np.concatenate([b.data for b in m.cells if b.type == "triangle"])
    if ext == ".stl":  # unordered, float32 (binary): compare the triangles' corners
        f32 = m.points.astype(np.float32).astype(np.float64)
        np.testing.assert_array_equal(back.points[tris[0]], f32[want])
    else:
        np.testing.assert_array_equal(np.concatenate(tris), want)
        np.testing.assert_array_equal(back.points, m.points)
    lines = sum(len(c) for t, c in back.cells if t == "line")
    assert lines == (counts["line"] if ext == ".obj" else 0)


def test_allow_loss_in_a_batch_names_each_files_loss(tmp_path, capsys):
    src = data_path("disc_77.msh")
    other = tmp_path / "sq.msh"
    other.write_bytes(data_path("square5.msh").read_bytes())
    out = tmp_path / "out"
    assert main(["convert", str(src), str(other), "-o", str(out), "--to", "off",
                 "--allow-loss"]) == 0
    err = capsys.readouterr().err.splitlines()
    warned = [e for e in err if ": dropped: " in e]
    assert len(warned) == 2 and warned[0].startswith(f"meshopt convert: warning: {src}: ")
    assert sorted(p.name for p in out.glob("*.off")) == ["disc_77.off", "sq.off"]


@settings(max_examples=25, deadline=None)
@given(st.lists(FLOATS, min_size=4 * 3, max_size=4 * 3, unique=True))
def test_ascii_stl_round_trip_is_bitwise(tmp_path_factory, values):
    pts = np.array(values).reshape(4, 3)
    tris = np.array([[0, 1, 2], [0, 2, 3], [1, 3, 2]])
    path = tmp_path_factory.mktemp("stl") / "m.stl"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow in the facet normals of huge corners
        save_cells(CellMesh(pts, [("triangle", tris)]), path, binary=False)
    back = load_cells(path)
    [(kind, out)] = back.cells
    assert kind == "triangle"
    assert back.points[out].tobytes() == pts[tris].tobytes()  # every corner, bit for bit


HUGE = "999999999999999999995"
FILES = {
    "a.obj": f"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 {HUGE}\n",
    "b.obj": f"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/{HUGE}\n",
    "a.off": f"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 {HUGE}\n",
    "b.off": f"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n{HUGE} 0 1 2\n",
    "a.ply": ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
              f"end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 {HUGE}\n"),
    "b.ply": ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nproperty uchar red\nelement face 1\n"
              "property list uchar int vertex_indices\nend_header\n"
              "0 0 0 300\n1 0 0 1\n0 1 0 2\n3 0 1 2\n"),
    "c.ply": ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 1e300\n1 0 0\n0 1 0\n3 0 1 2\n"),
    "a.vtk": ("# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\n"
              f"POINTS 3 double\n0 0 0 1 0 0 0 1 0\nCELLS 1 4\n3 0 1 {HUGE}\nCELL_TYPES 1\n5\n"),
    "a.msh": ("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n"
              f"$EndNodes\n$Elements\n1\n1 2 2 0 1 1 2 {HUGE}\n$EndElements\n"),
}
MESSAGES = {
    "a.obj": "element index 1000000000000000000000 out of range",
    "b.obj": "texture index 1000000000000000000000 out of range",
    "a.off": f"face index {HUGE} out of range",
    "b.off": f"face size {HUGE} out of range",
    "a.ply": "PLY face index 1000000000000000000000 out of range",
    "b.ply": "vertex property 'red': value 300.0 does not fit its type uchar",
    "c.ply": "vertex property 'z': value 1e+300 does not fit its type float",
    "a.vtk": "out of range",
    "a.msh": "cannot read gmsh file",
}


@pytest.mark.parametrize("name", sorted(FILES))
def test_every_reader_refuses_a_huge_index_with_one_line(tmp_path, name):
    path = tmp_path / name
    path.write_text(FILES[name])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning in a cast is a failure here
        with pytest.raises(ReadError) as info:
            load_cells(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: ") and MESSAGES[name] in msg and "\n" not in msg


def test_binary_stl_refuses_coordinates_beyond_float32(tmp_path):
    from meshopt_toolkit.errors import WriteError

    cm = CellMesh(np.array([[0, 0, 0], [1e300, 0, 0], [0, 1, 0]]),
                  [("triangle", np.array([[0, 1, 2]]))])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(WriteError, match=r"binary STL holds float32 coordinates; 1e\+300 is "
                                             r"out of range \(write ASCII\)"):
            save_cells(cm, tmp_path / "m.stl")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("options", [["--msh-version", "2.2", "--ascii"],
                                     ["--msh-version", "2.2"], ["--ascii"], []])
def test_obj_normals_kept_by_msh_as_node_data(tmp_path, capsys, options):
    src, pts, uv, nrm = _normals_obj(tmp_path)
    out = tmp_path / "n.msh"
    assert main(["convert", str(src), "-o", str(out), *options]) == 1  # (N, 2) uv: no view
    assert "texture_coordinates point data" in capsys.readouterr().err
    assert main(["convert", str(src), "-o", str(out), "--allow-loss", *options]) == 0
    assert capsys.readouterr().err == (f"meshopt convert: warning: {src}: dropped: "
                                       "texture_coordinates point data\n")
    back = load_cells(out)
    assert back.point_data[NORMALS].tobytes() == nrm.tobytes()
    assert back.points.tobytes() == pts.tobytes()
    pytest.importorskip("gmsh")  # gmsh itself reads the view
    from meshopt_toolkit.gmsh_session import gmsh_session

    with gmsh_session() as gmsh:
        gmsh.open(str(out))
        [tag] = gmsh.view.getTags()
        kind, nodes, data, _, comps = gmsh.view.getModelData(tag, 0)
    assert (kind, comps) == ("NodeData", 3)
    np.testing.assert_array_equal(np.asarray(data)[np.argsort(nodes)], nrm)


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_without_leaves_out_exactly_the_parts_and_stays_consistent(data):
    from test_convert_lossless import mixed

    from meshopt_toolkit.io._loss import data_parts, describe, without
    from meshopt_toolkit.io.cells import check_cells

    cm = mixed()
    every = [("cells", t) for t in cm.cell_counts()] + data_parts(cm)
    parts = data.draw(st.lists(st.sampled_from(every), unique=True))
    out = without(cm, parts)
    check_cells(out)  # cell data lists still match the remaining blocks
    gone = {name for kind, name in parts if kind == "cells"}
    assert [t for t, _ in out.cells] == [t for t, _ in cm.cells if t not in gone]
    for kind, table in (("cell", out.cell_data), ("field", out.field_data)):
        dropped = {name for k, name in parts if k == kind}
        assert set(table) == set(getattr(cm, f"{kind}_data")) - dropped
    for key, blocks in out.cell_data.items():  # the kept blocks' values, untouched
        kept = [b for (t, _), b in zip(cm.cells, cm.cell_data[key]) if t not in gone]
        assert all(np.array_equal(a, b) for a, b in zip(blocks, kept))
    assert out.dropped == ([describe(cm, parts)] if parts else [])
