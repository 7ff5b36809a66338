"""Every error of every command is one line on stderr naming the file ("FILE: cause"),
errors raised deep in the library included; nothing is written.

The reproducers are real files (a 125-vertex tet cube, a sphere, a surface with a
degenerate triangle, a .msh with a header only, target tables with bad rows); the last
tests make a library call fail with a message that names no file, for each command.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from meshopt_toolkit import data_path
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.io import save_cells
from meshopt_toolkit.io.cells import CellMesh

trimesh = pytest.importorskip("trimesh")

# the six tets of a unit cube (Kuhn's subdivision), by corner bits (x, y, z)
_KUHN = [(0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)]


def _cube_tets(n: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Tets of [0, 1]³ on an n × n × n grid of vertices, positively oriented."""
    g = np.linspace(0.0, 1.0, n)
    P = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange(n ** 3).reshape(n, n, n)
    base = idx[:-1, :-1, :-1].ravel()
    corner = np.array([idx[(b >> 0) & 1, (b >> 1) & 1, (b >> 2) & 1] for b in range(8)])
    T = np.array([[base + corner[c] for c in tet] for tet in _KUHN]).transpose(2, 0, 1)
    T = T.reshape(-1, 4)
    e = P[T[:, 1:]] - P[T[:, :1]]
    flip = np.linalg.det(e) < 0
    T[flip] = T[flip][:, [0, 2, 1, 3]]
    return P, T


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("reproducers")
    P, T = _cube_tets()
    save_cells(CellMesh(P, [("tetra", T)]), d / "cube.msh")
    unit = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    save_cells(CellMesh(np.vstack([unit, unit + 0.25]), [("tetra", np.array(
        [[0, 1, 2, 3], [4, 5, 6, 7]]))]), d / "crossing.msh")
    s = trimesh.creation.icosphere(subdivisions=2)
    s.export(d / "sphere.obj")
    V, F = np.array(s.vertices), np.array(s.faces)
    V[F[0, 2]] = V[F[0, 0]]  # triangle 0 has two equal corners
    trimesh.Trimesh(V, F, process=False).export(d / "degenerate.obj")
    (d / "header_only.msh").write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n")
    (d / "out_of_range.csv").write_text("200,0,0,0\n")
    (d / "twice.csv").write_text("index,x,y,z\n5,0.1,0,0\n# a comment\n5,0.2,0,0\n")
    (d / "not_finite.csv").write_text("index,x,y,z\n5,0.1,0,0\n6,nan,0,0\n")
    (d / "nudge.csv").write_text("0,0,0,0.1\n")
    (d / "far.csv").write_text("62,3,0.5,0.5\n")  # the centre, outside the fixed boundary
    shutil.copy(data_path("disc_25.msh"), d / "disc.msh")
    np.save(d / "v.npy", np.zeros((25, 2)))
    return d


def _one_line(capsys, *names) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    lines = [ln for ln in err if not ln.startswith("meshopt run: ") or ": error: " in ln]
    assert len(lines) == 1, err
    assert "Traceback" not in lines[0] and "internal error" not in lines[0], err
    for name in names:
        assert str(name) in lines[0], (name, lines[0])
    return lines[0]


# --------------------------------------------------------- the reported messages, named
MOVES = [
    # (mesh, move arguments, the file the line names, what it says)
    ("sphere.obj", ["--map", "x; y; 2*z*z - 0.5"], "sphere.obj",
     "the targets make the surface intersect itself"),
    ("crossing.msh", ["--targets", "nudge.csv"], "crossing.msh",
     "the boundary intersects itself"),
    ("degenerate.obj", ["--where", "x > 0.5", "--map", "x + 0.1; y; z"], "degenerate.obj",
     "reference triangle 0 is degenerate"),
    ("cube.msh", ["--targets", "far.csv"], "cube.msh",
     "no admissible position of the mesh"),
    ("cube.msh", ["--targets", "out_of_range.csv"], "out_of_range.csv",
     "line 1: vertex index 200 is out of range (the mesh has 125 vertices"),
    ("cube.msh", ["--targets", "twice.csv"], "twice.csv",
     "line 2 and line 4 give vertex 5 different targets"),
    ("cube.msh", ["--targets", "not_finite.csv"], "not_finite.csv",
     "line 3: the target of vertex 6 is not finite"),
    ("header_only.msh", ["--map", "x; y"], "header_only.msh", "has no nodes"),
]


