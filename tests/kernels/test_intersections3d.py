"""Exact orient3d and triangle–triangle self-intersections in 3D, against Fraction
references written here (a separating-axis test, independent of the edge tests of the
module), closed forms and pymeshlab."""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.kernels.intersections3d import (
    candidate_pairs,
    intersecting_pairs,
    self_intersections,
)
from meshopt_toolkit.kernels.predicates import orient3d

# ---------------------------------------------------------------- Fraction references


def _fr(p):
    return [Fraction(float(x)) for x in p]


def _sub(a, b):
    return [x - y for x, y in zip(a, b)]


def _cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def _dot(u, v):
    return sum(x * y for x, y in zip(u, v))


def ref_orient3d(a, b, c, d) -> int:
    a, b, c, d = map(_fr, (a, b, c, d))
    det = _dot(_cross(_sub(b, a), _sub(c, a)), _sub(d, a))
    return (det > 0) - (det < 0)


def ref_triangles_meet(A, B) -> bool:
    """Closed triangles (non-degenerate) meet iff no axis separates them strictly; the
    axes: both normals, the nine edge cross products, the in-plane edge normals."""
    A = [_fr(p) for p in A]
    B = [_fr(p) for p in B]
    eA = [_sub(A[(i + 1) % 3], A[i]) for i in range(3)]
    eB = [_sub(B[(i + 1) % 3], B[i]) for i in range(3)]
    nA, nB = _cross(eA[0], eA[1]), _cross(eB[0], eB[1])
    axes = [nA, nB] + [_cross(u, v) for u in eA for v in eB]
    axes += [_cross(n, e) for n in (nA, nB) for e in eA + eB]
    for L in axes:
        if not any(L):
            continue
        pa = [_dot(L, p) for p in A]
        pb = [_dot(L, p) for p in B]
        if max(pa) < min(pb) or max(pb) < min(pa):
            return False
    return True


def _pair(A, B):
    """The two triangles as a mesh of six vertices (no vertex shared)."""
    return np.array(list(A) + list(B), float), np.array([[0, 1, 2], [3, 4, 5]])


def _meet(A, B) -> bool:
    V, F = _pair(A, B)
    return len(self_intersections(V, F)) == 1


# ---------------------------------------------------------------- orient3d

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False, width=64)
point = st.tuples(finite, finite, finite)


@given(st.lists(st.tuples(point, point, point, point), min_size=1, max_size=20))
@settings(max_examples=150, deadline=None)
def test_orient3d_matches_fractions_random(rows):
    P = np.array(rows, float)
    got = orient3d(P[:, 0], P[:, 1], P[:, 2], P[:, 3])
    assert got.tolist() == [ref_orient3d(*r) for r in rows]


@given(point, point, point, st.floats(-3, 3), st.floats(-3, 3),
       st.sampled_from([0.0, 1e-300, 1e-17, 1e-15, 2.0**-52]))
@settings(max_examples=300, deadline=None)
def test_orient3d_near_coplanar_exact(a, b, c, s, t, lift):
    """d = a + s(b − a) + t(c − a) rounded (and nudged): the sign is the exact one."""
    a, b, c = (np.array(p) for p in (a, b, c))
    d = a + s * (b - a) + t * (c - a) + lift
    got = int(orient3d(a, b, c, d))
    assert got == ref_orient3d(a, b, c, d)
    # the permutations' signs (exact, so exactly antisymmetric)
    assert int(orient3d(b, a, c, d)) == -got
    assert int(orient3d(a, c, b, d)) == -got
    assert int(orient3d(b, c, a, d)) == got


@given(st.lists(st.tuples(*[st.integers(-40, 40)] * 2), min_size=4, max_size=4),
       st.integers(-60, 60), st.tuples(*[st.integers(-9, 9)] * 3),
       st.tuples(*[st.integers(-9, 9)] * 3), st.tuples(*[st.integers(-9, 9)] * 3))
