"""``meshopt info`` describes files of any cell types (counts, bounding box, the quality
of their tetrahedra and triangles); the operations that need simplices refuse them in one
line naming the file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshopt_toolkit.cli import main
from meshopt_toolkit.io import save_cells
from meshopt_toolkit.io.cells import CellMesh

S3 = np.sqrt(3.0)


def mixed_cells() -> CellMesh:
    """A unit hexahedron, a pyramid on it, a wedge beside it, a regular tetrahedron and an
    equilateral triangle (closed forms: mean ratio 1, aspect ratio 1)."""
    cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                     [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    apex = [[0.5, 0.5, 1.7]]
    wedge = [[2, 0, 0], [2, 1, 0], [2, 0, 1], [2, 1, 1]]  # with cube's 1, 2, 5, 6
    tet = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float) + [5, 5, 5]
    tri = [[10, 0, 0], [11, 0, 0], [10.5, S3 / 2, 0]]
    pts = np.concatenate([cube, apex, wedge, tet, tri])
    return CellMesh(pts, [
        ("hexahedron", np.array([[0, 1, 2, 3, 4, 5, 6, 7]])),
        ("pyramid", np.array([[4, 5, 6, 7, 8]])),
        ("wedge", np.array([[1, 9, 10, 5, 11, 12]])),  # triangles at z = 0 and z = 1
        ("tetra", np.array([[13, 15, 14, 16]])),
        ("triangle", np.array([[17, 18, 19]])),
    ])


@pytest.fixture
def mixed_msh(tmp_path):
    return save_cells(mixed_cells(), tmp_path / "mixed.msh")


def _info(path, capsys) -> dict:
    assert main(["info", "--json", str(path)]) == 0
    return json.loads(capsys.readouterr().out)


def test_info_describes_mixed_cells(mixed_msh, capsys):
    info = _info(mixed_msh, capsys)
    assert info["cell_kind"] == "mixed cells"
    counts = {k: v for k, v in info.items() if k.startswith("n_") and k not in
              ("n_vertices", "n_cells")}
    assert counts == {"n_hexahedron": 1, "n_pyramid": 1, "n_wedge": 1, "n_tetra": 1,
                      "n_triangle": 1}
    # gmsh reads the same elements
    gmsh_counts = {}
    pytest.importorskip("gmsh")
    from meshopt_toolkit.gmsh_session import gmsh_session

    with gmsh_session() as gmsh:
        gmsh.open(str(mixed_msh))
        types, tags, _ = gmsh.model.mesh.getElements()
        for t, e in zip(types, tags):
            name = gmsh.model.mesh.getElementProperties(t)[0].split()[0].lower()
            gmsh_counts[name] = len(e)
    assert gmsh_counts == {"hexahedron": 1, "pyramid": 1, "prism": 1, "tetrahedron": 1,
                           "triangle": 1}
    pts = mixed_cells().points
    assert info["bounding_box_min"] == pts.min(axis=0).tolist()
    assert info["bounding_box_max"] == pts.max(axis=0).tolist()
    assert info["tetra_min_mean_ratio"] == pytest.approx(1.0, abs=1e-12)
    assert info["tetra_total_volume"] == pytest.approx(8 / 3, rel=1e-12)  # edge 2√2
    assert info["triangle_min_aspect_ratio"] == pytest.approx(1.0, abs=1e-12)
    assert "hexahedron" in info["operations"]


def test_info_describes_a_quad_obj_and_prints_text(tmp_path, capsys):
    src = tmp_path / "quads.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0.2\nv 2 1 0\n"
                   "f 1 2 5 4\nf 2 3 6 5\n")
    info = _info(src, capsys)
    assert info["n_quad"] == 2 and info["n_vertices"] == 6
    assert info["bounding_box_max"] == [2.0, 1.0, 0.2]
    assert main(["info", str(src)]) == 0
    text = capsys.readouterr().out
    assert "mixed cells" in text and "n quad" in text


@pytest.mark.parametrize("command", [["move", "--map", "x; y; z + 1"],
                                     ["optimize"]])
def test_operations_refuse_mixed_cells_in_one_line(mixed_msh, tmp_path, capsys, command):
    out = tmp_path / ("out.msh" if command[0] == "move" else "out")
    args = [command[0], str(mixed_msh), "-o", str(out), *command[1:]]
    assert main(args) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(mixed_msh) in err[0] and "supported" in err[0], err
    assert not out.exists()
