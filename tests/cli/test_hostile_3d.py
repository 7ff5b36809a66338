"""Inputs a careless or hostile user gives the 3D commands: each refusal is one line naming
the file (no warning line before it), each accepted file is written (small real files)."""

from __future__ import annotations

import pytest

from meshopt_toolkit.cli import main

trimesh = pytest.importorskip("trimesh")


def _obj_with_statements(path, faces: str) -> None:
    """An OBJ file of a 3 × 3 grid bent in z: an 'o' statement (which the reader does not
    represent), the vertices, then ``faces`` (face lines, 'g' statements among them)."""
    rows = [f"v {i} {j} {0.1 * i * j}" for j in range(3) for i in range(3)]
    path.write_text("o plate\n" + "\n".join(rows) + "\n" + faces)


@pytest.mark.parametrize("faces, argv", [
    # quads: refused for their cells
    ("g left\nf 1 2 5 4\nf 2 3 6 5\ng right\nf 4 5 8 7\nf 5 6 9 8\n",
     ["--where", "x < 0.5", "--map", "x; y; z + 0.1"]),
    # triangles, a selection of no vertex: refused for the selection
    ("g left\nf 1 2 5\nf 1 5 4\ng right\nf 5 6 9\nf 5 9 8\n",
     ["--where", "x > 5", "--map", "x; y; z + 0.1"]),
])
def test_a_refused_move_is_one_line_without_the_not_kept_warning(tmp_path, capsys, caplog,
                                                                   faces, argv):
    src = tmp_path / "plate.obj"
    _obj_with_statements(src, faces)
    rc = main(["move", str(src), "-o", str(tmp_path / "out.obj"), *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1
    assert len(err) == 1 and "error" in err[0] and str(src) in err[0], err
    assert not [r for r in caplog.records if r.levelname == "WARNING"], caplog.text
    assert not (tmp_path / "out.obj").exists()


def test_a_written_move_still_names_what_it_did_not_keep(tmp_path, caplog):
    src = tmp_path / "plate.obj"
    _obj_with_statements(src, "g left\nf 1 2 5\nf 1 5 4\ng right\nf 5 6 9\nf 5 9 8\n")
    rc = main(["move", str(src), "-o", str(tmp_path / "out.obj"), "--where", "x < 0.5",
               "--map", "x; y; z + 0.1"])
    assert rc == 0 and (tmp_path / "out.obj").exists()
    assert "not kept in the output" in caplog.text and "'g' statements" in caplog.text


@pytest.mark.parametrize("ext, binary", [(".ply", True), (".obj", False), (".stl", True)])
def test_a_mesh_given_as_the_pipeline_is_refused_as_not_a_pipeline(tmp_path, capsys, ext,
                                                                    binary):
    mesh = tmp_path / f"sphere{ext}"
    trimesh.creation.icosphere(1).export(mesh, **({"encoding": "binary"} if ext == ".ply"
                                                   else {}))
    rc = main(["run", str(mesh), str(mesh), "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1, err
    assert str(mesh) in err[0] and "not a pipeline" in err[0], err
    assert not (tmp_path / "out").exists()


def test_a_refused_morph_is_one_line_without_the_not_kept_warning(tmp_path, capsys, caplog):
    src, tgt = tmp_path / "plate.obj", tmp_path / "other.obj"
    _obj_with_statements(src, "g left\nf 1 2 5\nf 1 5 4\ng right\nf 5 6 9\nf 5 9 8\n")
    _obj_with_statements(tgt, "f 1 2 5\nf 1 5 4\n")  # other triangles: refused
    rc = main(["morph", str(src), str(tgt), "-o", str(tmp_path / "out"), "--frames", "2",
               "--no-plots"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and "error" in err[0], err
    assert not [r for r in caplog.records if r.levelname == "WARNING"], caplog.text


def test_a_vtu_datum_under_the_gmsh_entity_name_is_named_not_lost(tmp_path, caplog, capsys):
    """A .vtu's point datum named ``gmsh:dim_tags`` (the name meshio gives gmsh's node
    entities, which the readers leave out) is named by move and refused by convert."""
    import meshio
    import numpy as np

    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    src = tmp_path / "t.vtu"
    meshio.Mesh(pts, [("tetra", np.array([[0, 1, 2, 3]]))],
                point_data={"gmsh:dim_tags": np.arange(8).reshape(4, 2)}).write(src)
    assert main(["move", str(src), "-o", str(tmp_path / "o.vtu"), "--where", "z > 0.5",
                 "--map", "x; y; z + 0.1"]) == 0
    assert [r.getMessage() for r in caplog.records if "gmsh:dim_tags" in r.getMessage()] == [
        f"{src}: not kept in the output: point data 'gmsh:dim_tags'"]
    assert main(["convert", str(src), "-o", str(tmp_path / "t.msh")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "gmsh:dim_tags" in err[0] and not (tmp_path / "t.msh").exists()