@pytest.mark.parametrize("mesh,extra,named,shown", MOVES, ids=[m[3][:24] for m in MOVES])
def test_move_errors_name_the_file(files, tmp_path, capsys, mesh, extra, named, shown):
    extra = [str(files / a) if (files / a).is_file() else a for a in extra]
    out = tmp_path / f"moved{(files / mesh).suffix}"
    assert main(["move", str(files / mesh), "-o", str(out), *extra]) == 1
    line = _one_line(capsys, files / named, shown)
    assert line.startswith(f"meshopt move: error: {files / named}: "), line
    assert not out.exists()


def test_morph_error_from_the_library_names_the_files(files, tmp_path, capsys):
    out = tmp_path / "morph"
    assert main(["morph", str(files / "degenerate.obj"), str(files / "sphere.obj"), "-o",
                 str(out), "--frames", "3", "--no-plots"]) == 1
    _one_line(capsys, files / "degenerate.obj", "reference triangle 0 is degenerate")
    assert not out.exists()


@pytest.mark.parametrize("command", [["info"], ["convert", "-o", "{out}.vtu"],
                                     ["optimize", "--no-plots", "-o", "{out}"]])
def test_a_file_without_nodes_is_one_line_naming_it(files, tmp_path, capsys, command):
    argv = [command[0], str(files / "header_only.msh"),
            *[a.format(out=tmp_path / "out") for a in command[1:]]]
    assert main(argv) == 1
    line = _one_line(capsys, files / "header_only.msh", "has no nodes")
    assert "shape" not in line
    assert not list(tmp_path.iterdir())


# ------------------------------------------------ planar-only commands say what they take
@pytest.mark.parametrize("command,mesh,kind", [  # optimize takes tetrahedra too
    ("optimize", "sphere.obj", "a triangle surface in 3D"),
    ("deform", "cube.msh", "a tetrahedral mesh (384 tetrahedra)"),
    ("deform", "sphere.obj", "a triangle surface in 3D")])
def test_planar_commands_name_what_they_support(files, tmp_path, capsys, command, mesh, kind):
    out = tmp_path / ("out" if command == "optimize" else f"out{(files / mesh).suffix}")
    argv = [command, str(files / mesh), "-o", str(out)]
    argv += ["--no-plots"] if command == "optimize" else ["--displacement", str(files / "v.npy")]
    assert main(argv) == 1
    line = _one_line(capsys)
    takes = ("planar triangle and tetrahedral meshes" if command == "optimize"
             else "planar triangle meshes")
    assert line == (f"meshopt {command}: error: {files / mesh}: {command} supports {takes}; "
                    f"this is {kind}" + ("" if "tetra" in kind else
                                         " (its points are not on one plane)"))
    assert "not planar" not in line and not out.exists()


# ----------------------------------------------- a library message without a file, named
def _commands(d, out) -> dict[str, list[str]]:
    (d / "refine.json").write_text(json.dumps(
        {"filters": [{"name": "meshing_uniform_refinement"}]}))
    disc = str(d / "disc.msh")
    return {
        "move": ["move", disc, "--map", "x; y", "-o", f"{out}.msh"],
        "morph": ["morph", disc, disc, "-o", str(out), "--frames", "3", "--no-plots"],
        "deform": ["deform", disc, "--displacement", str(d / "v.npy"), "-o", f"{out}.msh"],
        "optimize": ["optimize", disc, "-o", str(out), "--no-plots"],
        "info": ["info", disc],
        "convert": ["convert", disc, "-o", f"{out}.vtu"],
        "run": ["run", str(d / "refine.json"), disc, "-o", str(out)],
    }


