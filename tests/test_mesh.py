"""The mesh model (SPEC §1): validation, check_mesh, refinement, topology, immutability."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import grid_mesh, square5

from meshopt_toolkit.errors import InvalidMeshError, NotAdmissibleError
from meshopt_toolkit.geometry import inverse_shape_quality, signed_areas
from meshopt_toolkit.mesh import (
    PlanarMesh,
    TriangleMesh,
    boundary_self_intersections,
    check_mesh,
    require_admissible,
)

SQ_PTS = [[-1, -1], [1, -1], [1, 1], [-1, 1], [0, 0]]
SQ_TRI = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]


def compact(points, triangles) -> PlanarMesh:
    """Drop unused vertices and renumber."""
    used = np.unique(triangles)
    new = np.full(len(points), -1)
    new[used] = np.arange(len(used))
    return PlanarMesh(np.asarray(points)[used], new[triangles])


def disc25() -> PlanarMesh:
    from meshopt_toolkit.datasets import data_path
    from meshopt_toolkit.io import load

    return load(data_path("disc_25.msh")).as_planar()


# -- construction-time validation -------------------------------------------------------


@pytest.mark.parametrize(
    "points, triangles, match",
    [
        ([[0, 0], [1, np.nan], [0, 1]], [[0, 1, 2]], r"vertex 1 has a non-finite"),
        ([[0, 0], [1, 0], [np.inf, 1]], [[0, 1, 2]], r"vertex 2 has a non-finite"),
        ([[0, 0], [1, 0], [0, 1]], [[0, 1, 3]], r"triangle 0 \[0, 1, 3\].*out of range"),
        ([[0, 0], [1, 0], [0, 1]], [[0, 1, 2], [0, -1, 2]], r"triangle 1 .*out of range"),
        ([0, 1, 2, 3], [[0, 1, 2]], r"points must have shape"),
        ([[0, 0, 0, 0]] * 3, [[0, 1, 2]], r"points must have shape"),
        ([[0, 0], [1, 0], [0, 1]], [0, 1, 2], r"triangles must have shape"),
        ([[0, 0], [1, 0], [0, 1], [1, 1]], [[0, 1, 2, 3]], r"triangles must have shape"),
        ([[0, 0], [1, 0], [0, 1]], np.zeros((0, 3), int), r"no triangles"),
        ([[0, 0], [1, 0], [0, 1]], [[0, 1.5, 2]], r"must be integers"),
        ([[0, 0], [1, 0], [0, 1]], [[0, np.nan, 2]], r"must be integers"),
    ],
)
@pytest.mark.parametrize("cls", [TriangleMesh, PlanarMesh])
def test_readable_validation(cls, points, triangles, match):
    with pytest.raises(InvalidMeshError, match=match):
        cls(points, triangles)


def test_integer_valued_float_indices_are_accepted():
    m = PlanarMesh([[0, 0], [1, 0], [0, 1]], [[0.0, 1.0, 2.0]])
    assert m.triangles.dtype == np.int64


def test_error_names_the_source_file():
    with pytest.raises(InvalidMeshError, match=r"^foo\.msh: "):
        TriangleMesh([[0, 0], [1, 0]], [[0, 1, 2]], source="foo.msh")


def test_tag_validation():
    with pytest.raises(InvalidMeshError, match="triangle_tags"):
        PlanarMesh(SQ_PTS, SQ_TRI, triangle_tags=[1, 2])
    with pytest.raises(InvalidMeshError, match="line_tags"):
        PlanarMesh(SQ_PTS, SQ_TRI, lines=[[0, 1], [1, 2]], line_tags=[1])
    with pytest.raises(InvalidMeshError, match="line element"):
        PlanarMesh(SQ_PTS, SQ_TRI, lines=[[0, 7]], line_tags=[1])


def test_planar_mesh_rejects_nonzero_z_and_accepts_zero_z():
    with pytest.raises(InvalidMeshError, match=r"not planar: vertex 2 has z = 0\.5"):
        PlanarMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0.5]], [[0, 1, 2]])
    m = PlanarMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    assert m.points.shape == (3, 2)
    t = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0.5]], [[0, 1, 2]])
    assert not t.is_planar
    with pytest.raises(InvalidMeshError, match="not planar"):
        t.as_planar()
    assert TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).as_planar().dim == 2


# -- check_mesh: every problem, each naming the element ----------------------------------


def _problem(points, triangles):
    report = check_mesh(TriangleMesh(points, triangles))
    assert not report.admissible
    return report


def test_square_is_admissible(square):
    r = check_mesh(square)
    assert r.planar and r.manifold and r.admissible and not r.reoriented
    assert r.problems == [] and r.mesh == square


def test_non_planar_is_reported():
    r = check_mesh(TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 1e-3]], [[0, 1, 2]]))
    assert not r.planar and not r.manifold and "not planar" in r.problems[0]


def test_unused_vertex():
    r = _problem(SQ_PTS + [[5, 5]], SQ_TRI)
    assert not r.manifold
    assert "vertex 5 is not used" in r.problems[0]


def test_repeated_vertex_in_a_triangle():
    r = _problem(SQ_PTS, SQ_TRI + [[0, 0, 1]])
    assert "triangle 4 [0, 0, 1] repeats a vertex" in r.problems[0]


def test_edge_in_three_triangles():
    pts = SQ_PTS + [[0, -2], [0.5, -3]]
    r = _problem(pts, SQ_TRI + [[1, 0, 5], [0, 1, 6]])
    assert "edge (0, 1) is shared by 3 triangles" in r.problems[0]


def test_inconsistent_orientation():
    tri = [list(t) for t in SQ_TRI]
    tri[2] = tri[2][::-1]
    r = _problem(SQ_PTS, tri)
    assert not r.manifold
    assert "inconsistent orientation" in r.problems[0]
    assert any(f"({a}, {b})" in r.problems[0] for a, b in [(2, 4), (3, 4)])


def test_disconnected_pieces():
    pts = [[0, 0], [1, 0], [0, 1], [5, 0], [6, 0], [5, 1]]
    r = _problem(pts, [[0, 1, 2], [3, 4, 5]])
    assert "2 pieces not connected through edges" in " ".join(r.problems)


def test_bow_tie_in_an_otherwise_edge_connected_mesh():
    # 3×3 cells without the centre and the top-right cell: a ring of cells in which the
    # top-middle and middle-right cells touch only at grid vertex (2, 2)
    g = grid_mesh(3)
    n = 3
    cells = np.arange(n * n)
    keep = ~np.isin(cells, [4, 8])
    tri = np.concatenate([g.triangles[: n * n][keep], g.triangles[n * n :][keep]])
    m = compact(g.points, tri)
    r = check_mesh(m)
    assert not r.manifold
    pinch = int(np.flatnonzero((m.points == [2 / 3, 2 / 3]).all(1))[0])
    assert r.problems == [f"vertex {pinch} is a bow-tie: its triangles form 2 separate fans"]


def test_bow_tie_of_two_lone_triangles():
    pts = [[0, 0], [1, 0], [0, 1], [-1, 0], [0, -1]]
    r = _problem(pts, [[0, 1, 2], [0, 3, 4]])
    assert any("vertex 0 is a bow-tie" in p for p in r.problems)


def test_bow_tie_of_an_interior_fan_and_a_loose_triangle():
    # the full fan around the centre of the square plus a triangle hanging off it
    pts = SQ_PTS + [[3, 0], [3, 1]]
    r = _problem(pts, SQ_TRI + [[4, 5, 6]])
    assert any("vertex 4 is a bow-tie: its triangles form 2 separate fans" in p for p in r.problems)


def test_clockwise_mesh_is_reoriented():
    cw = PlanarMesh(SQ_PTS, np.array(SQ_TRI)[:, ::-1])
    r = check_mesh(cw)
    assert r.admissible and r.reoriented and r.problems == []
    assert np.all(signed_areas(r.mesh.points, r.mesh.triangles) > 0)
    np.testing.assert_array_equal(r.mesh.triangles, cw.triangles[:, ::-1])
    assert require_admissible(cw) == r.mesh


def test_inverted_triangle():
    g = grid_mesh(4)
    p = g.points.copy()
    p[6] = [0.6, 0.6]  # an interior vertex pushed across its neighbours
    r = check_mesh(g.with_points(p))
    assert r.manifold and not r.admissible and not r.reoriented
    bad = np.flatnonzero(signed_areas(p, g.triangles) <= 0)
    k = bad[0]
    assert r.problems[0].startswith(f"triangle {k} {g.triangles[k].tolist()} is inverted")
    assert f"{bad.size} non-positive triangles" in r.problems[0]
    with pytest.raises(NotAdmissibleError, match=f"triangle {k} "):
        require_admissible(g.with_points(p), "the test")


def test_zero_area_triangle():
    p = np.array(SQ_PTS, float)
    p[4] = [0.0, -1.0]  # the centre onto the bottom edge: triangle 0 collapses
    r = check_mesh(PlanarMesh(p, SQ_TRI))
    assert r.manifold and not r.admissible
    assert r.problems == ["triangle 0 [0, 1, 4] is zero-area (signed area 0)"]


def folded_strip(turns=1.25, n=40, width=0.5, pitch=0.1) -> PlanarMesh:
    """A strip of quads along a spiral that overlaps itself after one turn."""
    th = np.linspace(0, 2 * np.pi * turns, n + 1)
    r_in = 1 + pitch * th / (2 * np.pi)
    inner = np.stack([r_in * np.cos(th), r_in * np.sin(th)], 1)
    outer = np.stack([(r_in + width) * np.cos(th), (r_in + width) * np.sin(th)], 1)
    pts = np.vstack([inner, outer])
    i = np.arange(n)
    o = i + n + 1
    tri = np.concatenate([np.stack([i, o + 1, i + 1], 1), np.stack([i, o, o + 1], 1)])
    return PlanarMesh(pts, tri)


def test_boundary_self_intersection_with_positive_areas():
    m = folded_strip()
    assert np.all(m.signed_areas() > 0)
    r = check_mesh(m)
    assert r.manifold and not r.admissible
    assert len(r.problems) == 1 and r.problems[0].startswith("boundary self-intersects: edges (")
    hits = boundary_self_intersections(m.points, m.boundary_edges)
    assert len(hits) > 0
    # every reported pair really crosses (independent check: parametric intersection)
    for i, j in hits:
        a, b = m.points[m.boundary_edges[i]]
        c, d = m.points[m.boundary_edges[j]]
        M = np.column_stack([b - a, c - d])
        s, t = np.linalg.solve(M, c - a)
        assert -1e-12 <= s <= 1 + 1e-12 and -1e-12 <= t <= 1 + 1e-12
    # less than a full turn: no overlap
    assert check_mesh(folded_strip(turns=0.9)).admissible


def test_boundary_self_intersections_brute_force(rng):
    # random segments: compare with an all-pairs test
    pts = rng.uniform(0, 1, (40, 2))
    edges = rng.permutation(40).reshape(20, 2)
    got = {tuple(sorted(p)) for p in boundary_self_intersections(pts, edges).tolist()}

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    want = set()
    for i in range(20):
        for j in range(i + 1, 20):
            a, b = pts[edges[i]]
            c, d = pts[edges[j]]
            if cross(a, b, c) * cross(a, b, d) < 0 and cross(c, d, a) * cross(c, d, b) < 0:
                want.add((i, j))
    assert got == want


# -- refinement ---------------------------------------------------------------------------


def dyadic_mesh(seed=0) -> PlanarMesh:
    """Jittered 4×4 grid with integer coordinates: every refinement area is exact."""
    g = grid_mesh(4)
    r = np.random.default_rng(seed)
    p = g.points * 64  # cells of 16 × 16, vertices moved by at most 3
    inner = (g.points > 0).all(1) & (g.points < 1).all(1)
    p[inner] += r.integers(-3, 4, (inner.sum(), 2))
    return g.with_points(p)


def test_refine_counts_and_exact_areas():
    m = dyadic_mesh()
    f = m.refine()
    assert f.n_vertices == m.n_vertices + len(m.edges)
    assert f.n_triangles == 4 * m.n_triangles
    np.testing.assert_array_equal(f.points[: m.n_vertices], m.points)
    mid = 0.5 * (m.points[m.edges[:, 0]] + m.points[m.edges[:, 1]])
    np.testing.assert_array_equal(f.points[m.n_vertices :], mid)
    a, af = m.signed_areas(), f.signed_areas()
    assert af.sum() == a.sum()
    np.testing.assert_array_equal(af.reshape(-1, 4).sum(axis=1), a)
    np.testing.assert_array_equal(af.reshape(-1, 4), np.repeat(a[:, None] / 4, 4, axis=1))
    assert check_mesh(f).admissible


def test_refine_children_keep_their_parents_orientation():
    m = dyadic_mesh(1)
    tri = m.triangles.copy()
    tri[::3] = tri[::3, ::-1]  # mixed orientation (refine does not need a manifold)
    mixed = PlanarMesh(m.points, tri)
    a, af = mixed.signed_areas(), mixed.refine().signed_areas()
    np.testing.assert_array_equal(np.sign(af).reshape(-1, 4), np.repeat(np.sign(a)[:, None], 4, 1))


def test_refine_equilateral_children_are_equilateral():
    m = PlanarMesh([[0, 0], [2, 0], [1, math.sqrt(3)]], [[0, 1, 2]])
    f = m.refine()
    np.testing.assert_allclose(inverse_shape_quality(f.points, f.triangles), 1.0, rtol=1e-14)
    np.testing.assert_allclose(
        inverse_shape_quality(f.refine().points, f.refine().triangles), 1.0, rtol=1e-14
    )


def test_refine_inherits_tags():
    g = grid_mesh(3)
    b = g.boundary_edges
    ttags = np.arange(g.n_triangles) % 2 + 1
    ltags = np.where((g.points[b, 1] == 0).all(1), 3, 4)  # bottom edges tagged 3
    m = PlanarMesh(
        g.points,
        g.triangles,
        triangle_tags=ttags,
        lines=b,
        line_tags=ltags,
        tag_names={"even": (1, 2), "odd": (2, 2), "bottom": (3, 1), "rest": (4, 1)},
    )
    f = m.refine()
    np.testing.assert_array_equal(f.triangle_tags, np.repeat(ttags, 4))
    assert len(f.lines) == 2 * len(b)
    np.testing.assert_array_equal(f.line_tags, np.repeat(ltags, 2))
    halves = f.lines.reshape(-1, 2, 2)
    np.testing.assert_array_equal(halves[:, 0, 0], b[:, 0])
    np.testing.assert_array_equal(halves[:, 1, 1], b[:, 1])
    np.testing.assert_array_equal(halves[:, 0, 1], halves[:, 1, 0])
    np.testing.assert_allclose(
        f.points[halves[:, 0, 1]], 0.5 * (g.points[b[:, 0]] + g.points[b[:, 1]])
    )
    assert f.tag_names == m.tag_names
    bottom = f.tagged_vertices("bottom")
    assert np.all(f.points[bottom, 1] == 0) and len(bottom) == 2 * 3 + 1
    # the refined boundary lines are exactly the refined mesh's boundary
    assert set(map(tuple, f.lines.tolist())) == set(map(tuple, f.boundary_edges.tolist()))


def test_tagged_vertices_errors(square):
    with pytest.raises(InvalidMeshError, match="no physical group named 'wall'"):
        square.tagged_vertices("wall")
    with pytest.raises(InvalidMeshError, match="no element carries physical tag 7"):
        square.tagged_vertices(7)


# -- with_points and immutability -----------------------------------------------------------


def test_with_points_keeps_topology(square):
    edges = square.edges  # computed and cached before moving
    q = square.points * 2.0
    m = square.with_points(q)
    np.testing.assert_array_equal(m.points, q)
    np.testing.assert_array_equal(m.triangles, square.triangles)
    np.testing.assert_array_equal(m.edges, edges)
    np.testing.assert_array_equal(m.boundary_edges, square.boundary_edges)
    assert m.signed_areas().sum() == 4 * square.signed_areas().sum()
    assert square.points[0, 0] == -1  # the original is untouched
    q[0] = 99.0
    assert m.points[0, 0] == -2  # and the new mesh owns a copy


@pytest.mark.parametrize("shape", [(5, 3), (4, 2), (10,), (5, 1)])
def test_with_points_rejects_wrong_shapes(square, shape):
    with pytest.raises(InvalidMeshError, match="new points have shape"):
        square.with_points(np.zeros(shape))


def test_with_points_rejects_non_finite(square):
    q = square.points.copy()
    q[3, 1] = np.nan
    with pytest.raises(InvalidMeshError, match="vertex 3 has a non-finite"):
        square.with_points(q)


def test_arrays_are_read_only(square):
    m = square.refine()
    for arr in [
        m.points,
        m.triangles,
        m.edges,
        m.triangle_edges,
        m.edge_triangle_counts,
        m.boundary_edges,
        m.boundary_vertices,
    ]:
        assert not arr.flags.writeable
        with pytest.raises(ValueError):
            arr[0] = 0
    pts = np.array(SQ_PTS, float)
    m = PlanarMesh(pts, SQ_TRI)
    pts[0] = 7.0
    assert m.points[0, 0] == -1.0  # construction copies


# -- topology --------------------------------------------------------------------------------


def _left_of(m: PlanarMesh) -> np.ndarray:
    """For each boundary edge, cross(edge, centroid - start) of the triangle owning it."""
    b = m.boundary_edges
    out = np.empty(len(b))
    for k, (i, j) in enumerate(b):
        t = np.flatnonzero((m.triangles == i).any(1) & (m.triangles == j).any(1))
        assert len(t) == 1
        c = m.points[m.triangles[t[0]]].mean(axis=0)
        e, d = m.points[j] - m.points[i], c - m.points[i]
        out[k] = e[0] * d[1] - e[1] * d[0]
    return out


def test_square_topology(square):
    assert len(square.edges) == 8
    assert np.all(square.edges[:, 0] < square.edges[:, 1])
    assert sorted(map(tuple, square.boundary_edges.tolist())) == [(0, 1), (1, 2), (2, 3), (3, 0)]
    np.testing.assert_array_equal(square.boundary_vertices, [0, 1, 2, 3])
    np.testing.assert_array_equal(square.edge_triangle_counts[square.triangle_edges][0], [2, 2, 1])
    deg = np.asarray(square.vertex_adjacency.sum(axis=1)).ravel()
    np.testing.assert_array_equal(deg, [3, 3, 3, 3, 4])
    adj = square.triangle_adjacency.toarray()
    np.testing.assert_array_equal(adj, adj.T)
    np.testing.assert_array_equal(adj.sum(axis=1), [2, 2, 2, 2])
    assert not adj.diagonal().any()
    vt = square.vertex_triangles.toarray()
    np.testing.assert_array_equal(vt.sum(axis=1), [2, 2, 2, 2, 4])
    # triangle_edges: edge l of triangle k joins its vertices l+1 and l+2
    for k, t in enumerate(square.triangles):
        for l in range(3):
            e = square.edges[square.triangle_edges[k, l]]
            assert sorted(e) == sorted([t[(l + 1) % 3], t[(l + 2) % 3]])


@pytest.mark.parametrize("levels", [0, 1, 2])
def test_refined_disc_topology(levels):
    m = disc25()
    for _ in range(levels):
        m = m.refine()
    V, E, T = m.n_vertices, len(m.edges), m.n_triangles
    assert V - E + T == 1  # Euler characteristic of a disc
    assert np.all(_left_of(m) > 0)  # boundary edges CCW: interior on the left
    assert len(m.boundary_edges) == 16 * 2**levels
    assert len(m.boundary_vertices) == len(m.boundary_edges)
    np.testing.assert_allclose(np.linalg.norm(m.points[m.boundary_vertices[:1]], axis=1), 1.0)
    assert 3 * T == 2 * E - len(m.boundary_edges)
    assert check_mesh(m).admissible
    ref = {tuple(sorted(e)) for t in m.triangles.tolist() for e in [t[1:], t[::2], t[:2]]}
    assert ref == set(map(tuple, m.edges.tolist()))


def test_repr_and_equality(square):
    assert repr(square) == "PlanarMesh(n_vertices=5, n_triangles=4)"
    assert square == square5() and square != square.refine()
    assert square.diameter == pytest.approx(2 * math.sqrt(2))
