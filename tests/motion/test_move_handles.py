"""Which vertices ``meshopt move`` holds: ``--targets`` keeps the boundary it does not list
(``--free-boundary`` frees it), ``--group NAME`` moves a physical group's nodes by
``--map``; the command line, the move filter and ``motion.engine.targets`` agree."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from meshopt_toolkit import data_path
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.io import load
from meshopt_toolkit.motion.engine.targets import fix_boundary, group_vertices, handles_of

DISC = data_path("disc_25.msh")


@pytest.fixture
def disc(tmp_path):
    shutil.copy(DISC, tmp_path / "disc.msh")
    return tmp_path / "disc.msh"


def _interior(mesh) -> np.ndarray:
    return np.setdiff1d(np.arange(mesh.n_vertices), np.unique(mesh.boundary_edges))


def _run_filter(mesh, name: str, **params):
    from meshopt_toolkit.pipeline import Document, Pipeline

    doc = Document()
    doc.add(mesh, name=name)
    Pipeline.from_dict({"filters": [{"name": "apply_coord_prescribed_motion",
                                     "params": params}]}).run(doc)
    return doc.current_entry.mesh


# ------------------------------------------------------------------------ --targets
def test_one_target_moves_that_vertex_and_the_boundary_stays_bitwise(disc, tmp_path):
    mesh = load(disc).as_planar()
    v = int(_interior(mesh)[0])
    target = mesh.points[v] + [0.05, -0.03]
    (tmp_path / "t.csv").write_text(f"index,x,y\n{v},{float(target[0])!r},{float(target[1])!r}\n")
    assert main(["move", str(disc), "-o", str(tmp_path / "m.msh"),
                 "--targets", str(tmp_path / "t.csv")]) == 0
    moved = load(tmp_path / "m.msh").as_planar()
    boundary = np.unique(mesh.boundary_edges)
    assert np.array_equal(moved.points[v], target)
    assert np.array_equal(moved.points[boundary], mesh.points[boundary])
    assert (moved.signed_areas() > 0).all()
    # the filter reads the same table the same way
    via_filter = _run_filter(mesh, "disc", targets=str(tmp_path / "t.csv"))
    assert np.array_equal(via_filter.points, moved.points)


def test_free_boundary_lets_one_target_translate_the_mesh(disc, tmp_path):
    mesh = load(disc).as_planar()
    shift = np.array([0.05, -0.03])
    np.save(tmp_path / "t.npy", np.array([[3, *(mesh.points[3] + shift)]]))
    assert main(["move", str(disc), "-o", str(tmp_path / "m.msh"), "--free-boundary",
                 "--targets", str(tmp_path / "t.npy")]) == 0
    moved = load(tmp_path / "m.msh").as_planar()
    np.testing.assert_allclose(moved.points, mesh.points + shift, atol=1e-12)
    via_filter = _run_filter(mesh, "disc", targets=str(tmp_path / "t.npy"), free_boundary=True)
    assert np.array_equal(via_filter.points, moved.points)


def test_fix_boundary_adds_the_unlisted_boundary_at_its_place():
    mesh = load(DISC).as_planar()
    boundary = np.unique(mesh.boundary_edges)
    listed = np.array([boundary[2], _interior(mesh)[0]])
    targets = np.array([[9.0, 9.0], [8.0, 8.0]])
    handles, positions = fix_boundary(mesh, listed, targets)
    assert len(handles) == len(np.unique(handles)) == len(boundary) + 1
    assert set(handles.tolist()) == set(boundary.tolist()) | set(listed.tolist())
    by_vertex = dict(zip(handles.tolist(), map(tuple, positions)))
    assert by_vertex[int(listed[0])] == (9.0, 9.0) and by_vertex[int(listed[1])] == (8.0, 8.0)
    for b in boundary[boundary != listed[0]]:
        assert by_vertex[int(b)] == tuple(mesh.points[b])


def test_free_boundary_is_for_targets(disc, tmp_path, capsys):
    assert main(["move", str(disc), "-o", str(tmp_path / "m.msh"), "--map", "x; y",
                 "--free-boundary"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--free-boundary is for --targets" in err[0]


# -------------------------------------------------------------------------- --group
@pytest.fixture(scope="module")
def grouped(tmp_path_factory):
    """A gmsh 4.1 annulus with physical groups hole (5), rim (6) and domain (7)."""
    pytest.importorskip("gmsh")
    from meshopt_toolkit.gmsh_session import gmsh_session

    path = tmp_path_factory.mktemp("groups") / "annulus.msh"
    with gmsh_session() as gmsh:
        gmsh.model.add("annulus")
        occ = gmsh.model.occ
        outer, inner = occ.addDisk(0, 0, 0, 1.0, 1.0), occ.addDisk(0, 0, 0, 0.3, 0.3)
        occ.cut([(2, outer)], [(2, inner)])
        occ.synchronize()

        def width(curve):
            x0, _, _, x1, _, _ = gmsh.model.getBoundingBox(1, curve)
            return x1 - x0

        curves = sorted((c for _, c in gmsh.model.getEntities(1)), key=width)
        gmsh.model.addPhysicalGroup(1, [curves[0]], 5, name="hole")
        gmsh.model.addPhysicalGroup(1, [curves[-1]], 6, name="rim")
        gmsh.model.addPhysicalGroup(2, [s for _, s in gmsh.model.getEntities(2)], 7,
                                    name="domain")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.15)
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
    assert path.read_text().startswith("$MeshFormat\n4.1")
    return path


@pytest.mark.parametrize("group", ["hole", "5"])
def test_group_moves_exactly_its_nodes_to_the_map(grouped, tmp_path, group):
    mesh = load(grouped).as_planar()
    r = np.hypot(*mesh.points.T)
    hole = np.flatnonzero(np.isclose(r, 0.3))  # found from the geometry, not the tags
    rim = np.flatnonzero(np.isclose(r, 1.0))
    assert len(hole) >= 8 and len(rim) >= 8
    assert np.array_equal(np.sort(group_vertices(mesh, group)), hole)
    out = tmp_path / "moved.msh"
    assert main(["move", str(grouped), "-o", str(out), "--group", group,
                 "--map", "x + 0.1; 1.5*y"]) == 0
    moved = load(out).as_planar()
    P = mesh.points
    assert np.array_equal(moved.points[hole], np.column_stack([P[hole, 0] + 0.1,
                                                               1.5 * P[hole, 1]]))
    assert np.array_equal(moved.points[rim], P[rim])
    assert (moved.signed_areas() > 0).all()
    assert moved.tag_names == mesh.tag_names  # the groups travel
    via_filter = _run_filter(mesh, "annulus", map="x + 0.1; 1.5*y", group=group)
    assert np.array_equal(via_filter.points, moved.points)


def test_group_with_where_moves_part_of_the_group(grouped, tmp_path):
    mesh = load(grouped).as_planar()
    handles, targets = handles_of(mesh, mapping="x + 0.01; y", where="x > 0", group="hole")
    hole = group_vertices(mesh, "hole")
    moved = handles[np.any(targets != mesh.points[handles], axis=1)]
    assert set(moved.tolist()) == {int(v) for v in hole if mesh.points[v, 0] > 0}
    assert set(handles.tolist()) == set(np.unique(mesh.boundary_edges).tolist())


def test_unknown_group_is_one_line_listing_the_groups(grouped, tmp_path, capsys):
    for group in ("inlet", "9"):
        assert main(["move", str(grouped), "-o", str(tmp_path / "m.msh"), "--group", group,
                     "--map", "x; y"]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "internal error" not in err[0]
        assert err[0] == (f"meshopt move: error: --group '{group}': {grouped} has no such "
                          "physical group; it has: domain (7), hole (5), rim (6)")
    assert not (tmp_path / "m.msh").exists()
    mesh = load(grouped).as_planar()
    with pytest.raises(InvalidMeshError, match=r"it has: domain \(7\), hole \(5\), rim \(6\)"):
        _run_filter(mesh, "annulus", map="x; y", group="inlet")


def test_group_needs_map(disc, tmp_path, capsys):
    np.save(tmp_path / "t.npy", np.zeros((1, 3)))
    assert main(["move", str(disc), "-o", str(tmp_path / "m.msh"), "--group", "hole",
                 "--targets", str(tmp_path / "t.npy")]) == 1
    assert "--group needs --map" in capsys.readouterr().err
