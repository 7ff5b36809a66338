"""The mesh model (SPEC §1): validation, check_mesh, refinement, topology, immutability."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import grid_mesh, square5

import meshopt_toolkit.mesh.topology as mesh_module
from meshopt_toolkit.gmsh_session import gmsh_session
from meshopt_toolkit.errors import InvalidMeshError, NotAdmissibleError
from meshopt_toolkit.kernels.triangles import inverse_shape_quality, quality_summary, signed_areas
from meshopt_toolkit.mesh import (
    PlanarMesh,
    TriangleMesh,
    boundary_self_intersections,
    check_mesh,
    require_admissible,
)
from meshopt_toolkit.mesh.checks import _manifold_problems
from meshopt_toolkit.mesh.topology import (
    _clean_manifold,
    _corner_table,
    _fans_per_vertex,
    _sorted_half_edges,
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
    assert t.is_planar and not t.in_xy_plane  # one plane, not z = 0: its own coordinates
    assert np.allclose(t.as_planar().embedding.to_3d(t.as_planar().points), t.points)
    bent = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5]], [[0, 1, 2], [1, 3, 2]])
    assert not bent.is_planar
    with pytest.raises(InvalidMeshError, match="not planar"):
        bent.as_planar()
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
    r = check_mesh(TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1e-3]],
                                [[0, 1, 2], [1, 3, 2]]))
    assert not r.planar and not r.manifold and "not planar" in r.problems[0]


def test_unused_vertex():
    r = _problem(SQ_PTS + [[5, 5]], SQ_TRI)
    assert r.manifold  # not a non-manifold edge or vertex, but not admissible either
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
    r = check_mesh(TriangleMesh(SQ_PTS, tri))  # oriented by propagation
    assert r.manifold and r.admissible and r.reoriented and r.n_reoriented == 1
    assert r.mesh.triangles.tolist() == SQ_TRI


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


@pytest.mark.parametrize("kind", ["planar", "surface"])
def test_tagged_vertices_by_name_take_the_group_dimension_only(kind):
    # gmsh numbers physical groups per dimension: line group 1 and surface group 1 differ
    from meshopt_toolkit.mesh import PlanarMesh, SurfaceMesh

    cls = PlanarMesh if kind == "planar" else SurfaceMesh
    P = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    mesh = cls(P, [[0, 1, 2], [0, 2, 3]], triangle_tags=[1, 1], lines=[[0, 1]],
               line_tags=[1], tag_names={"bottom": (1, 1), "domain": (1, 2)})
    np.testing.assert_array_equal(mesh.tagged_vertices("bottom"), [0, 1])
    np.testing.assert_array_equal(mesh.tagged_vertices("domain"), [0, 1, 2, 3])
    np.testing.assert_array_equal(mesh.tagged_vertices(1), [0, 1, 2, 3])


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
    with pytest.raises(InvalidMeshError, match=r"new points: shape \(\d.*\), expected"):
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


# -- the fast check against the exact one and a brute-force reference ---------------------


def brute_force_fans(triangles, n) -> np.ndarray:
    """Fans per vertex by a union-find over the triangles at each vertex (Python loops)."""
    tri = [tuple(t) for t in np.asarray(triangles).tolist()]
    by_edge: dict = {}
    for k, t in enumerate(tri):
        for l in range(3):
            by_edge.setdefault(frozenset((t[(l + 1) % 3], t[(l + 2) % 3])), []).append(k)
    fans = np.zeros(n, int)
    for v in range(n):
        at = [k for k, t in enumerate(tri) if v in t]
        parent = {k: k for k in at}

        def find(k, parent=parent):
            while parent[k] != k:
                k = parent[k]
            return k

        for k in at:
            for w in tri[k]:
                if w != v:
                    for k2 in by_edge[frozenset((v, w))]:
                        parent[find(k)] = find(k2)
        fans[v] = len({find(k) for k in at})
    return fans


def brute_force_clean(triangles, n) -> bool:
    """Every planar-manifold condition of SPEC §1, by direct counting (Python loops)."""
    tri = [tuple(t) for t in np.asarray(triangles).tolist()]
    if len({v for t in tri for v in t}) < n or any(len(set(t)) < 3 for t in tri):
        return False
    directed: dict = {}
    undirected: dict = {}
    for k, t in enumerate(tri):
        for l in range(3):
            a, b = t[(l + 1) % 3], t[(l + 2) % 3]
            directed[(a, b)] = directed.get((a, b), 0) + 1
            undirected.setdefault(frozenset((a, b)), []).append(k)
    if max(directed.values()) > 1 or max(map(len, undirected.values())) > 2:
        return False  # inconsistent orientation or an edge in three triangles
    piece = list(range(len(tri)))

    def find(k):
        while piece[k] != k:
            k = piece[k]
        return k

    for ks in undirected.values():
        if len(ks) == 2:
            piece[find(ks[0])] = find(ks[1])
    if len({find(k) for k in range(len(tri))}) > 1:
        return False
    return brute_force_fans(tri, n).max() <= 1


def mutated_mesh(rng) -> PlanarMesh:
    """A small grid with 0-3 random defects (removed, flipped, duplicated or random
    triangles, merged vertices, hanging triangles, glued copies), randomly renumbered."""
    g = grid_mesh(int(rng.integers(2, 5)))
    tri, pts = g.triangles.copy(), g.points.copy()
    for op in rng.integers(0, 8, size=int(rng.integers(0, 4))):
        nv = len(pts)
        if op == 0 and len(tri) > 2:
            tri = np.delete(tri, rng.choice(len(tri), int(rng.integers(1, 3)), replace=False), 0)
        elif op == 1:
            k = rng.integers(len(tri))
            tri[k] = tri[k, ::-1]
        elif op == 2:
            a, b = rng.choice(nv, 2, replace=False)
            tri[tri == b] = a
        elif op == 3:
            tri = np.vstack([tri, rng.choice(nv, 3, replace=False)])
        elif op == 4:
            pts = np.vstack([pts, rng.uniform(2, 3, (2, 2))])
            tri = np.vstack([tri, [rng.integers(nv), nv, nv + 1]])
        elif op == 5:
            tri = np.vstack([tri, tri[rng.integers(len(tri))]])
        elif op == 6:
            keep = rng.random(len(tri)) < 0.8  # random subsets: bow-ties, holes, pieces
            tri = tri[keep] if keep.any() else tri
        else:  # a second copy sharing one vertex, possibly also glued along an edge
            v = int(rng.integers(nv))
            copy = g.triangles + nv
            copy[copy == v + nv] = v
            pts = np.vstack([pts, g.points + 5])
            tri = np.vstack([tri, copy])
    perm = rng.permutation(len(pts))
    inv = np.argsort(perm)
    tri = np.roll(perm[tri][rng.permutation(len(tri))], int(rng.integers(3)), axis=1)
    return PlanarMesh(pts[inv], tri)


@pytest.mark.parametrize("walk_steps", [0, 1, 64])
def test_fast_check_agrees_with_exact_check_and_brute_force(monkeypatch, walk_steps):
    # walk_steps 0: every fan by pointer doubling; 1: walks and pointer doubling mixed
    monkeypatch.setattr(mesh_module, "_WALK_STEPS", walk_steps)
    rng = np.random.default_rng(walk_steps)
    seen = set()
    for _ in range(250):
        m = mutated_mesh(rng)
        fast = _clean_manifold(m) is not None
        exact = _manifold_problems(PlanarMesh(m.points, m.triangles)) == []
        reference = brute_force_clean(m.triangles, m.n_vertices)
        assert fast == exact == reference, m.triangles.tolist()
        seen.add(fast)
    assert seen == {True, False}


def test_fans_per_vertex_against_brute_force():
    rng = np.random.default_rng(7)
    n_bow = 0
    for _ in range(150):
        m = mutated_mesh(rng)
        report = check_mesh(m)
        if any("orientable" in p or "shared by" in p or "repeats" in p for p in report.problems):
            continue  # _fans_per_vertex needs an edge-manifold, oriented mesh
        fans = _fans_per_vertex(PlanarMesh(m.points, report.mesh.triangles))
        np.testing.assert_array_equal(fans, brute_force_fans(m.triangles, m.n_vertices))
        n_bow += int(fans.max() > 1)
    assert n_bow > 5


def bridge(mesh: PlanarMesh, other: PlanarMesh, v: int, w: int) -> PlanarMesh:
    """``mesh`` and a copy of ``other`` (shifted right) with vertex ``w`` of the copy
    identified with vertex ``v`` and the pieces joined by two triangles across a
    boundary edge of each: edge-connected, consistently oriented, edge-manifold."""
    n = mesh.n_vertices
    p, q = mesh.boundary_edges[0]
    r, s = other.boundary_edges[0] + n
    tri = np.vstack([mesh.triangles, other.triangles + n, [[q, p, s], [s, r, q]]])
    tri[tri == w + n] = v
    return compact(np.vstack([mesh.points, other.points + [3, 0]]), tri)


def _centre(m: PlanarMesh) -> int:
    return int(np.argmin(np.linalg.norm(m.points - m.points.mean(axis=0), axis=1)))


@pytest.mark.parametrize("kind", ["closed+closed", "closed+open", "open+open"])
def test_bow_tie_in_an_edge_connected_mesh(kind):
    g = grid_mesh(4)
    centre = _centre(g)  # interior vertex: a closed fan
    corner = int(np.flatnonzero((g.points == [1, 1]).all(1))[0])  # a boundary fan
    v = corner if kind == "open+open" else centre
    w = centre if kind == "closed+closed" else corner
    m = bridge(g, g, v, w)
    assert _clean_manifold(m) is None
    fans = brute_force_fans(m.triangles, m.n_vertices)
    (pinch,) = np.flatnonzero(fans > 1)
    report = check_mesh(m)
    assert report.problems == [
        f"vertex {pinch} is a bow-tie: its triangles form 2 separate fans"
    ]
    np.testing.assert_array_equal(_fans_per_vertex(m), fans)


def test_bridge_without_a_pinch_is_clean():
    g = grid_mesh(3)
    n = g.n_vertices
    m = bridge(g, g, n + 7, n + 7)  # identifies nothing (w + n is not in the mesh)
    assert _clean_manifold(m) is not None
    assert check_mesh(m).manifold


@pytest.mark.parametrize("walk_steps", [0, 2, 64])
def test_high_degree_fans(monkeypatch, walk_steps):
    # a fan of 40 triangles around the origin (one closed fan), then two such fans glued
    monkeypatch.setattr(mesh_module, "_WALK_STEPS", walk_steps)
    k = 40
    th = 2 * np.pi * np.arange(k) / k
    pts = np.vstack([[0, 0], np.stack([np.cos(th), np.sin(th)], 1)])
    tri = np.stack([np.zeros(k, int), 1 + np.arange(k), 1 + (np.arange(k) + 1) % k], 1)
    disc = PlanarMesh(pts, tri)
    assert _clean_manifold(disc) is not None and check_mesh(disc).admissible
    double = bridge(disc, disc, 0, 0)
    assert _clean_manifold(double) is None
    assert "is a bow-tie: its triangles form 2 separate fans" in check_mesh(double).problems[0]
    half = PlanarMesh(pts, tri[: k // 2])  # an open fan
    assert _clean_manifold(compact(half.points, half.triangles)) is not None


def test_check_fills_the_boundary_cache_exactly(rng):
    for seed in range(6):
        g = grid_mesh(5, jitter=0.3, seed=seed)
        tri = np.roll(g.triangles[rng.permutation(g.n_triangles)], seed % 3, axis=1)
        for t in (tri, tri[:, ::-1]):  # CCW, and CW (re-oriented by the check)
            m = PlanarMesh(g.points, t)
            report = check_mesh(m)
            assert report.admissible and report.reoriented == (t is not tri)
            fresh = PlanarMesh(report.mesh.points, report.mesh.triangles)
            np.testing.assert_array_equal(report.mesh.boundary_edges, fresh.boundary_edges)
            np.testing.assert_array_equal(m.boundary_edges, PlanarMesh(g.points, t).boundary_edges)


def test_half_edge_sort_packed_and_unpacked_agree():
    m = grid_mesh(4, jitter=0.2)
    table = _corner_table(m.triangles[np.random.default_rng(1).permutation(m.n_triangles)])
    for step in (0, 1):
        c1, code1, b1 = _sorted_half_edges(table, m.n_vertices, np.int64, step)
        c2, code2, b2 = _sorted_half_edges(table, 2**30, np.int64, step)  # no room to pack
        assert b2 == 30 and b1 < b2
        np.testing.assert_array_equal(c1, c2)
        lo1, lo2 = code1 >> np.uint64(b1 + 1), code2 >> np.uint64(b2 + 1)
        np.testing.assert_array_equal(lo1, lo2)
    # the codes name the corners' half-edges: (lo, hi, direction) of 3k + l
    c, code, b = _sorted_half_edges(table, m.n_vertices, np.int64)
    t = table.T
    src, dst = t[c // 3, (c % 3 + 1) % 3], t[c // 3, (c % 3 + 2) % 3]
    np.testing.assert_array_equal(code >> np.uint64(b + 1), np.minimum(src, dst))
    np.testing.assert_array_equal((code >> np.uint64(1)) & np.uint64(2**b - 1), np.maximum(src, dst))
    np.testing.assert_array_equal(code & np.uint64(1), src > dst)
    assert np.all(np.diff(code.astype(np.int64)) >= 0)


def test_readable_checks_with_huge_but_finite_coordinates():
    pts = [[1e308, 0], [1e308, 1e308], [0, 1e308]]  # the coordinate sum overflows
    assert PlanarMesh(pts, [[0, 1, 2]]).n_vertices == 3
    with pytest.raises(InvalidMeshError, match=r"vertex 1 has a non-finite"):
        PlanarMesh([[1e308, 0], [np.inf, 1e308], [0, 1e308]], [[0, 1, 2]])
    with pytest.raises(InvalidMeshError, match=r"triangle 1 \[0, -2, 1\].*out of range"):
        PlanarMesh(pts, np.array([[0, 1, 2], [0, -2, 1]], dtype=np.int32))


def test_mesh_info_agrees_with_check_mesh_and_quality(tmp_path):
    from meshopt_toolkit.cli.info import mesh_info
    from meshopt_toolkit.io import save

    g = grid_mesh(4, jitter=0.3)
    p = g.points.copy()
    p[6] = [0.6, 0.6]
    cases = {
        "ok": g,
        "cw": g.flipped(),
        "inverted": g.with_points(p),
        "three": PlanarMesh(SQ_PTS + [[0, -2], [0.5, -3]], SQ_TRI + [[1, 0, 5], [0, 1, 6]]),
        "bowtie": bridge(g, g, _centre(g), _centre(g)),
        "strip": folded_strip(),
    }
    for name, m in cases.items():
        path = save(m, tmp_path / f"{name}.msh")
        info = mesh_info(path)
        report = check_mesh(m)
        q = quality_summary(report.mesh.points, report.mesh.triangles).as_dict()
        assert info["problems"] == report.problems, name
        assert (info["manifold"], info["admissible"], info["reoriented"]) == (
            report.manifold, report.admissible, report.reoriented
        )
        assert info["n_boundary_vertices"] == len(m.boundary_vertices)
        for key in ("min_area", "total_area", "n_inverted", "min_angle_deg"):
            assert info[key] == q[key], (name, key)


# -- the direct gmsh 4.1 reader (io/gmsh_layout.py) reads exactly what meshio reads -------


def _via_meshio(path):
    import meshio.gmsh

    from meshopt_toolkit.conversions import from_meshio

    return from_meshio(meshio.gmsh.read(path), source=str(path))


def _direct(path):
    from meshopt_toolkit.io import gmsh as gmsh_io

    with open(path, "rb") as fh:
        return gmsh_io.parse41(fh)


def _same_mesh(a, b):
    assert type(a) is type(b) and a == b and a.source == b.source
    for name in ("triangle_tags", "lines", "line_tags"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y)
    assert a.tag_names == b.tag_names


@pytest.fixture(scope="module")
def gmsh_binary_files(tmp_path_factory):
    """Bundled meshes and a gmsh-meshed square (physical point, lines, surface) written
    by gmsh itself as binary 4.1, and a square meshed without physical groups."""
    pytest.importorskip("gmsh")
    from meshopt_toolkit.datasets import data_path

    d = tmp_path_factory.mktemp("msh41")
    files = []
    with gmsh_session() as gmsh:
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 1)
        for name in ("disc_77.msh", "square5.msh"):
            gmsh.open(str(data_path(name)))
            files.append(d / name)
            gmsh.write(str(files[-1]))
            gmsh.clear()
        for groups in (True, False):
            gmsh.model.add(f"sq{groups}")
            s = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
            gmsh.model.occ.synchronize()
            if groups:
                gmsh.model.addPhysicalGroup(2, [s], 5, "plate")
                gmsh.model.addPhysicalGroup(1, [1, 2], 6, "sides")
                gmsh.model.addPhysicalGroup(0, [1], 8, "pin")
            gmsh.option.setNumber("Mesh.MeshSizeMax", 0.25)
            gmsh.model.mesh.generate(2)
            files.append(d / f"square_{groups}.msh")
            gmsh.write(str(files[-1]))
            gmsh.clear()
    return files


def test_direct_gmsh_reader_matches_meshio_on_gmsh_files(gmsh_binary_files):
    from meshopt_toolkit.io import load

    for path in gmsh_binary_files:
        assert _direct(path) is not None, path  # the fast path is taken
        _same_mesh(load(path), _via_meshio(path))


def test_direct_gmsh_reader_matches_meshio_on_our_files(tmp_path):
    from meshopt_toolkit.io import load, save

    g = grid_mesh(3, jitter=0.2)
    b = g.boundary_edges
    tagged = PlanarMesh(
        g.points, g.triangles, triangle_tags=np.arange(g.n_triangles) % 2 + 1, lines=b,
        line_tags=np.where(b[:, 0] < 4, 3, 4), tag_names={"a": (1, 2), "b": (2, 2), "c": (3, 1)},
    )
    surface = TriangleMesh(np.column_stack([g.points, g.points[:, 0] ** 2]), g.triangles)
    for k, m in enumerate([g, tagged, surface]):
        path = save(m, tmp_path / f"m{k}.msh")
        assert _direct(path) is not None
        got = load(path)
        _same_mesh(got, _via_meshio(path))
        assert got == m


def test_direct_gmsh_reader_hands_unusual_files_to_meshio(tmp_path):
    from meshopt_toolkit.errors import ReadError
    from meshopt_toolkit.io import load, save

    path = save(grid_mesh(3), tmp_path / "g.msh")
    data = path.read_bytes()
    # sparse node tags (every tag doubled, elements too): meshio's tag map is used
    nodes = data.index(b"$Nodes\n") + 7
    head = np.frombuffer(data, "<u8", 4, nodes).copy()
    n = int(head[1])
    tags_at = nodes + 32 + 12 + 8
    tags = np.frombuffer(data, "<u8", n, tags_at) * 2
    sparse = bytearray(data)
    sparse[tags_at : tags_at + 8 * n] = tags.tobytes()
    els = data.index(b"$Elements\n") + 10
    n_tri = int(np.frombuffer(data, "<u8", 1, els + 8)[0])
    at = els + 32 + 12 + 8
    table = np.frombuffer(data, "<u8", 4 * n_tri, at).reshape(-1, 4).copy()
    table[:, 1:] *= 2
    sparse[at : at + table.nbytes] = table.tobytes()
    sparse[nodes + 24 : nodes + 32] = np.array([2 * n], "<u8").tobytes()  # max tag
    p2 = tmp_path / "sparse.msh"
    p2.write_bytes(bytes(sparse))
    assert _direct(p2).complete  # mapped as meshio maps them
    np.testing.assert_array_equal(_direct(p2).layout.node_tags, tags)
    assert load(p2) == grid_mesh(3)
    _same_mesh(load(p2), _via_meshio(p2))
    # an unknown section: meshio reads the file, the layout is kept
    p3 = tmp_path / "extra.msh"
    p3.write_bytes(data + b"$Comments\nhello\n$EndComments\n")
    assert not _direct(p3).complete
    _same_mesh(load(p3), _via_meshio(p3))
    # truncated: the error is meshio's, named by our reader
    p4 = tmp_path / "cut.msh"
    p4.write_bytes(data[: len(data) - 200])
    with pytest.raises(ValueError):
        _direct(p4)
    with pytest.raises(ReadError, match=r"cut\.msh: cannot read gmsh file"):
        load(p4)


def test_check_after_with_points_reuses_the_topology_check():
    g = grid_mesh(4, jitter=0.2)
    assert check_mesh(g).admissible
    moved = g.with_points(g.points * 2)
    assert "_clean_corners" in moved.__dict__  # the topological verdict is shared
    p = g.points.copy()
    p[6] = [0.6, 0.6]
    report = check_mesh(g.with_points(p))
    assert report.manifold and not report.admissible  # areas are still checked
    broken = compact(g.points, g.triangles[1:])
    assert check_mesh(broken).manifold  # a different connectivity is checked anew
    ring = bridge(g, g, _centre(g), _centre(g))
    assert not check_mesh(ring).manifold and not check_mesh(ring.with_points(ring.points)).manifold
