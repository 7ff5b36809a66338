"""Lossless or refusing conversion: CellMesh readers/writers, convert."""

from __future__ import annotations

import numpy as np
import pytest

from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import InvalidMeshError, ReadError, WriteError
from meshopt_toolkit.io import CellMesh, load, load_cells, save_cells
from meshopt_toolkit.datasets import data_path


def mixed() -> CellMesh:
    """Triangles, a quad, a boundary line and a vertex cell with physical groups."""
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0.5]])
    cells = [("line", np.array([[0, 1]])), ("triangle", np.array([[0, 1, 2], [1, 3, 2]])),
             ("quad", np.array([[1, 4, 5, 3]])), ("vertex", np.array([[4]]))]
    cd = {"gmsh:physical": [np.array([7]), np.array([3, 3]), np.array([3]), np.array([9])],
          "gmsh:geometrical": [np.array([1]), np.array([1, 1]), np.array([1]), np.array([2])]}
    fd = {"inlet": np.array([7, 1]), "surf": np.array([3, 2]), "pin": np.array([9, 0])}
    return CellMesh(pts, cells, cell_data=cd, field_data=fd)


def with_data() -> CellMesh:
    rng = np.random.default_rng(1)
    pts = rng.random((6, 3))
    cells = [("triangle", np.array([[0, 1, 2], [1, 3, 2]])), ("quad", np.array([[1, 4, 5, 3]])),
             ("polygon", np.array([[0, 1, 4, 5, 3]]))]
    pd = {"u": rng.random(6), "v": rng.random((6, 3)), "id": np.arange(6, dtype=np.int32)}
    cd = {"q": [rng.random(2), rng.random(1), rng.random(1)],
          "mat": [np.array([1, 2]), np.array([3]), np.array([4])]}
    return CellMesh(pts, cells, point_data=pd, cell_data=cd)


def assert_same_cells(a: CellMesh, b: CellMesh, *, field: bool = True) -> None:
    np.testing.assert_array_equal(a.points, b.points)
    assert [t for t, _ in a.cells] == [t for t, _ in b.cells]
    for (_, x), (_, y) in zip(a.cells, b.cells):
        np.testing.assert_array_equal(x, y)
    assert sorted(a.point_data) == sorted(b.point_data)
    for k in a.point_data:
        np.testing.assert_array_equal(a.point_data[k], b.point_data[k], err_msg=k)
        assert np.asarray(a.point_data[k]).shape == np.asarray(b.point_data[k]).shape, k
    assert sorted(a.cell_data) == sorted(b.cell_data)
    for k in a.cell_data:
        for x, y in zip(a.cell_data[k], b.cell_data[k]):
            np.testing.assert_array_equal(x, y, err_msg=k)
            assert np.asarray(x).shape == np.asarray(y).shape, k
    if field:
        assert sorted(a.field_data) == sorted(b.field_data)
        for k in a.field_data:
            np.testing.assert_array_equal(np.asarray(a.field_data[k]).reshape(-1),
                                          np.asarray(b.field_data[k]).reshape(-1))


@pytest.mark.parametrize("chain", [
    [".msh", ".vtu", ".msh"],
    [".vtu", ".msh", ".vtu"],
])
@pytest.mark.parametrize("binary", [True, False])
@pytest.mark.parametrize("version", ["4.1", "2.2"])
def test_msh_vtu_msh_keeps_every_cell_and_group(tmp_path, chain, binary, version):
    m = mixed()
    cur = m
    for i, ext in enumerate(chain):
        path = save_cells(cur, tmp_path / f"s{i}{ext}", binary=binary, msh_version=version)
        cur = load_cells(path)
        assert_same_cells(m, cur)


@pytest.mark.parametrize("ext", [".vtu", ".vtk"])
@pytest.mark.parametrize("binary", [True, False])
def test_vtu_keeps_point_and_cell_data(tmp_path, ext, binary):
    m = with_data()
    back = load_cells(save_cells(m, tmp_path / f"d{ext}", binary=binary))
    assert_same_cells(m, back)
    again = load_cells(save_cells(back, tmp_path / f"e{ext}", binary=binary))
    assert_same_cells(m, again)


@pytest.mark.parametrize("binary", [True, False])
def test_ply_keeps_polygons_and_scalar_data(tmp_path, binary):
    m = with_data()
    m = CellMesh(m.points, m.cells, point_data={"u": m.point_data["u"],
                                                "id": m.point_data["id"]},
                 cell_data={"q": m.cell_data["q"]})
    back = load_cells(save_cells(m, tmp_path / "p.ply", binary=binary))
    assert_same_cells(m, back)


@pytest.mark.parametrize("ext", [".obj", ".off"])
def test_text_formats_keep_polygons(tmp_path, ext):
    m = with_data()
    m = CellMesh(m.points, m.cells)
    back = load_cells(save_cells(m, tmp_path / f"p{ext}"))
    assert_same_cells(m, back)


GROUPS = "gmsh:physical, gmsh:geometrical cell data"
NAMES = "inlet, surf, pin field data"


