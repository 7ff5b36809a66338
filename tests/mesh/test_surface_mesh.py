"""Triangle surfaces in 3D: kernels against closed forms, SurfaceMesh topology against
trimesh's, round trips through the surface formats, trimesh/pymeshlab, meshopt info."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from meshopt_toolkit.cli import main
from meshopt_toolkit.conversions import (surface_from_pymeshlab, surface_from_trimesh,
                                         to_pymeshlab, to_trimesh)
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.io import CellMesh, load, load_cells, save_cells
from meshopt_toolkit.kernels import triangles as planar
from meshopt_toolkit.kernels.surface import (areas, aspect_ratios, degenerate_triangles,
                                             unit_normals)
from meshopt_toolkit.mesh import PlanarMesh, SurfaceMesh

EQUILATERAL = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0]])


def sphere(subdivisions: int = 2) -> SurfaceMesh:
    s = trimesh.creation.icosphere(subdivisions)
    return SurfaceMesh(s.vertices, s.faces)


# ----------------------------------------------------------------------------- kernels
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(1e-3, 1e3))
def test_equilateral_in_a_random_plane(seed, scale):
    r = np.random.default_rng(seed)
    rot = Rotation.from_quat(r.normal(size=4)).as_matrix()
    pts = scale * EQUILATERAL @ rot.T + r.normal(size=3)
    tri = np.array([[0, 1, 2]])
    assert aspect_ratios(pts, tri)[0] == pytest.approx(1.0, rel=1e-9)
    assert areas(pts, tri)[0] == pytest.approx(np.sqrt(3) / 4 * scale**2, rel=1e-9)
    n = unit_normals(pts, tri)[0]
    assert np.linalg.norm(n) == pytest.approx(1.0)
    np.testing.assert_allclose(n, rot[:, 2], atol=1e-9)  # right-hand rule: rotated e_z


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_aspect_ratio_is_the_planar_one(seed):
    r = np.random.default_rng(seed)
    pts2 = r.normal(size=(30, 2))
    tri = np.array([r.choice(30, 3, replace=False) for _ in range(20)])
    ccw = planar.signed_areas(pts2, tri) > 0
    tri[~ccw] = tri[~ccw][:, ::-1]
    rot = Rotation.from_quat(r.normal(size=4)).as_matrix()
    pts3 = np.column_stack([pts2, np.zeros(30)]) @ rot.T
    np.testing.assert_allclose(aspect_ratios(pts3, tri), planar.aspect_ratios(pts2, tri),
                               rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(areas(pts3, tri), planar.signed_areas(pts2, tri),
                               rtol=1e-9, atol=1e-14)


def test_right_triangle_closed_forms():
    pts = np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0.0]])
    tri = np.array([[0, 1, 2]])
    # r = (3 + 4 − 5)/2 = 1, R = 5/2: 2r/R = 4/5
    assert aspect_ratios(pts, tri)[0] == pytest.approx(0.8, rel=1e-15)
    assert areas(pts, tri)[0] == 6.0


def test_degenerate_triangles():
    pts = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 1], [1, 1, 1 + 1e-17]])
    tri = np.array([[0, 1, 3], [0, 1, 2], [0, 0, 3], [3, 4, 0]])
    np.testing.assert_array_equal(degenerate_triangles(pts, tri), [1, 2])
    assert aspect_ratios(pts, tri)[1] == 0.0
    np.testing.assert_array_equal(unit_normals(pts, tri)[2], [0, 0, 0])


# ----------------------------------------------------------------------------- topology
def test_icosphere_is_a_closed_oriented_sphere():
    m = sphere(3)
    assert m.is_closed and m.is_manifold and m.is_orientable and m.is_oriented
    assert m.n_components == 1 and list(m.euler_characteristics) == [2] and m.genera == [0]
    assert m.problems == [] and m.require_valid() is m
    t = trimesh.Trimesh(m.points, m.triangles, process=False)
    assert t.is_watertight and t.is_winding_consistent and t.euler_number == 2
    assert m.enclosed_volume() == pytest.approx(t.volume, rel=1e-12) and t.volume > 0


def test_torus_has_genus_one():
    t = trimesh.creation.torus(1.0, 0.3)
    m = surface_from_trimesh(t)
    assert m.is_closed and m.is_manifold and m.genera == [1]
    assert list(m.euler_characteristics) == [t.euler_number] == [0]


def test_open_surface_loops_and_components():
    s = sphere(2)
    z = s.points[s.triangles].mean(axis=1)[:, 2]
    band = s.triangles[np.abs(z) < 0.5]  # a band: two boundary loops
    m = SurfaceMesh(s.points, band)
    assert not m.is_closed and m.n_boundary_loops == 2 and m.genera == [0]
    assert list(m.euler_characteristics) == [0]
    # and a second, disjoint cap: components are counted apart
    cap = s.triangles[z > 0.8]
    two = SurfaceMesh(s.points, np.vstack([band, cap]))
    assert two.n_components == 2 and two.genera == [0, 0]
    assert list(two.boundary_loops_per_component) == [2, 1]
    t = trimesh.Trimesh(s.points, band, process=False)
    assert not t.is_watertight


def test_flipped_triangle_is_reported_and_fixed():
    s = sphere(1)
    tri = s.triangles.copy()
    tri[5] = tri[5, ::-1]
    m = SurfaceMesh(s.points, tri)
    assert m.is_orientable and not m.is_oriented
    assert any("not consistently oriented" in p for p in m.problems)
    fixed = m.consistently_oriented()
    assert fixed.is_oriented
    np.testing.assert_array_equal(fixed.triangles, s.triangles)


def test_moebius_strip_is_not_orientable():
    n = 12
    u = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = []
    for a in u:
        for w in (-0.3, 0.3):
            pts.append([(1 + w * np.cos(a / 2)) * np.cos(a), (1 + w * np.cos(a / 2)) * np.sin(a),
                        w * np.sin(a / 2)])
    tri = []
    for i in range(n):
        a, b = 2 * i, 2 * i + 1
        c, d = (2 * (i + 1), 2 * (i + 1) + 1) if i < n - 1 else (1, 0)  # the half twist
        tri += [[a, c, b], [b, c, d]]
    m = SurfaceMesh(np.array(pts), np.array(tri))
    assert m.is_manifold and not m.is_orientable and m.genera == [None]
    assert m.n_boundary_loops == 1 and list(m.euler_characteristics) == [0]
    assert any("not orientable" in p for p in m.problems)


def test_non_manifold_edge_and_vertex():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [1, 1, 1],
                    [2, 2, 1], [1, 2, 2]])
    # three triangles on edge (0, 1)
    fin = SurfaceMesh(pts, [[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert not fin.is_edge_manifold and fin.non_manifold_edges.tolist() == [[0, 1]]
    # two triangles touching at vertex 5 only (a bowtie)
    bowtie = SurfaceMesh(pts, [[0, 1, 5], [5, 6, 7]])
    assert bowtie.is_edge_manifold and not bowtie.is_vertex_manifold
    assert bowtie.non_manifold_vertices.tolist() == [5] and bowtie.genera == [None]
    assert any("non-manifold vertices" in p for p in bowtie.problems)


def test_degenerate_triangle_is_a_problem():
    pts = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 1]])
    m = SurfaceMesh(pts, [[0, 1, 3], [0, 2, 1]], source="d.obj")
    assert m.degenerate_triangles.tolist() == [1]
    with pytest.raises(InvalidMeshError, match=r"d\.obj: 1 degenerate triangles: 1"):
        m.require_valid()


# ----------------------------------------------------------------------------- files
def tagged_sphere() -> SurfaceMesh:
    s = sphere(2)
    tags = np.where(s.points[s.triangles].mean(axis=1)[:, 2] > 0, 1, 2)
    return SurfaceMesh(s.points, s.triangles, triangle_tags=tags,
                       tag_names={"north": (1, 2), "south": (2, 2)})


@pytest.mark.parametrize("ext,binary", [(".obj", None), (".off", None), (".ply", True),
                                        (".ply", False), (".vtu", True), (".vtu", False),
                                        (".vtk", True), (".msh", True), (".msh", False),
                                        (".mesh", None)])
def test_surface_round_trip_is_exact(tmp_path, ext, binary):
    m = sphere(2)
    path = save_cells(CellMesh.from_triangle_mesh(m), tmp_path / f"s{ext}", binary=binary)
    back = load_cells(path).to_surface_mesh()
    assert back.points.tobytes() == m.points.tobytes()
    np.testing.assert_array_equal(back.triangles, m.triangles)


@pytest.mark.parametrize("name", ["t.msh", "t.vtu", "t.mesh"])
def test_surface_tags_round_trip(tmp_path, name):
    m = tagged_sphere()
    save_cells(CellMesh.from_triangle_mesh(m), tmp_path / name)
    back = load_cells(tmp_path / name).to_surface_mesh()
    assert back.points.tobytes() == m.points.tobytes()
    np.testing.assert_array_equal(back.triangle_tags, m.triangle_tags)
    assert back.tag_names == m.tag_names


@pytest.mark.parametrize("binary", [True, False])
def test_stl_keeps_the_triangles_as_sets(tmp_path, binary):
    # binary STL stores float32 corners (ASCII ours: exact), and the reader merges and sorts
    # them: compare the sets of triangles, each as its three corners in order
    m = sphere(2)
    save_cells(CellMesh.from_triangle_mesh(m), tmp_path / "s.stl", binary=binary)
    back = load_cells(tmp_path / "s.stl").to_surface_mesh()
    corners = lambda p, t: {tuple(map(tuple, p[k])) for k in t}  # noqa: E731
    stored = m.points.astype(np.float32).astype(np.float64) if binary else m.points
    assert corners(back.points, back.triangles) == corners(stored, m.triangles)
    assert back.is_closed and back.genera == [0]


def test_convert_cli_and_planar_loads_unchanged(tmp_path):
    m = sphere(1)
    save_cells(CellMesh.from_triangle_mesh(m), tmp_path / "s.ply")
    for out in ("s.obj", "s.off", "s.vtu", "s.msh"):
        assert main(["convert", str(tmp_path / "s.ply"), "-o", str(tmp_path / out)]) == 0
        assert load_cells(tmp_path / out).points.tobytes() == m.points.tobytes()
    # a planar file still loads as a PlanarMesh; its surface keeps z = 0
    flat = PlanarMesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]])
    save_cells(CellMesh.from_triangle_mesh(flat), tmp_path / "f.obj")
    assert isinstance(load(tmp_path / "f.obj"), PlanarMesh)
    s = load_cells(tmp_path / "f.obj").to_surface_mesh()
    assert s.points.shape == (3, 3) and not s.points[:, 2].any()


def test_trimesh_and_pymeshlab_round_trips_are_bitwise():
    import pymeshlab

    m = SurfaceMesh(*(lambda t: (t.vertices + 1e-3 * np.sin(t.vertices * 7), t.faces))(
        trimesh.creation.icosphere(2)))
    t = to_trimesh(m)
    assert surface_from_trimesh(t).points.tobytes() == m.points.tobytes()
    np.testing.assert_array_equal(surface_from_trimesh(t).triangles, m.triangles)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(to_pymeshlab(m))
    back = surface_from_pymeshlab(ms.current_mesh())
    assert back.points.tobytes() == m.points.tobytes()
    np.testing.assert_array_equal(back.triangles, m.triangles)
    # pymeshlab's topology agrees
    top = ms.get_topological_measures()
    assert top["is_mesh_two_manifold"] and top["genus"] == 0
    assert top["boundary_edges"] == len(m.boundary_edges) == 0


# ----------------------------------------------------------------------------- info
def test_info_on_icosphere_and_open_surface(tmp_path, capsys):
    trimesh.creation.icosphere(3).export(tmp_path / "ico.obj")
    assert main(["info", "--json", str(tmp_path / "ico.obj")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["cell_kind"] == "surface triangles"
    assert info["closed"] and info["manifold"] and info["oriented"] and info["genus"] == [0]
    assert info["boundary_loops"] == 0 and info["problems"] == []
    assert 0.9 < info["min_aspect_ratio"] <= info["mean_aspect_ratio"] <= 1
    s = sphere(2)
    z = s.points[s.triangles].mean(axis=1)[:, 2]
    save_cells(CellMesh(s.points, [("triangle", s.triangles[z < 0.5])]), tmp_path / "open.ply")
    assert main(["info", str(tmp_path / "open.ply")]) == 0
    out = capsys.readouterr().out
    assert "closed                no" in out and "boundary loops        1" in out
    assert "genus                 0" in out and "manifold              yes" in out


def test_info_merges_a_triangle_soup(tmp_path, capsys):
    s = sphere(2)
    soup = CellMesh(s.points[s.triangles].reshape(-1, 3),
                    [("triangle", np.arange(3 * s.n_triangles).reshape(-1, 3))])
    save_cells(soup, tmp_path / "soup.ply")
    assert main(["info", "--json", str(tmp_path / "soup.ply")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert not info["closed"] and info["components"] == s.n_triangles
    assert main(["info", "--json", "--merge-tolerance", "0", str(tmp_path / "soup.ply")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["n_merged"] == 3 * s.n_triangles - s.n_vertices
    assert info["closed"] and info["manifold"] and info["genus"] == [0]
    assert info["n_vertices"] == s.n_vertices


def test_info_planar_file_says_planar(tmp_path, capsys):
    flat = PlanarMesh([[0, 0], [1, 0], [0, 1], [1, 1]], [[0, 1, 2], [1, 3, 2]])
    save_cells(CellMesh.from_triangle_mesh(flat), tmp_path / "f.obj")
    assert main(["info", "--json", str(tmp_path / "f.obj")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["cell_kind"] == "planar triangles" and info["planar"] and info["admissible"]


def test_info_reads_a_format_with_a_triangle_reader_only(tmp_path, monkeypatch, capsys):
    from meshopt_toolkit import io

    flat = PlanarMesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]])
    monkeypatch.setitem(io.READERS, ".tri1", lambda path: flat)
    (tmp_path / "a.tri1").write_text("anything")
    assert main(["info", "--json", str(tmp_path / "a.tri1")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["cell_kind"] == "planar triangles" and info["n_triangles"] == 1


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), keep=st.floats(0.3, 1.0), torus=st.booleans())
def test_topology_agrees_with_meshlab_on_random_pieces(seed, keep, torus):
    # pieces of a closed sphere or torus, vertices renumbered, some triangles flipped:
    # MeshLab's topological measures are the reference
    import pymeshlab

    r = np.random.default_rng(seed)
    t = trimesh.creation.torus(1.0, 0.4, 16, 8) if torus else trimesh.creation.icosphere(1)
    perm = r.permutation(len(t.vertices))
    inverse = np.argsort(perm)
    pts = np.asarray(t.vertices)[perm]
    tri = inverse[np.asarray(t.faces)][r.random(len(t.faces)) < keep]
    if not len(tri):
        return
    flip = r.random(len(tri)) < 0.3
    tri[flip] = tri[flip][:, ::-1]
    m = SurfaceMesh(pts, tri)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(pts, tri.astype(np.int32)))
    top = ms.get_topological_measures()
    assert len(m.boundary_edges) == top["boundary_edges"]
    assert len(m.edges) == top["edges_number"]
    assert len(m.non_manifold_vertices) == top["non_two_manifold_vertices"]
    assert m.is_manifold == top["is_mesh_two_manifold"]
    assert m.is_orientable  # a piece of an orientable surface, whatever its triangles' order
    # consistently oriented iff no directed edge is used twice
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    assert m.is_oriented == (len(np.unique(directed, axis=0)) == len(directed))
    if m.is_manifold:
        assert m.n_components == top["connected_components_number"]
        assert m.n_boundary_loops == top["number_holes"]
        assert sum(m.genera) == top["genus"]
    fixed = m.consistently_oriented()
    assert fixed.is_oriented and fixed.is_orientable
