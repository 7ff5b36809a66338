"""Orientation by propagation, planes in 3D, coincident vertices."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit import io
from meshopt_toolkit.cli import main
from meshopt_toolkit.cli.info import mesh_info
from meshopt_toolkit.mesh import PlanarMesh, TriangleMesh, check_mesh, require_admissible
from meshopt_toolkit.orientation import component_labels, orient_components, plane_of


def grid(n: int = 4) -> PlanarMesh:
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    pts = np.column_stack([x.ravel(), y.ravel()])
    tri = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            tri += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    return PlanarMesh(pts, tri)


def cross2(p, t):
    e1, e2 = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    return e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]


def test_scikit_fem_mesh_in_mixed_orientation_is_accepted():
    skfem = pytest.importorskip("skfem")
    m = skfem.MeshTri.init_circle(2)
    pts, tri = m.p.T, m.t.T
    n_cw = int((cross2(pts, tri) < 0).sum())
    assert 0 < n_cw < len(tri)  # really mixed
    report = check_mesh(TriangleMesh(pts, tri))
    assert report.manifold and report.admissible and report.problems == []
    assert report.reoriented and report.n_reoriented == n_cw
    assert (report.mesh.signed_areas() > 0).all()
    assert require_admissible(TriangleMesh(pts, tri)).n_triangles == len(tri)


@settings(max_examples=25, deadline=None)
@given(st.data())
def test_random_flips_are_undone(data):
    g = grid(4)
    flip = np.array(data.draw(st.lists(st.booleans(), min_size=g.n_triangles,
                                       max_size=g.n_triangles)))
    tri = np.where(flip[:, None], g.triangles[:, ::-1], g.triangles)
    report = check_mesh(PlanarMesh(g.points, tri))
    assert report.admissible
    assert report.n_reoriented == (int(flip.sum()) if report.reoriented else 0)
    assert np.array_equal(report.mesh.triangles, g.triangles)


def test_each_component_oriented_and_pieces_are_not_non_manifold():
    g = grid(2)
    shifted = g.points + [3.0, 0.0]
    pts = np.vstack([g.points, shifted])
    tri = np.vstack([g.triangles, g.triangles[:, ::-1] + g.n_vertices])  # second piece CW
    report = check_mesh(PlanarMesh(pts, tri))
    assert report.manifold and not report.admissible
    assert report.n_reoriented == g.n_triangles
    assert report.problems == ["mesh has 2 pieces not connected through edges"]
    assert (report.mesh.signed_areas() > 0).all()


def test_mobius_strip_is_not_orientable():
    # a strip of 5 quads whose ends are glued with a half twist
    n = 5
    top, bottom = list(range(n)), list(range(n, 2 * n))
    tri = []
    for i in range(n):
        a, b = top[i], top[(i + 1) % n]
        c, d = bottom[i], bottom[(i + 1) % n]
        if i == n - 1:
            b, d = d, b  # the twist
        tri += [[a, b, d], [a, d, c]]
    _, _, orientable = orient_components(np.array(tri), 2 * n)
    assert not orientable


def test_bow_tie_is_still_non_manifold():
    pts = [[0, 0], [1, 0], [0, 1], [-1, 0], [0, -1]]
    report = check_mesh(PlanarMesh(pts, [[0, 1, 2], [0, 3, 4]]))
    assert not report.manifold and any("bow-tie" in p for p in report.problems)


def test_mesh_on_the_plane_z_1_is_planar_and_written_back_exactly(tmp_path):
    g = grid(3)
    pts = np.column_stack([g.points, np.ones(g.n_vertices)])
    mesh = TriangleMesh(pts, g.triangles)
    report = check_mesh(mesh)
    assert report.planar and report.admissible
    np.testing.assert_array_equal(report.mesh.points, g.points)  # exact for z = c
    out = io.load(io.save(report.mesh.with_points(report.mesh.points), tmp_path / "m.ply"))
    np.testing.assert_array_equal(out.points, pts)


def test_tilted_plane_is_planar():
    g = grid(3)
    c, s = np.cos(0.7), np.sin(0.7)
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    pts = np.column_stack([g.points, np.zeros(g.n_vertices)]) @ rot.T + [1, 2, 3]
    report = check_mesh(TriangleMesh(pts, g.triangles))
    assert report.planar and report.admissible and not report.reoriented
    np.testing.assert_allclose(report.mesh.signed_areas(), g.signed_areas(), rtol=1e-12)
    back = report.mesh.embedding.to_3d(report.mesh.points)
    np.testing.assert_allclose(back, pts, atol=1e-14)
    bent = pts.copy()
    bent[5] += 1e-3 * np.cross(rot[:, 0], rot[:, 1])
    assert not check_mesh(TriangleMesh(bent, g.triangles)).planar
    assert plane_of(bent)[0] is None


def split_grid() -> PlanarMesh:
    """A 4x4 grid cut along x = 0.5 into two halves that do not share vertices."""
    g = grid(4)
    pts = list(map(list, g.points))
    tri = g.triangles.copy()
    seam = np.flatnonzero(np.isclose(g.points[:, 0], 0.5))
    right = g.points[tri].mean(axis=1)[:, 0] > 0.5
    copy = {}
    for v in seam:
        copy[v] = len(pts)
        pts.append(list(g.points[v]))
    for k in np.flatnonzero(right):
        tri[k] = [copy.get(v, v) for v in tri[k]]
    return PlanarMesh(pts, tri)


def test_coincident_vertices_reported_by_count(tmp_path, capsys):
    m = split_grid()
    report = check_mesh(m)
    assert report.manifold and not report.admissible
    assert report.problems[0].startswith("10 coincident vertices")
    path = io.save(m, tmp_path / "s.msh")
    info = mesh_info(path, merge_tolerance=0.0)
    assert info["admissible"] and info["n_merged"] == 5 and info["n_vertices"] == 25
    assert main(["info", str(path), "--merge-tolerance", "1e-9"]) == 0
    assert "admissible" in capsys.readouterr().out


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 30), st.lists(st.tuples(st.integers(0, 29), st.integers(0, 29)),
                                    max_size=40))
def test_component_labels_agree_with_scipy(n, edges):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.array([(a % n, b % n) for a, b in edges], np.int64).reshape(-1, 2)
    labels = component_labels(n, e[:, 0], e[:, 1])
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    _, ref = connected_components(g, directed=False)
    # same partition, labelled by the smallest member
    for comp in np.unique(ref):
        members = np.flatnonzero(ref == comp)
        assert (labels[members] == members.min()).all()


def test_numpy_and_scipy_paths_of_the_check_agree(monkeypatch):
    import meshopt_toolkit.kernels.boundary as boundary_module
    import meshopt_toolkit.mesh.topology as mesh_module
    from meshopt_toolkit.datasets import data_path

    disc = io.load(data_path("disc_25.msh")).as_planar().refine().refine()
    g = grid(3)
    pieces = PlanarMesh(np.vstack([g.points, g.points + 3]),
                        np.vstack([g.triangles, g.triangles + g.n_vertices]))
    p = g.points.copy()
    p[3] = [0.2, -0.3]  # a boundary vertex pulled across: boundary crossing
    cases = [disc, split_grid(), pieces, g.with_points(p)]
    def run():
        reports = [check_mesh(PlanarMesh(m.points, m.triangles)) for m in cases]
        hits = [{tuple(sorted(h)) for h in boundary_module.boundary_self_intersections(
            r.mesh.points, r.mesh.boundary_edges).tolist()} for r in reports]
        short = [[q.split(":")[0] for q in r.problems] for r in reports]
        return reports, hits, short

    fast, fast_hits, fast_problems = run()
    monkeypatch.setattr(mesh_module, "_NUMPY_CONNECTIVITY", -1)
    monkeypatch.setattr(boundary_module, "_NUMPY_PAIRS", -1)
    slow, slow_hits, slow_problems = run()
    assert fast_hits == slow_hits and fast_problems == slow_problems
    for a, b in zip(fast, slow):
        assert (a.manifold, a.admissible) == (b.manifold, b.admissible)
    assert [r.admissible for r in fast] == [True, False, False, False]