@settings(max_examples=200, deadline=None)
def test_orient3d_exactly_coplanar_grid(uv, k, u, w, shift):
    """Points i·u + j·w + shift of an integer grid in a plane, scaled by 2^k: exactly 0;
    moved off the plane by 2^k along an axis, the sign of the Fraction reference."""
    u, w, shift = (np.array(x, float) for x in (u, w, shift))
    P = (np.array([i * u + j * w for i, j in uv]) + shift) * 2.0**k
    assert int(orient3d(*P)) == 0
    Q = P.copy()
    Q[3, 2] += 2.0**k
    assert int(orient3d(*Q)) == ref_orient3d(*Q)


tiny = st.floats(-1e-300, 1e-300, allow_nan=False, allow_infinity=False, width=64)
mixed = st.one_of(tiny, finite, st.floats(-1e-150, 1e-150, width=64))


@given(st.lists(st.tuples(*[st.tuples(mixed, mixed, mixed)] * 4), min_size=1, max_size=10))
@settings(max_examples=200, deadline=None)
def test_orient3d_matches_fractions_at_tiny_magnitudes(rows):
    """Subnormal and tiny coordinates mixed with unit ones: products may underflow."""
    P = np.array(rows, float)
    got = orient3d(P[:, 0], P[:, 1], P[:, 2], P[:, 3])
    assert got.tolist() == [ref_orient3d(*r) for r in rows]


def test_orient3d_extremes_and_shapes():
    a, b, c, d = np.eye(4, 3)  # (1,0,0), (0,1,0), (0,0,1), (0,0,0)
    assert orient3d(d, a, b, c) == 1
    assert orient3d(d, b, a, c) == -1
    for s in (2.0**-1070, 2.0**-600, 2.0**600, 1e300):
        assert orient3d(d * s, a * s, b * s, c * s) == 1
    assert orient3d(np.zeros((2, 5, 3)), np.ones(3), [1, 2, 3], [3, 3, 3]).shape == (2, 5)
    with pytest.raises(ValueError):
        orient3d(np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2))


# ---------------------------------------------------------------- closed forms

T0 = [(0, 0, 0), (2, 0, 0), (0, 2, 0)]


@pytest.mark.parametrize("B, meet", [
    ([(0.5, 0.5, -1), (0.5, 0.5, 1), (3, 3, 0.5)], True),   # crossing
    ([(0.5, 0.5, 0), (1, 1, 1), (0, 1, 1)], True),          # touching at a point inside
    ([(2, 0, 0), (3, 0, 1), (3, 1, -1)], True),              # touching at a vertex
    ([(1, 1, 0), (1, 1, 1), (2, 2, 1)], True),               # touching on an edge
    ([(0.5, 0.5, 1e-300), (1, 1, 1), (0, 1, 1)], False),     # just above
    ([(1, 1, 0), (3, 3, 0), (3, 1, 0)], True),               # coplanar, sharing a point
    ([(1.0000000000000002, 1, 0), (3, 3, 0), (3, 1, 0)], False),  # coplanar, an ulp off
    ([(0.2, 0.2, 0), (1, 0.2, 0), (0.2, 1, 0)], True),       # coplanar, one inside
    ([(1, -1, 0), (1, 3, 0), (3, 1, 0)], True),              # coplanar, edges crossing
    ([(3, 3, 0), (4, 3, 0), (3, 4, 0)], False),              # coplanar, apart
    ([(0, 0, 1), (2, 0, 1), (0, 2, 1)], False),              # parallel planes
])
def test_two_triangles_closed_forms(B, meet):
    assert _meet(T0, B) is meet
    assert ref_triangles_meet(T0, B) is meet
    assert _meet(B, T0) is meet  # symmetric


def _two(F, V):
    return len(self_intersections(np.array(V, float), np.array(F)))


def test_shared_edge_only_along_it():
    V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0.5, 0), (0, 1, 1)]
    assert _two([[0, 1, 2], [1, 0, 3]], V) == 0   # flat, on both sides of the edge
    assert _two([[0, 1, 2], [1, 0, 5]], V) == 0   # a hinge
    assert _two([[0, 1, 2], [1, 0, 4]], V) == 1   # folded flat onto each other
    # folded flat with the other triangle larger: still an overlap
    assert _two([[0, 1, 2], [1, 0, 2]], [(0, 0, 0), (1, 0, 0), (0, 1, 0)]) == 1