@pytest.mark.parametrize("ext,what", [
    (".obj", f"OBJ files cannot hold {GROUPS}; {NAMES} (use .vtu)"),
    (".off", f"OFF files cannot hold {GROUPS}; {NAMES}; 1 line cells, 1 vertex cells (use .vtu)"),
    (".ply", f"PLY files cannot hold {NAMES}; 1 line cells, 1 vertex cells (use .vtu)"),
    (".stl", f"STL files cannot hold {GROUPS}; {NAMES}; 1 line cells, 1 quad cells, "
             "1 vertex cells (use .vtu or .msh)"),
    (".vtk", f"legacy VTK files cannot hold {NAMES} (use .vtu)"),
])
def test_what_a_format_cannot_hold_is_refused(tmp_path, ext, what):
    with pytest.raises(WriteError) as info:
        save_cells(mixed(), tmp_path / f"x{ext}")
    assert str(info.value) == f"{tmp_path / f'x{ext}'}: {what}"
    assert list(tmp_path.iterdir()) == []  # nothing written, no partial file


def test_msh_refuses_point_data(tmp_path):
    # u and v are float views ($NodeData); the int32 id is not
    with pytest.raises(WriteError, match=r"gmsh files cannot hold id point data; q, mat "
                                         r"cell data; 1 polygon cells \(use \.vtu\)"):
        save_cells(with_data(), tmp_path / "x.msh")


def test_gmsh41_entity_with_two_physical_tags_is_refused(tmp_path):
    m = mixed()
    m.cell_data["gmsh:physical"][1] = np.array([3, 4])
    with pytest.raises(WriteError, match="msh-version 2.2"):
        save_cells(m, tmp_path / "x.msh", msh_version="4.1")
    back = load_cells(save_cells(m, tmp_path / "x.msh", msh_version="2.2"))
    assert_same_cells(m, back)


def test_triangle_operations_refuse_other_cells(tmp_path):
    path = save_cells(mixed(), tmp_path / "m.msh")
    with pytest.raises(ReadError, match=r"m\.msh: has 1 quad cells; only triangles"):
        load(path)


# -- OBJ ------------------------------------------------------------------------------


def test_obj_quad_after_triangles_is_kept_whole(tmp_path):
    path = tmp_path / "q.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 0 0\nv 2 1 0\nv 3 1 0\n"
                    "f 1 2 3\nf 2 6 7 3\nf 2 5 6\n")
    cm = load_cells(path)
    assert [(t, c.tolist()) for t, c in cm.cells] == [
        ("triangle", [[0, 1, 2]]), ("quad", [[1, 5, 6, 2]]), ("triangle", [[1, 4, 5]])]
    with pytest.raises(ReadError, match="1 quad cells"):
        load(path)


def test_obj_two_coordinate_vertex_among_three_is_refused(tmp_path):
    path = tmp_path / "v.obj"
    path.write_text("v 0 0 1\nv 1 0 2\nv 0 1\nf 1 2 3\n")
    with pytest.raises(ReadError, match=r"vertex 3 has 2 coordinates"):
        load(path)
    path.write_text("v 0 0\nv 1 0\nv 0 1\nf 1 2 3\n")  # all 2D: fine
    assert load(path).dim == 2


def test_obj_unrepresented_statements_refused_by_convert(tmp_path, capsys):
    src = tmp_path / "t.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\ng part\nusemtl red\nf 1 2 3\n")
    assert load(src).n_triangles == 1  # the triangle operations may ignore them
    assert main(["convert", str(src), "-o", str(tmp_path / "t.vtu")]) == 1
    err = capsys.readouterr().err
    assert err == (f"meshopt convert: error: {src}: cannot convert without loss: 1 'g' "
                   "statements; 1 'usemtl' statements would not be kept; --allow-loss "
                   "writes the rest and names what it drops\n")
    assert not (tmp_path / "t.vtu").exists()


# -- the command -------------------------------------------------------------------------


def test_convert_prints_what_it_wrote_and_keeps_groups(tmp_path, capsys):
    src = save_cells(mixed(), tmp_path / "m.msh", msh_version="2.2")
    out = tmp_path / "m.vtu"
    assert main(["convert", str(src), "-o", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out} (6 vertices, 5 cells)"
    back = tmp_path / "back.msh"
    assert main(["convert", str(out), "-o", str(back)]) == 0
    assert_same_cells(mixed(), load_cells(back))


def test_converted_disc_keeps_its_boundary_group(tmp_path):
    vtu, msh = tmp_path / "d.vtu", tmp_path / "d.msh"
    assert main(["convert", str(data_path("disc_77.msh")), "-o", str(vtu)]) == 0
    assert main(["convert", str(vtu), "-o", str(msh)]) == 0
    for path in (vtu, msh):
        mesh = load(path).as_planar()
        np.testing.assert_array_equal(mesh.tagged_vertices("boundary"),
                                      load(data_path("disc_77.msh")).tagged_vertices("boundary"))


def test_convert_refusal_is_one_line(tmp_path, capsys):
    src = save_cells(mixed(), tmp_path / "m.msh")
    assert main(["convert", str(src), "-o", str(tmp_path / "m.stl")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "m.stl: STL files cannot hold" in err[0] and "1 quad cells" in err[0]
    assert not (tmp_path / "m.stl").exists()


def test_from_triangle_mesh_and_back(tmp_path):
    mesh = load(data_path("disc_77.msh"))
    cm = CellMesh.from_triangle_mesh(mesh)
    back = cm.to_triangle_mesh()
    assert back == mesh and np.array_equal(back.line_tags, mesh.line_tags)
    with pytest.raises(InvalidMeshError, match="no triangles"):
        CellMesh(np.zeros((2, 3)), [("line", np.array([[0, 1]]))]).to_triangle_mesh()