@pytest.mark.parametrize("exc", [InvalidMeshError("reference triangle 320 is degenerate"),
                                 TypeError("an unexpected bug")])
@pytest.mark.parametrize("command", ["move", "morph", "deform", "optimize", "info",
                                     "convert", "run"])
def test_every_command_names_the_file_of_a_deep_error(files, tmp_path, capsys, monkeypatch,
                                                      command, exc):
    import meshopt_toolkit.io as io

    def fail(*args, **kwargs):
        raise exc

    argv = _commands(files, tmp_path / "out")[command]
    monkeypatch.setattr(io, "load_cells", fail)
    assert main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    lines = [ln for ln in err if ": error: " in ln or "internal error" in ln]
    assert len(lines) == 1 and "Traceback" not in lines[0], err
    assert f"{files / 'disc.msh'}: " in lines[0] and str(exc) in lines[0], lines[0]
    # nothing written (run makes its output folder first: no file in it)
    assert not [p for p in tmp_path.rglob("*") if p.is_file() and not p.name.startswith(".")]


def test_an_option_error_names_the_file(files, tmp_path, capsys):
    assert main(["move", str(files / "disc.msh"), "-o", str(tmp_path / "o.msh"), "--map",
                 "x; y", "--frames", "1"]) == 1
    assert _one_line(capsys).startswith(f"meshopt move: error: {files / 'disc.msh'}: "
                                        "--frames must be between 2 and")


def test_a_message_naming_its_file_is_kept(files, tmp_path, capsys):
    """An existing output is named by the output alone (no input in front)."""
    out = tmp_path / "there.msh"
    out.write_text("mine\n")
    assert main(["move", str(files / "disc.msh"), "-o", str(out), "--map", "x; y"]) == 1
    assert _one_line(capsys) == f"meshopt move: error: {out}: exists (use --force to overwrite)"
    assert out.read_text() == "mine\n"


# ---------------------------------------------------------------- the library's messages
def test_library_handle_checks_name_the_entry():
    from meshopt_toolkit.motion.engine.handles import check_handles, distinct_handles

    with pytest.raises(InvalidMeshError, match=r"handles\[1\] = 200 is out of range "
                                               r"\(the mesh has 125 vertices, 0 to 124\)"):
        check_handles([3, 200], np.zeros((2, 3)), 125)
    with pytest.raises(InvalidMeshError, match=r"targets\[1\] \(of vertex 7\) is not finite"):
        check_handles([3, 7], [[0, 0, 0], [np.nan, 0, 0]], 125)
    with pytest.raises(InvalidMeshError, match="vertex 7 is a handle twice with different"):
        distinct_handles(np.array([7, 3, 7]), np.array([[0, 0, 0], [1, 1, 1], [0, 0, 1.0]]))


def test_tet_move_names_the_files_vertex_of_a_clash():
    """Vertices in no tet are renumbered away before the solve; the clash names the
    vertex as the caller numbers it."""
    import meshopt_toolkit as mt
    from meshopt_toolkit.mesh import TetMesh

    P, T = _cube_tets(3)
    loose = np.vstack([[5.0, 5.0, 5.0], P])  # vertex 0 is in no tet
    mesh = TetMesh(loose, T + 1)
    with pytest.raises(InvalidMeshError, match="vertex 4 is a handle twice"):
        mt.move(mesh, [4, 4], [[0, 0, 0], [0, 0, 1.0]])


def test_control_characters_of_a_name_are_escaped(tmp_path, capsys):
    out = tmp_path / "o.msh"
    assert main(["move", str(tmp_path / "d\x01\x00.msh"), "-o", str(out), "--map", "x; y"]) == 1
    line = _one_line(capsys)
    assert "d\\x01\\x00.msh" in line and line.isprintable()