def test_shared_vertex_only_at_it():
    V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0), (0.2, 0.2, 0),
         (1, 1, 0.5), (0.5, -0.5, 1), (0.3, 0.3, -1), (0.3, 0.3, 1)]
    assert _two([[0, 1, 2], [0, 3, 4]], V) == 0   # opposite wedges in the plane
    assert _two([[0, 1, 2], [0, 5, 6]], V) == 1   # 5 inside 012: edge 56 crosses it
    assert _two([[0, 1, 2], [0, 8, 9]], V) == 1   # edge 89 pierces 012
    assert _two([[0, 1, 2], [0, 6, 7]], V) == 0   # above, touching only at 0
    # coplanar, a wedge inside the other's wedge
    W = [(0, 0, 0), (2, 0, 0), (0, 2, 0), (1, 0.5, 0), (0.5, 1, 0)]
    assert _two([[0, 1, 2], [0, 3, 4]], W) == 1
    # collinear edges overlapping (0–3 runs along 0–1): they touch beyond the vertex
    W = [(0, 0, 0), (2, 0, 0), (0, 2, 0), (1, 0, 0), (1, -1, 0)]
    assert _two([[0, 1, 2], [0, 3, 4]], W) == 1


def test_same_three_vertices_and_bad_input():
    V = np.eye(3)
    assert self_intersections(V, [[0, 1, 2], [2, 1, 0]]).tolist() == [[0, 1]]
    from meshopt_toolkit.errors import InvalidMeshError

    # a triangle on a repeated vertex is left out
    assert self_intersections(V, [[0, 1, 1], [0, 1, 2], [0, 1, 1]]).shape == (0, 2)
    W = np.vstack([V, [[0.2, 0.2, -1], [0.2, 0.2, 1]]])
    assert self_intersections(W, [[0, 0, 1], [0, 1, 2], [3, 3, 4], [2, 3, 4]]).tolist() == \
        [[1, 3]]
    with pytest.raises(InvalidMeshError):
        self_intersections(np.array([[np.nan, 0, 0], [0, 1, 0], [0, 0, 1]]), [[0, 1, 2]])
    assert self_intersections(V, np.zeros((0, 3), int)).shape == (0, 2)


def test_degenerate_triangles_are_their_segments():
    # a zero-area triangle lying across a triangle: they meet; lifted, they do not
    V = [(0, 0, 0), (2, 0, 0), (0, 2, 0), (-1, 0.5, 0), (0.5, 0.5, 0), (3, 0.5, 0)]
    assert _two([[0, 1, 2], [3, 4, 5]], V) == 1
    V2 = [p if i < 3 else (p[0], p[1], 1e-20) for i, p in enumerate(V)]
    assert _two([[0, 1, 2], [3, 4, 5]], V2) == 0
    # two zero-area triangles: crossing segments, then skew ones
    S = [(0, 0, 0), (1, 1, 0), (2, 2, 0), (0, 2, 0), (1, 1, 0.0), (2, 0, 0)]
    S[4] = (1.5, 0.5, 0)
    assert _two([[0, 1, 2], [3, 4, 5]], S) == 1
    S[3], S[4], S[5] = (0, 2, 1), (1, 1, 1), (2, 0, 1)
    assert _two([[0, 1, 2], [3, 4, 5]], S) == 0


# ---------------------------------------------------------------- random soups


def _brute(V, F):
    out = []
    for i, j in itertools.combinations(range(len(F)), 2):
        if ref_triangles_meet(V[F[i]], V[F[j]]):
            out.append([i, j])
    return out


def _soup(rng, n, grid):
    V = rng.integers(-grid, grid + 1, size=(3 * n, 3)).astype(float) / 4
    F = np.arange(3 * n).reshape(n, 3)
    area = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    return V, F[area > 0]


