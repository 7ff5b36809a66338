"""Tests of the penalties f1 (HeightPenalty) and f2 (QualityPenalty).

Derivatives are checked by Taylor tests (orders 2 and 3) per term and for the sums,
values against hand computations and independent kernels (``geometry``, ``distance``).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh, square5

from meshopt_toolkit import data_path, load
from meshopt_toolkit.penalties import tuning as pen
from meshopt_toolkit.kernels.distance import boundary_pairs, regularized_distance_value
from meshopt_toolkit.errors import NotAdmissibleError
from meshopt_toolkit.kernels.triangles import heights, inverse_shape_quality, signed_areas
from meshopt_toolkit.mesh import PlanarMesh
from meshopt_toolkit.penalties import HeightPenalty, QualityPenalty, cutoff
from meshopt_toolkit.diagnostics import check_gradient, check_hvp

# ---------------------------------------------------------------------------------------
# meshes
# ---------------------------------------------------------------------------------------


def slot_mesh(n: int = 6, gap: float = 0.02, depth: int = 4) -> PlanarMesh:
    """[0, 1]² grid with a slot of width ``gap`` cut from the top of column n//2.

    Boundary vertices on the left wall of the slot are at distance ``gap`` from the
    (non-incident) boundary edges of the right wall: boundary pairs close to contact.
    """
    a = (1.0 - gap) / (n - 1)
    widths = np.full(n, a)
    widths[n // 2] = gap
    xs = np.concatenate([[0.0], np.cumsum(widths)])
    ys = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(xs, ys, indexing="xy")
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)  # idx[row, col]
    tris = []
    for j in range(n):  # building a tiny test mesh, not a hot path
        for i in range(n):
            if i == n // 2 and j >= n - depth:
                continue
            a0, b0, c0, d0 = idx[j, i], idx[j, i + 1], idx[j + 1, i + 1], idx[j + 1, i]
            tris += [[a0, b0, c0], [a0, c0, d0]]
    tris = np.array(tris)
    used = np.unique(tris)
    remap = np.full(len(pts), -1)
    remap[used] = np.arange(len(used))
    return PlanarMesh(pts[used], remap[tris])


def disc(name: str) -> PlanarMesh:
    return load(data_path(name))


def perturbed(mesh: PlanarMesh, scale: float, seed: int = 1) -> np.ndarray:
    """Mesh points moved randomly by ``scale`` × (shortest edge)."""
    r = np.random.default_rng(seed)
    e = mesh.edges
    hmin = np.linalg.norm(mesh.points[e[:, 0]] - mesh.points[e[:, 1]], axis=1).min()
    return mesh.points + scale * hmin * r.uniform(-1, 1, mesh.points.shape)


MESHES = {
    "square": lambda: square5(),
    "grid": lambda: grid_mesh(4, jitter=0.3),
    "refined": lambda: grid_mesh(3, jitter=0.3, seed=2).refine(),
    "disc77": lambda: disc("disc_77.msh"),
    "slot": lambda: slot_mesh(),
}

# each single term, then the sums
F2_TERMS = {
    "quality": (1.0, 0, 0, 0),
    "area": (0, 1.0, 0, 0),
    "boundary": (0, 0, 1.0, 0),
    "reference": (0, 0, 0, 1.0),
    "all": (1.0, 0.5, 0.2, 1.5),
}
F1_TERMS = {
    "height": (1.0, 0, 0),
    "boundary": (0, 1.0, 0),
    "reference": (0, 0, 1.0),
    "all": (1.0, 0.3, 2.0),
}


def _direction(Q, seed):
    v = np.random.default_rng(seed).standard_normal(Q.shape)
    return v / np.abs(v).max()


def _taylor(P, Q, seed=0, eps0=None):
    V = _direction(Q, seed)
    if eps0 is None:  # a tenth of the shortest edge
        e = P.mesh.edges
        eps0 = 0.1 * np.linalg.norm(Q[e[:, 0]] - Q[e[:, 1]], axis=1).min()
    r1 = check_gradient(P.value, P.gradient, Q, V, eps0=eps0)
    assert r1.passed and abs(r1.order - 2) < 0.3, r1
    r2 = check_hvp(P.value, P.gradient, P.hvp, Q, V, eps0=eps0)
    assert r2.passed and r2.order > 2.7, r2
    return r1, r2


# ---------------------------------------------------------------------------------------
# Taylor tests, every term separately and together
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("mesh_name", list(MESHES))
@pytest.mark.parametrize("term", list(F2_TERMS))
def test_f2_taylor(mesh_name, term):
    mesh = MESHES[mesh_name]()
    P = QualityPenalty(mesh, beta=F2_TERMS[term], mu=4.0)
    Q = perturbed(mesh, 0.1)
    if term != "all":
        assert P.term_names == [term]
    _taylor(P, Q)


@pytest.mark.parametrize("mesh_name", list(MESHES))
@pytest.mark.parametrize("term", list(F1_TERMS))
def test_f1_taylor(mesh_name, term):
    mesh = MESHES[mesh_name]()
    P = HeightPenalty(mesh, alpha=F1_TERMS[term], mu=4.0)
    Q = perturbed(mesh, 0.1, seed=3)
    if term != "all":
        assert P.term_names == [term]
    _taylor(P, Q, seed=1)


@pytest.mark.parametrize("mu", [1.0, 30.0, 1000.0])
@pytest.mark.parametrize("cls", [QualityPenalty, HeightPenalty])
def test_boundary_term_near_contact(cls, mu):
    """A boundary vertex at distance 2e-3 of a non-incident boundary edge, several μ."""
    gap = 2e-3
    mesh = slot_mesh(gap=gap)
    coef = (0, 0, 1.0, 0) if cls is QualityPenalty else (0, 1.0, 0)
    P = cls(mesh, coef, mu=mu)
    Q = perturbed(mesh, 0.05, seed=4)
    _taylor(P, Q, eps0=gap / 20)


def _pairs_with_summand(P, Q, w):
    """All pairs and their summands w/D^μ (brute force over every pair)."""
    m = P.mesh
    pairs = boundary_pairs(m.boundary_vertices, m.boundary_edges)
    return pairs, w / regularized_distance_value(Q, pairs, P.mu)


@pytest.mark.parametrize("cls", [QualityPenalty, HeightPenalty])
def test_cutoff_taylor_and_brute_force(cls):
    """Cut-off boundary term: Taylor orders with some pairs inside the blend zone, and the
    radius-searched value/gradient equal the all-pairs sum of χ(s)."""
    mesh = slot_mesh(gap=0.01)
    mu = 50.0
    coef = (0, 0, 1.0, 0) if cls is QualityPenalty else (0, 2.0, 0)
    w = 1.0 if cls is QualityPenalty else 2.0
    Q = perturbed(mesh, 0.05, seed=5)
    P0 = cls(mesh, coef, mu=mu)
    _, s = _pairs_with_summand(P0, Q, w)
    # blend zone around the closest pairs: some pairs in (s_lo, s_hi), some above s_hi
    s_sorted = np.sort(s)[::-1]
    s_lo, s_hi = 0.5 * s_sorted[12], 0.9 * s_sorted[0]
    assert ((s > s_lo) & (s < s_hi)).sum() >= 3 and (s >= s_hi).any()
    P = cls(mesh, coef, mu=mu, cutoff=(s_lo, s_hi))
    # pairs stay clear of s_lo along the test line: the searched set cannot change
    V = _direction(Q, 7)
    for e in (0.0, 1e-3):
        _, s_e = _pairs_with_summand(P0, Q + e * V, w)
        assert np.abs(s_e - s_lo).min() > 1e-3 * s_lo
    _taylor(P, Q, seed=7, eps0=2e-3)
    # brute force: χ over every pair
    _, s = _pairs_with_summand(P, Q, w)
    c = (
        1.0
        if cls is HeightPenalty
        else 1.0 / (len(mesh.boundary_edges) * len(mesh.boundary_vertices))
    )
    expected = c * cutoff(s, s_lo, s_hi)[0].sum()
    assert P.value(Q) == pytest.approx(expected, rel=1e-12)
    # the unclipped term is larger (χ(s) ≤ s)
    assert P0.value(Q) > P.value(Q)


def test_cutoff_gradient_matches_all_pairs_evaluation(monkeypatch):
    """Radius-searched gradient = gradient of the all-pairs χ-sum (radius search patched
    to return every pair)."""
    mesh = slot_mesh(gap=0.01)
    Q = perturbed(mesh, 0.05, seed=6)
    P = QualityPenalty(mesh, (0, 0, 1.0, 0), mu=20.0, cutoff=(20.0, 200.0))
    g_search, curv_search = P.gradient_and_curvature(Q, _direction(Q, 2))
    all_pairs = boundary_pairs(mesh.boundary_vertices, mesh.boundary_edges)
    import meshopt_toolkit.kernels.distance as dist

    monkeypatch.setattr(dist, "boundary_pairs", lambda *a, **k: all_pairs)
    g_all, curv_all = P.gradient_and_curvature(Q, _direction(Q, 2))
    assert np.abs(g_search).max() > 0
    np.testing.assert_allclose(g_search, g_all, rtol=1e-12, atol=1e-12 * np.abs(g_all).max())
    assert curv_search == pytest.approx(curv_all, rel=1e-12)


def test_all_pairs_chunked_equals_cached(monkeypatch):
    """Without a cut-off, iterating pairs in chunks gives the cached all-pairs result."""
    mesh = slot_mesh(gap=0.05)
    Q = perturbed(mesh, 0.05)
    V = _direction(Q, 3)
    P = QualityPenalty(mesh, (0, 0, 1.0, 0), mu=10.0)
    ref = (P.value(Q), P.gradient(Q), P.hvp(Q, V))
    assert P._other_terms[0]._all_pairs is not None  # the cached list
    monkeypatch.setattr(pen, "PAIR_CHUNK", 37)
    for cache in (10**6, 0):  # cached list in slices, then regenerated chunks
        monkeypatch.setattr(pen, "PAIR_CACHE", cache)
        P2 = QualityPenalty(mesh, (0, 0, 1.0, 0), mu=10.0)
        assert (P2._other_terms[0]._all_pairs is None) == (cache == 0)
        assert P2.value(Q) == pytest.approx(ref[0], rel=1e-13)
        np.testing.assert_allclose(P2.gradient(Q), ref[1], rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(P2.hvp(Q, V), ref[2], rtol=1e-12, atol=1e-14)


# ---------------------------------------------------------------------------------------
# consistency of the derivative entry points
# ---------------------------------------------------------------------------------------


def _penalties(mesh):
    return [
        QualityPenalty(mesh, (1.0, 0.5, 0.3, 2.0), mu=5.0),
        HeightPenalty(mesh, (0.7, 0.2, 1.0), mu=5.0),
        QualityPenalty(mesh, (1.0, 0.5, 0.3, 2.0), mu=5.0, cutoff=(0.5, 3.0)),
    ]


@pytest.mark.parametrize("mesh_name", ["grid", "slot", "disc77"])
def test_gradient_and_curvature_consistent(mesh_name, rng):
    mesh = MESHES[mesh_name]()
    Q = perturbed(mesh, 0.1)
    for P in _penalties(mesh):
        V = rng.standard_normal(Q.shape)
        U = rng.standard_normal(Q.shape)
        g, curv = P.gradient_and_curvature(Q, V)
        g_ref = P.gradient(Q)
        Hv = P.hvp(Q, V)
        Hu = P.hvp(Q, U)
        np.testing.assert_allclose(g, g_ref, rtol=1e-13, atol=0)
        assert curv == pytest.approx(float(np.vdot(V, Hv)), rel=1e-10)
        assert P.curvature(Q, V) == pytest.approx(curv, rel=1e-12)
        f, g2 = P.value_and_gradient(Q)
        assert f == pytest.approx(P.value(Q), rel=1e-14)
        np.testing.assert_array_equal(g2, g_ref)
        # symmetry of the Hessian
        uhv, vhu = float(np.vdot(U, Hv)), float(np.vdot(V, Hu))
        assert uhv == pytest.approx(vhu, rel=1e-10, abs=1e-10 * np.abs(Hv).max())
        # hvp against central differences of the gradient (independent of Taylor)
        h = 1e-6
        fd = (P.gradient(Q + h * V) - P.gradient(Q - h * V)) / (2 * h)
        np.testing.assert_allclose(Hv, fd, rtol=1e-5, atol=1e-5 * np.abs(Hv).max())
        assert sum(P.terms(Q).values()) == pytest.approx(f, rel=1e-14)


def test_cutoff_function_is_c3():
    s_lo, s_hi = 2.0, 5.0
    chi, d1, d2 = cutoff(np.array([0.0, 1.0, 2.0, 5.0, 6.0, 100.0]), s_lo, s_hi)
    np.testing.assert_array_equal(chi, [0, 0, 0, 5, 6, 100])
    np.testing.assert_array_equal(d1, [0, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(d2, [0, 0, 0, 0, 0, 0])
    # derivatives against finite differences everywhere (incl. across the breakpoints)
    s = np.linspace(1.0, 6.0, 2001)
    h = 1e-5
    c0, c1, c2 = cutoff(s, s_lo, s_hi)
    fd1 = (cutoff(s + h, s_lo, s_hi)[0] - cutoff(s - h, s_lo, s_hi)[0]) / (2 * h)
    fd2 = (cutoff(s + h, s_lo, s_hi)[1] - cutoff(s - h, s_lo, s_hi)[1]) / (2 * h)
    np.testing.assert_allclose(c1, fd1, atol=1e-8)
    np.testing.assert_allclose(c2, fd2, atol=1e-7)
    # C3: one-sided difference quotients of χ'' tend to χ''' = 0 at both breakpoints
    # (linearly in the offset δ; a jump in χ''' would leave them at a constant)
    for b in (s_lo, s_hi):
        d2b = cutoff(np.array([b]), s_lo, s_hi)[2]
        for side in (-1.0, 1.0):
            for delta in (1e-3, 1e-4, 1e-5):
                t = np.array([b + side * delta])
                q = (cutoff(t, s_lo, s_hi)[2] - d2b) / (t - b)
                assert abs(q[0]) < 100 * delta, (b, side, delta, q)
    # monotone and 0 ≤ χ ≤ s
    assert (c1 >= 0).all() and (c0 >= 0).all() and (c0 <= s).all()
    with pytest.raises(ValueError):
        QualityPenalty(square5(), cutoff=(3.0, 1.0))


# ---------------------------------------------------------------------------------------
# values
# ---------------------------------------------------------------------------------------


def test_values_by_hand_on_square():
    """5-vertex square: four right isosceles triangles with legs √2 and hypotenuse 2."""
    m = square5()
    b = (0.3, 0.7, 1.1, 1.9)
    mu = 1.0
    shift = np.zeros((5, 2))
    shift[4] = [0.1, -0.2]
    Qref = m.points - shift
    P = QualityPenalty(m, beta=b, mu=mu, reference=Qref)
    t = P.terms(m.points)
    # S = 4 + 2 + 2 = 8, A = 1, 1/ψ = 8/(4√3)
    assert t["quality"] == pytest.approx(b[0] * 2 / np.sqrt(3), rel=1e-15)
    assert t["area"] == pytest.approx(b[1] / 4, rel=1e-15)
    # 4 boundary edges × 2 non-incident vertices = 8 pairs; each has the vertex above an
    # edge endpoint at height 2: D = 2, D^μ = h_μ(2) = 2 − 1/(4μ)
    assert t["boundary"] == pytest.approx(b[2] / 16 * 8 / (2 - 0.25 / mu), rel=1e-14)
    assert t["reference"] == pytest.approx(b[3] / 10 * (0.01 + 0.04), rel=1e-14)
    a = (0.5, 0.25, 3.0)
    P1 = HeightPenalty(m, alpha=a, mu=mu, reference=Qref)
    t1 = P1.terms(m.points)
    # heights: 2A/2 = 1 onto the hypotenuse, 2A/√2 = √2 onto each leg
    assert t1["height"] == pytest.approx(4 * a[0] * (1 + 2 / np.sqrt(2)), rel=1e-15)
    assert t1["boundary"] == pytest.approx(a[1] * 8 / 1.75, rel=1e-14)
    assert t1["reference"] == pytest.approx(a[2] / 2 * 0.05, rel=1e-14)
    assert P1.value(m.points) == pytest.approx(sum(t1.values()), rel=1e-15)


@pytest.mark.parametrize("mesh_name", ["grid", "disc77", "slot"])
def test_values_against_independent_kernels(mesh_name):
    mesh = MESHES[mesh_name]()
    Q = perturbed(mesh, 0.2)
    T, N = mesh.n_triangles, mesh.n_vertices
    mu = 3.0
    pairs = boundary_pairs(mesh.boundary_vertices, mesh.boundary_edges)
    inv_d = 1.0 / regularized_distance_value(Q, pairs, mu)
    t2 = QualityPenalty(mesh, (1.0, 1.0, 1.0, 1.0), mu=mu).terms(Q)
    assert t2["quality"] == pytest.approx(
        inverse_shape_quality(Q, mesh.triangles).mean(), rel=1e-13
    )
    assert t2["area"] == pytest.approx(1.0 / signed_areas(Q, mesh.triangles).sum(), rel=1e-12)
    nb = len(mesh.boundary_edges) * len(mesh.boundary_vertices)
    assert t2["boundary"] == pytest.approx(inv_d.sum() / nb, rel=1e-13)
    assert t2["reference"] == pytest.approx(((Q - mesh.points) ** 2).sum() / (2 * N), rel=1e-13)
    t1 = HeightPenalty(mesh, (1.0, 1.0, 1.0), mu=mu).terms(Q)
    assert t1["height"] == pytest.approx((1.0 / heights(Q, mesh.triangles)).sum(), rel=1e-13)
    assert t1["boundary"] == pytest.approx(inv_d.sum(), rel=1e-13)
    assert T > 0


# ---------------------------------------------------------------------------------------
# barrier behaviour and admissibility
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "make", [lambda m: QualityPenalty(m, (1.0, 0, 0, 0)), lambda m: HeightPenalty(m, (1.0, 0, 0))]
)
def test_blows_up_as_triangle_collapses(make):
    m = square5()
    P = make(m)
    vals = []
    for d in [1e-1, 1e-3, 1e-5, 1e-7]:
        Q = m.points.copy()
        Q[4] = [0.0, -1.0 + d]  # centre towards the bottom edge: triangle 0 collapses
        vals.append(P.value(Q))
    assert np.all(np.diff(vals) > 0) and vals[-1] > 1e6
    # inverted: +inf, not NaN; derivatives raise naming the triangle
    Q = m.points.copy()
    Q[4] = [0.0, -1.5]
    with np.errstate(all="raise"):
        assert P.value(Q) == np.inf
    assert P.terms(Q)[P.term_names[0]] == np.inf
    assert not P.is_admissible(Q)
    for call in (P.gradient, lambda q: P.hvp(q, q), lambda q: P.gradient_and_curvature(q, q)):
        with pytest.raises(NotAdmissibleError, match=r"triangle 0 \[0, 1, 4\] is inverted"):
            call(Q)
    Q[4] = [0.0, -1.0]  # zero area
    assert P.value(Q) == np.inf
    with pytest.raises(NotAdmissibleError, match="zero-area"):
        P.gradient(Q)


@pytest.mark.parametrize("cls", [QualityPenalty, HeightPenalty])
def test_blows_up_as_boundary_vertex_approaches_edge(cls):
    mesh = slot_mesh(gap=0.1)
    coef = (0, 0, 1.0, 0) if cls is QualityPenalty else (0, 1.0, 0)
    P = cls(mesh, coef, mu=10.0)
    # a vertex of the left slot wall, mid-height, moves right towards the right wall
    xs = np.unique(mesh.points[:, 0])
    x_left = xs[len(xs) // 2]
    assert xs[len(xs) // 2 + 1] - x_left == pytest.approx(0.1)
    cand = np.flatnonzero(
        np.isclose(mesh.points[:, 0], x_left)
        & (mesh.points[:, 1] > 0.7)
        & (mesh.points[:, 1] < 0.9)
    )
    assert cand.size == 1 and cand[0] in mesh.boundary_vertices
    v = cand[0]
    vals = []
    for d in [5e-2, 1e-2, 1e-3, 1e-4, 1e-5]:
        Q = mesh.points.copy()
        Q[v, 0] += 0.1 - d
        assert P.is_admissible(Q)
        vals.append(P.value(Q))
    assert np.all(np.diff(vals) > 0) and vals[-1] > 1e6
    # touching the edge, and going through it: not admissible
    for over in (0.0, 0.02):
        Q = mesh.points.copy()
        Q[v, 0] += 0.1 + over
        assert not P.is_admissible(Q)
        assert P.value(Q) == np.inf
        with pytest.raises(NotAdmissibleError, match="boundary"):
            P.gradient(Q)


def test_simple_boundary_cache_is_exact():
    # the cache of boundaries found simple never hides a crossing boundary
    mesh = slot_mesh(gap=0.1)
    P = QualityPenalty(mesh, (1.0, 1.0, 0.0, 0.0))
    xs = np.unique(mesh.points[:, 0])
    v = np.flatnonzero(np.isclose(mesh.points[:, 0], xs[len(xs) // 2])
                       & (mesh.points[:, 1] > 0.7) & (mesh.points[:, 1] < 0.9))[0]
    good, bad = mesh.points.copy(), mesh.points.copy()
    good[v, 0] += 0.05
    bad[v, 0] += 0.12  # through the opposite wall, every area still positive
    assert (mesh.with_points(bad).signed_areas() > 0).all()
    calls = []
    test = P._boundary_test
    P._boundary_test = lambda Q: calls.append(1) or test(Q)
    for _ in range(3):
        assert np.isfinite(P.value(good)) and P.value(bad) == np.inf
        P.gradient(good)
        with pytest.raises(NotAdmissibleError, match="boundary"):
            P.gradient(bad)
    assert len(calls) == 1 + 6  # the simple one once, the crossing one every time
    nudged = good.copy()
    nudged[v, 0] = np.nextafter(nudged[v, 0], np.inf)  # any change of a bit is a new key
    P.value(nudged)
    assert len(calls) == 8


def test_value_never_nan():
    m = square5()
    P = QualityPenalty(m, (1.0, 1.0, 1.0, 1.0))
    Q = m.points.copy()
    Q[:] = 0.0  # everything collapsed
    assert P.value(Q) == np.inf
    Q = m.points.copy()
    Q[2] = np.nan
    assert P.value(Q) == np.inf
    assert not P.is_admissible(Q)
    with pytest.raises(ValueError, match="shape"):
        P.value(np.zeros((4, 2)))


# ---------------------------------------------------------------------------------------
# invariances
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("mesh_name", ["grid", "slot"])
def test_rigid_motion_invariance(mesh_name):
    mesh = MESHES[mesh_name]()
    Q = perturbed(mesh, 0.2)
    th = 0.7
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    t = np.array([3.0, -1.5])

    def move(X):
        return X @ R.T + t

    for cls, coef in ((QualityPenalty, (1.0, 0.5, 0.3, 2.0)), (HeightPenalty, (0.7, 0.2, 1.0))):
        P = cls(mesh, coef, mu=5.0)
        Pm = cls(mesh, coef, mu=5.0, reference=move(mesh.points))
        a, b = P.terms(Q), Pm.terms(move(Q))
        for k in a:
            assert b[k] == pytest.approx(a[k], rel=1e-11), k
        # the gradient and Hessian rotate with the mesh
        V = _direction(Q, 1)
        np.testing.assert_allclose(
            Pm.gradient(move(Q)),
            P.gradient(Q) @ R.T,
            rtol=1e-9,
            atol=1e-11 * np.abs(P.gradient(Q)).max(),
        )
        hv = P.hvp(Q, V) @ R.T
        np.testing.assert_allclose(
            Pm.hvp(move(Q), V @ R.T), hv, rtol=1e-8, atol=1e-10 * np.abs(hv).max()
        )


@pytest.mark.parametrize("mesh_name", ["square", "grid", "disc77"])
def test_refinement_invariance(mesh_name):
    """Quality and area terms of f2 are exactly invariant under uniform refinement (the 4
    children of a triangle are similar to it, the areas add up); the reference term is not."""
    mesh = MESHES[mesh_name]()
    Q = perturbed(mesh, 0.2)
    coarse = mesh.with_points(Q)
    fine = coarse.refine()
    ref_fine = mesh.refine()  # reference refined the same way
    Pc = QualityPenalty(coarse, (1.0, 1.0, 0, 1.0), reference=mesh.points)
    Pf = QualityPenalty(fine, (1.0, 1.0, 0, 1.0), reference=ref_fine.points)
    tc, tf = Pc.terms(coarse.points), Pf.terms(fine.points)
    assert tf["quality"] == pytest.approx(tc["quality"], rel=1e-13)
    assert tf["area"] == pytest.approx(tc["area"], rel=1e-13)
    # the reference term is an average over nodes: refinement adds edge midpoints whose
    # displacement is the mean of two, so it changes
    assert tf["reference"] != pytest.approx(tc["reference"], rel=1e-3)
    # f1's height term scales with the number of triangles: not invariant either
    hc = HeightPenalty(coarse, (1.0, 0, 0)).value(coarse.points)
    hf = HeightPenalty(fine, (1.0, 0, 0)).value(fine.points)
    assert hf == pytest.approx(8 * hc, rel=1e-12)  # 4 children, heights halved


def test_reference_defaults_and_validation():
    m = grid_mesh(3)
    P = QualityPenalty(m, (0, 0, 0, 1.0))
    assert P.value(m.points) == 0.0
    np.testing.assert_array_equal(P.gradient(m.points), 0.0)
    P2 = QualityPenalty(m, (0, 0, 0, 1.0), reference=m.with_points(m.points + 1.0))
    assert P2.value(m.points) == pytest.approx(1.0, rel=1e-14)  # β4/(2N) · 2N
    with pytest.raises(ValueError):
        QualityPenalty(m, (1.0, 2.0))
    with pytest.raises(ValueError):
        HeightPenalty(m, (1.0, -1.0, 0))
    with pytest.raises(ValueError):
        HeightPenalty(m, mu=0.0)
    assert "quality" in repr(QualityPenalty(m, (1.0, 0, 0, 0)))


def test_exported_from_package():
    import meshopt_toolkit as mt

    assert mt.QualityPenalty is QualityPenalty and mt.HeightPenalty is HeightPenalty


def test_blocked_triangle_pass_matches_single_block(monkeypatch):
    """Several blocks (BLOCK = 7 triangles) give the single-block results, and an inverted
    triangle in a later block is still found."""
    mesh = grid_mesh(5, jitter=0.3)
    Q = perturbed(mesh, 0.1)
    V = _direction(Q, 4)
    ref = [QualityPenalty(mesh, (1.0, 0.5, 0, 1.0)), HeightPenalty(mesh, (1.0, 0, 1.0))]
    monkeypatch.setattr(pen, "BLOCK", 7)
    blocked = [QualityPenalty(mesh, (1.0, 0.5, 0, 1.0)), HeightPenalty(mesh, (1.0, 0, 1.0))]
    for P, B in zip(ref, blocked):
        assert len(B._blocks) == -(-mesh.n_triangles // 7) and len(P._blocks) == 1
        assert B.value(Q) == pytest.approx(P.value(Q), rel=1e-14)
        np.testing.assert_allclose(B.gradient(Q), P.gradient(Q), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(B.hvp(Q, V), P.hvp(Q, V), rtol=1e-13, atol=1e-12)
        gb, cb = B.gradient_and_curvature(Q, V)
        gp, cp = P.gradient_and_curvature(Q, V)
        np.testing.assert_allclose(gb, gp, rtol=1e-13, atol=1e-13)
        assert cb == pytest.approx(cp, rel=1e-13)
        # invert the last triangle (in the last block) by mirroring its first vertex
        k = mesh.n_triangles - 1
        i0, i1, i2 = mesh.triangles[k]
        Qbad = Q.copy()
        d = Q[i2] - Q[i1]
        n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        Qbad[i0] = Q[i0] - 2 * np.dot(Q[i0] - Q[i1], n) * n
        assert B.value(Qbad) == np.inf
        assert signed_areas(Qbad, mesh.triangles)[:7].min() > 0  # first block is fine
        with pytest.raises(NotAdmissibleError, match=r"triangle \d+ \[.*\] is inverted"):
            B.gradient(Qbad)