@pytest.mark.parametrize("seed", range(6))
def test_soups_match_brute_force_fractions(seed):
    """Small integer grids: coplanar, touching and collinear cases are common."""
    rng = np.random.default_rng(seed)
    V, F = _soup(rng, 40, 3 if seed % 2 else 8)
    assert self_intersections(V, F).tolist() == _brute(V, F)


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=25, deadline=None)
def test_near_degenerate_soups_match_fractions(seed):
    """Triangles through points of a plane (rounded), lifted by an ulp or not."""
    rng = np.random.default_rng(seed)
    n = 12
    uv = rng.uniform(-1, 1, size=(3 * n, 2))
    normal_mix = rng.uniform(-1, 1, size=2)
    V = np.column_stack([uv, uv @ normal_mix])
    lift = rng.integers(0, 3, size=3 * n)
    V[:, 2] = np.where(lift == 1, np.nextafter(V[:, 2], np.inf), V[:, 2])
    F = np.arange(3 * n).reshape(n, 3)
    assert self_intersections(V, F).tolist() == _brute(V, F)


def test_invariant_under_exact_maps():
    """Power-of-two scaling, axis permutations and sign flips, triangle and vertex order."""
    rng = np.random.default_rng(3)
    V, F = _soup(rng, 60, 6)
    ref = {tuple(p) for p in self_intersections(V, F).tolist()}
    assert ref
    perm = rng.permutation(len(F))
    inv = np.argsort(perm)
    for W in (V * 2.0**-900, V * 2.0**700, V[:, [2, 0, 1]] * [-1, 1, -1]):
        got = self_intersections(W, np.roll(F[perm], 1, axis=1))
        assert {tuple(sorted((int(perm[i]), int(perm[j])))) for i, j in got} == ref
    assert len(inv) == len(F)


# ---------------------------------------------------------------- surfaces


def test_primitives_are_free_and_a_pushed_vertex_is_not():
    trimesh = pytest.importorskip("trimesh")
    for m in (trimesh.creation.icosphere(subdivisions=3), trimesh.creation.box(),
              trimesh.creation.capsule(), trimesh.creation.torus(1.0, 0.3)):
        assert self_intersections(m.vertices, m.faces).shape == (0, 2)
    m = trimesh.creation.icosphere(subdivisions=3)
    V = np.array(m.vertices)
    V[0] = -1.5 * V[0]  # through the sphere and out at the other side
    P = self_intersections(V, m.faces)
    assert len(P) > 0
    assert np.isin(P, np.flatnonzero((m.faces == 0).any(axis=1))).any(axis=1).all()


@pytest.mark.parametrize("seed", range(4))
def test_matches_pymeshlab_on_noisy_spheres(seed):
    """Faces in some intersecting pair = pymeshlab's self-intersection selection."""
    trimesh = pytest.importorskip("trimesh")
    pymeshlab = pytest.importorskip("pymeshlab")
    m = trimesh.creation.icosphere(subdivisions=2)
    rng = np.random.default_rng(seed)
    V = np.array(m.vertices) + rng.normal(scale=0.12, size=m.vertices.shape)
    F = np.array(m.faces)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(V, F))
    ms.compute_selection_by_self_intersections_per_face()
    theirs = set(np.flatnonzero(ms.current_mesh().face_selection_array()).tolist())
    ours = set(np.unique(self_intersections(V, F)).tolist())
    assert theirs, "the noise should make some intersections"
    assert ours == theirs


def test_broad_phase_pairs_are_the_overlapping_boxes():
    rng = np.random.default_rng(0)
    lo = rng.uniform(0, 10, size=(400, 3))
    hi = lo + rng.exponential(0.5, size=(400, 3))
    hi[:3] = lo[:3] + 8  # a few big boxes
    hi[5] = lo[5]  # a point
    got = candidate_pairs(lo, hi)
    i, j = np.triu_indices(400, 1)
    ok = ((lo[i] <= hi[j]) & (lo[j] <= hi[i])).all(axis=1)
    assert got.tolist() == np.stack([i[ok], j[ok]], axis=1).tolist()


def test_narrow_phase_on_given_pairs():
    V, F = _pair(T0, [(0.5, 0.5, -1), (0.5, 0.5, 1), (3, 3, 0.5)])
    assert intersecting_pairs(V, F, [[0, 1], [1, 0]]).tolist() == [True, True]
