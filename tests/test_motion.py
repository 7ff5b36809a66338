"""The per-triangle distortion metric, its discrete geodesics, move and morph.

Guarantees are checked as invariants on random inputs: Taylor remainders of every
derivative, the closed forms of φ (singular values), its invariances, the per-triangle
quality bound along paths, similarity motions followed exactly, handles exact.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import grid_mesh
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.kernels.triangles import aspect_ratios, inverse_shape_quality
from meshopt_toolkit.motion.assembly import upper_to_blocks
from meshopt_toolkit.motion.move import move
from meshopt_toolkit.motion.morph import distortion_morph
from meshopt_toolkit.motion.graph_metric import GraphMetric
from meshopt_toolkit.motion.path import GraphPath
from meshopt_toolkit.motion.similarity import fit_similarity
from meshopt_toolkit.motion.strain import (
    TriangleDistortion,
    shape_quality_bound,
    stretch_ratios,
)
from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.riemannian.discrete_geodesic import discrete_geodesic

FAST = settings(max_examples=15, deadline=None)


def _similar(points, angle, scale, shift):
    c, s = np.cos(angle), np.sin(angle)
    return scale * points @ np.array([[c, -s], [s, c]]).T + np.asarray(shift)


def _random_admissible(mesh, rng, amplitude):
    """An affine image of ``mesh`` plus a small perturbation, admissible by construction:
    ``A = I + a·B`` with ``‖B‖₂ ≤ ‖B‖_F ≤ 1`` and ``a < 1`` keeps ``det A > 0``; the noise is
    halved until no triangle inverts (the affine image alone is admissible)."""
    assert amplitude < 1
    A = np.eye(2) + amplitude * rng.uniform(-0.5, 0.5, (2, 2))
    Q = mesh.points @ A.T + rng.uniform(-1, 1, 2)
    noise = 0.05 * amplitude / np.sqrt(mesh.n_vertices) * rng.standard_normal(Q.shape)
    while not (mesh.with_points(Q + noise).signed_areas() > 0).all():
        noise /= 2
    return Q + noise


def _geodesic(metric, frames, free, boundary_edges=None, anchor=None, **settings):
    """The Levenberg–Marquardt discrete geodesic from the initial path ``frames``."""
    return discrete_geodesic(metric, frames[0], frames[-1], len(frames) - 1, path=frames,
                             free=free, boundary_edges=boundary_edges, anchor=anchor,
                             options=settings)


@pytest.fixture(scope="module")
def disc():
    return grid_mesh(6, jitter=0.3)


# ------------------------------------------------------------------ φ and its Jacobian
def test_distortion_matches_singular_values(disc, rng):
    P, T = disc.points, disc.triangles
    Q = _random_admissible(disc, rng, 0.4)
    phi = TriangleDistortion(P, T).values(Q)
    D0 = np.stack([P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]], axis=2)
    D1 = np.stack([Q[T[:, 1]] - Q[T[:, 0]], Q[T[:, 2]] - Q[T[:, 0]]], axis=2)
    s = np.linalg.svd(D1 @ np.linalg.inv(D0), compute_uv=False)
    np.testing.assert_allclose(np.sqrt(2) * phi[:, 0], np.log(s[:, 0] * s[:, 1]), atol=1e-12)
    kappa = s[:, 0] / s[:, 1]
    np.testing.assert_allclose(np.sqrt(2) * np.hypot(phi[:, 1], phi[:, 2]),
                               (kappa - 1 / kappa) / 2, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(stretch_ratios(phi), kappa, rtol=1e-10)


@pytest.mark.parametrize("at_reference", [True, False])
def test_distortion_jacobian_taylor(disc, rng, at_reference):
    P, T = disc.points, disc.triangles
    dist = TriangleDistortion(P, T)
    Q = P.copy() if at_reference else _random_admissible(disc, rng, 0.3)
    weights = rng.standard_normal((len(T), 3))  # a scalar functional of φ tests every row

    def f(X):
        return float(np.sum(weights * dist.values(X)))

    def grad(X):
        _, blocks = dist.values_and_jacobian(X)
        return (dist.jacobian_matrix(blocks).T @ weights.ravel()).reshape(X.shape)

    result = check_gradient(f, grad, Q, eps0=1e-3, rng=rng)
    assert abs(result.order - 2) < 0.2, result


@pytest.mark.parametrize("at_reference", [True, False])
def test_distortion_second_order_taylor(disc, rng, at_reference):
    """``second_order(Q, ρ)`` is the Hessian of ``Σ ρ·φ``: second-order Taylor test."""
    P, T = disc.points, disc.triangles
    dist = TriangleDistortion(P, T)
    Q = P.copy() if at_reference else _random_admissible(disc, rng, 0.3)
    weights = rng.standard_normal((len(T), 3))
    cols = (2 * T[:, :, None] + np.arange(2)).reshape(-1, 6)

    def f(X):
        return float(np.sum(weights * dist.values(X)))

    def grad(X):
        _, blocks = dist.values_and_jacobian(X)
        return (dist.jacobian_matrix(blocks).T @ weights.ravel()).reshape(X.shape)

    def hvp(X, V):
        blocks = upper_to_blocks(dist.second_order(X, weights))
        local = np.matmul(blocks, V.ravel()[cols][:, :, None])[:, :, 0]
        return np.bincount(cols.ravel(), local.ravel(), minlength=V.size).reshape(V.shape)

    result = check_hvp(f, grad, hvp, Q, eps0=1e-3, rng=rng)
    assert abs(result.order - 3) < 0.2, result


def test_mesh_pattern_is_the_sorted_coordinate_pattern(disc):
    """The pattern built from vertex pairs is the sorted set of the coordinate entries,
    each triangle entry and diagonal entry lands on its own (row, col), and ``transposed``
    maps every slot to the slot of (col, row)."""
    from meshopt_toolkit.motion.assembly import MeshPattern

    n = 2 * disc.n_vertices
    cols = (2 * disc.triangles[:, :, None] + np.arange(2)).reshape(-1, 6)
    rows6 = np.broadcast_to(cols[:, :, None], (len(cols), 6, 6)).ravel()
    cols6 = np.broadcast_to(cols[:, None, :], (len(cols), 6, 6)).ravel()
    keys = np.unique(np.concatenate([rows6 * n + cols6, np.arange(n) * (n + 1)]))
    pattern = MeshPattern(disc.triangles, disc.n_vertices)
    assert np.array_equal(pattern.rows * n + pattern.cols, keys)
    slots = pattern.slot_of_entry
    assert np.array_equal(pattern.rows[slots], np.concatenate([rows6, np.arange(n)]))
    assert np.array_equal(pattern.cols[slots], np.concatenate([cols6, np.arange(n)]))
    assert np.array_equal(pattern.rows[pattern.transposed], pattern.cols)
    assert np.array_equal(pattern.cols[pattern.transposed], pattern.rows)


def test_symmetric_assembly_is_the_full_one(disc, rng):
    """Symmetric blocks assembled from their 21 upper entries (one bincount and the
    transpose) equal the full blocks' assembly."""
    from meshopt_toolkit.motion.assembly import MeshPattern, symmetric_products

    pattern = MeshPattern(disc.triangles, disc.n_vertices)
    a = rng.standard_normal((6, 3, disc.n_triangles))
    full = np.einsum("ict,jct->tij", a, a)
    upper = symmetric_products(a)
    assert np.abs(upper_to_blocks(upper) - full).max() <= 1e-14 * np.abs(full).max()
    diagonal = rng.random(2 * disc.n_vertices)
    expected = pattern.values(full, diagonal)
    assert np.abs(pattern.symmetric_values(upper, diagonal) - expected).max() \
        <= 1e-13 * np.abs(expected).max()


@FAST
@given(angle=st.floats(-3.1, 3.1), scale=st.floats(0.01, 100), shift=st.tuples(
    st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)), seed=st.integers(0, 2**16))
def test_distortion_invariances(angle, scale, shift, seed):
    mesh = grid_mesh(3, jitter=0.3)
    rng = np.random.default_rng(seed)
    dist = TriangleDistortion(mesh.points, mesh.triangles)
    Q = _random_admissible(mesh, rng, 0.3)
    phi = dist.values(Q)
    moved = dist.values(_similar(Q, angle, scale, shift))
    np.testing.assert_allclose(moved[:, 1:], phi[:, 1:], atol=1e-9 * (1 + np.abs(phi).max()))
    np.testing.assert_allclose(moved[:, 0] - phi[:, 0], np.sqrt(2) * np.log(scale), atol=1e-9)
    assert np.abs(dist.values(mesh.points)).max() < 1e-12


def test_distortion_is_infinite_where_inverted(disc):
    Q = disc.points.copy()
    t = disc.triangles[5]
    Q[t[0]] = Q[t[1]] + 2 * (Q[t[2]] - Q[t[1]]) * 0.5  # onto the opposite edge: degenerate
    phi = TriangleDistortion(disc.points, disc.triangles).values(Q)
    assert np.isinf(phi[5]).all()


# ------------------------------------------------------------------ quality bounds
@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.01, 0.6))
def test_shape_quality_bound_holds_for_every_triangle(seed, amplitude):
    mesh = grid_mesh(4, jitter=0.3, seed=seed)
    rng = np.random.default_rng(seed)
    Q = _random_admissible(mesh, rng, amplitude)
    phi = TriangleDistortion(mesh.points, mesh.triangles).values(Q)
    bound = shape_quality_bound(inverse_shape_quality(mesh.points, mesh.triangles),
                                np.linalg.norm(phi, axis=1))
    assert (inverse_shape_quality(Q, mesh.triangles) <= bound * (1 + 1e-12)).all()


@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.05, 0.5), weight=st.floats(0.2, 5))
def test_path_bounds_every_triangle_by_its_length(seed, amplitude, weight):
    """Along any discrete path, |φ_t(Q_k) − φ_t(Q_0)| ≤ ℓ_k/w, hence the 1/ψ bound."""
    mesh = grid_mesh(3, jitter=0.3, seed=seed)
    rng = np.random.default_rng(seed)
    frames = np.array([mesh.points] + [_random_admissible(mesh, rng, amplitude)
                                       for _ in range(4)])
    metric = GraphMetric(mesh.points, mesh.triangles, weight)
    ell = np.concatenate([[0.0], np.cumsum(metric.segment_lengths(frames))])
    q0 = inverse_shape_quality(mesh.points, mesh.triangles)
    for k, Q in enumerate(frames):
        change = np.linalg.norm(metric.strain.values(Q), axis=1)
        # rounding only: φ at the reference itself evaluates to a few ulps, not to 0
        assert (change <= ell[k] / weight * (1 + 1e-12) + 64 * np.finfo(float).eps).all()
        bound = shape_quality_bound(q0, np.full(len(q0), ell[k] / weight))
        assert (inverse_shape_quality(Q, mesh.triangles) <= bound * (1 + 1e-12)).all()


# ------------------------------------------------------------------ discrete geodesic
def test_path_energy_gradient_taylor(disc, rng):
    P, T = disc.points, disc.triangles
    frames = np.array([P] + [_random_admissible(disc, rng, 0.1 * k) for k in (1, 2, 3)])
    free = np.ones((4, disc.n_vertices), bool)
    free[0] = False
    free[3, :3] = False
    metric = GraphMetric(P, T, 1.7, triangle_weights=1 + rng.uniform(0, 1, len(T)))
    path = GraphPath(metric, frames, free, None, anchor_strain=None)
    x0 = path.unknowns(frames)

    def E(x):
        r, _ = path.evaluate(path.with_unknowns(x), jacobian=False)
        return float(r @ r)

    def grad(x):
        r, J = path.evaluate(path.with_unknowns(x), jacobian=True)
        return 2 * (J.T @ r)

    result = check_gradient(E, grad, x0, eps0=1e-3, rng=rng)
    assert abs(result.order - 2) < 0.2, result


@pytest.mark.parametrize("K, anchored, uneven", [(4, False, False), (4, False, True),
                                                 (4, False, "split"), (1, True, False),
                                                 (1, False, False)])
def test_normal_equations_match_the_sparse_jacobian(disc, rng, K, anchored, uneven):
    """The Gauss–Newton system assembled from per-triangle blocks is ``Jᵀr`` and ``JᵀJ``
    of the sparse Jacobian, with fixed vertices, weights and an anchor, with frames that
    fix different vertices (``uneven``) and with a fixed frame between two free ones."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    if K > 1:
        free[-1] = False
    free[:, np.unique(disc.boundary_edges)[:5]] = False
    if uneven is True:
        free[2, rng.choice(disc.n_vertices, 7, replace=False)] = False
        free[1, :3] = False
    if uneven == "split":
        free[2] = False
    metric = GraphMetric(P, disc.triangles, 1.3,
                         triangle_weights=1 + rng.random(disc.n_triangles))
    anchor = metric.strain.values(P) + 0.1 if anchored else None
    path = GraphPath(metric, frames, free, None, anchor_strain=anchor)
    r, J = path.evaluate(frames, jacobian=True)
    r2, g, H, scaling = path.normal_equations(frames)
    assert np.array_equal(r, r2)
    gJ, HJ = J.T @ r, (J.T @ J).toarray()
    assert np.abs(g - gJ).max() <= 1e-12 * np.abs(gJ).max()
    assert np.abs(H.tocsr().toarray() - HJ).max() <= 1e-12 * np.abs(HJ).max()
    assert np.abs(scaling - np.diag(HJ)).max() <= 1e-12 * np.abs(HJ).max()
    # Newton's matrix (Taylor-tested below): the same gradient and scaling, symmetric
    r3, g3, H3, scaling3 = path.normal_equations(frames, newton=True)
    assert np.array_equal(r3, r) and np.array_equal(g3, g) and np.array_equal(scaling3, scaling)
    assert abs(H3.tocsr() - H3.tocsr().T).max() <= 1e-12 * np.abs(HJ).max()


def test_block_tridiagonal_products_match_the_assembled_matrix(disc, rng):
    """The path matrix kept as frame blocks multiplies, damps and gives its diagonal
    blocks as the assembled matrix does, with frames that fix different vertices and a
    frame that fixes all (no coupling across it)."""
    P, K = disc.points, 5
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    free[3] = False  # no unknowns: frames 1–2 and 4–5 are two separate chains
    free[2, rng.choice(disc.n_vertices, 9, replace=False)] = False
    path = GraphPath(GraphMetric(P, disc.triangles), frames, free, None)
    _, _, H, _ = path.normal_equations(frames)
    dense = H.tocsr().toarray()
    assert len(H.blocks) == 4 and sorted(H.upper) == [0, 2]
    np.testing.assert_array_equal(dense, dense.T)
    v = rng.standard_normal(path.n_unknowns)
    shift = rng.random(path.n_unknowns)
    scale = np.abs(dense).max() * np.abs(v).max()
    assert np.abs(H @ v - dense @ v).max() <= 1e-13 * scale
    damped = H.damped(shift).damped(shift)
    assert np.abs(damped @ v - (dense @ v + 2 * shift * v)).max() <= 1e-13 * scale
    for B, (start, stop) in zip(damped.diagonal_blocks(), H.ranges):
        expected = dense[start:stop, start:stop] + np.diag(2 * shift[start:stop])
        np.testing.assert_allclose(B.toarray(), expected, rtol=0, atol=1e-14 * scale)
    assert H.shift is None  # damping made a new matrix
    from concurrent.futures import ThreadPoolExecutor

    from meshopt_toolkit.motion.assembly import BlockTridiagonal

    with ThreadPoolExecutor(2) as pool:  # frames in threads: the same products, bitwise
        threaded = BlockTridiagonal(H.ranges, H.blocks, H.upper, H.lower, shift,
                                    frames_map=pool.map)
        np.testing.assert_array_equal(threaded @ v, H.damped(shift) @ v)


def test_time_coupled_preconditioner_is_exact_for_equal_frames(disc, rng):
    """``P⁻¹ = 𝔻⁺(T⁻¹ ⊗ I)𝔻⁺ᵀ/K`` inverts the Gauss–Newton matrix exactly where every
    frame has the same Jacobian (a path standing still at a random admissible mesh), with
    a free last frame (``T_KK = 1``): one CG iteration, to rounding."""
    from meshopt_toolkit.motion.frame_blocks import FrameBlocks

    P, K = disc.points, 4
    Q = _random_admissible(disc, rng, 0.3)
    frames = np.array([P, *([Q] * K)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    path = GraphPath(GraphMetric(P, disc.triangles, 1.3), frames, free, None)
    _, _, H, _ = path.normal_equations(frames)
    assert H.embedding.coupled and H.embedding.segments == [2, 2, 2, 1]
    blocks = FrameBlocks(path.frame_indices())
    blocks.factorize(H)
    v = rng.standard_normal(path.n_unknowns)
    x = blocks.preconditioner(H)(H @ v)
    assert np.abs(x - v).max() <= 1e-8 * np.abs(v).max()


def test_time_coupled_preconditioner_is_symmetric_positive_definite(disc, rng):
    """On a moving path whose frames fix different vertices, split in two chains by a
    fixed frame, and damped: ``P⁻¹`` is symmetric and positive definite, and CG with it
    reaches the direct solution."""
    from scipy.sparse.linalg import spsolve

    from meshopt_toolkit.motion.frame_blocks import FrameBlocks

    P, K = disc.points, 6
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = free[3] = False
    free[:, np.unique(disc.boundary_edges)[:6]] = False
    free[2, rng.choice(disc.n_vertices, 9, replace=False)] = False
    path = GraphPath(GraphMetric(P, disc.triangles), frames, free, None)
    _, g, H, d = path.normal_equations(frames)
    A = H.damped(1e-3 * d)
    assert A.embedding.neighbours == [0, 2, 3]  # frames (1, 2), (4, 5), (5, 6)
    blocks = FrameBlocks(path.frame_indices())
    blocks.factorize(A)
    apply = blocks.preconditioner(A)
    U = rng.standard_normal((path.n_unknowns, 5))
    PU = np.column_stack([apply(u) for u in U.T])
    gram = U.T @ PU
    np.testing.assert_allclose(gram, gram.T, rtol=1e-10, atol=0)
    assert np.linalg.eigvalsh(0.5 * (gram + gram.T)).min() > 0
    exact = spsolve(A.tocsr().tocsc(), g)
    x = FrameBlocks(path.frame_indices()).solve(A, g, 1e-11)
    assert np.abs(x - exact).max() <= 1e-8 * np.abs(exact).max()


def test_time_coupled_solve_on_stale_factors_goes_on_with_fresh_ones(disc, rng, monkeypatch):
    """Factors of a far-away matrix (heavily damped) do not bring the time-coupled CG
    to its tolerance within ``STALE_CG_LIMIT`` iterations: the solve goes on from its
    iterate on fresh factors and still reaches the tolerance."""
    import meshopt_toolkit.motion.frame_blocks as frame_blocks

    frames, free, metric = _straight_path(disc, rng, K=6)
    path = GraphPath(metric, frames, free, None)
    _, g, H, d = path.normal_equations(frames)
    blocks = frame_blocks.FrameBlocks(path.frame_indices())
    blocks.factorize(H.damped(10.0 * d))  # kept factors of another matrix
    iterations = []
    pcg = frame_blocks.pcg

    def counting(*args, **kwargs):
        out = pcg(*args, **kwargs)
        iterations.append((out[1], kwargs["maxiter"]))
        return out

    monkeypatch.setattr(frame_blocks, "pcg", counting)
    x = blocks.solve(H, g, 1e-8)
    assert iterations[0] == (frame_blocks.STALE_CG_LIMIT, frame_blocks.STALE_CG_LIMIT)
    assert len(iterations) == 2 and iterations[1][1] > frame_blocks.STALE_CG_LIMIT
    assert np.linalg.norm(H @ x - g) <= 1e-8 * np.linalg.norm(g)


@pytest.mark.parametrize("K, anchored", [(4, False), (1, True)])
def test_newton_matrix_is_the_hessian_of_the_path_energy(disc, rng, K, anchored):
    """Second-order Taylor test: ``E(x + εv) − E − ε∇E·v − ½ε² vᵀ(2H)v = O(ε³)`` with H
    the Newton matrix (``∇E = 2g``), for a path and for an anchored single frame."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    free[:, np.unique(disc.boundary_edges)[:5]] = False
    metric = GraphMetric(P, disc.triangles, 1.3,
                         triangle_weights=1 + rng.random(disc.n_triangles))
    anchor = metric.strain.values(P) + 0.1 if anchored else None
    path = GraphPath(metric, frames, free, None, anchor_strain=anchor)

    def E(x):
        r, _ = path.evaluate(path.with_unknowns(x), jacobian=False)
        return float(r @ r)

    def grad(x):
        return 2 * path.normal_equations(path.with_unknowns(x))[1]

    def hvp(x, v):
        return 2 * (path.normal_equations(path.with_unknowns(x), newton=True)[2] @ v)

    result = check_hvp(E, grad, hvp, path.unknowns(frames), eps0=1e-3, rng=rng)
    assert abs(result.order - 3) < 0.2, result
    gauss_newton = check_hvp(E, grad, lambda x, v: 2 * (path.normal_equations(
        path.with_unknowns(x))[2] @ v), path.unknowns(frames), eps0=1e-3, rng=rng)
    assert gauss_newton.order < 2.5  # the test can tell the Gauss–Newton matrix apart


def test_frame_blocks_in_nested_dissection_order_solve_the_path_system(disc, rng):
    """The frames' blocks factorized in nested-dissection order (``points`` given) are the
    same preconditioner as in minimum-degree order: PCG reaches the direct solution."""
    from scipy.sparse.linalg import spsolve

    from meshopt_toolkit.motion.frame_blocks import FrameBlocks

    P, K = disc.points, 3
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    free[:, np.unique(disc.boundary_edges)] = False
    free[2, :4] = False  # frames of different sizes
    path = GraphPath(GraphMetric(P, disc.triangles), frames, free, None)
    _, g, H, _ = path.normal_equations(frames)
    exact = spsolve(H.tocsr().tocsc(), g)
    for points in (None, path.frame_points()):
        blocks = FrameBlocks(path.frame_indices(), points)
        x = blocks.solve(H, g, 1e-10)
        assert np.abs(x - exact).max() <= 1e-8 * np.abs(exact).max()
        assert (blocks.orderings is None) == (points is None)
    with pytest.raises(ValueError, match="one vertex per two columns"):
        FrameBlocks(path.frame_indices(), path.frame_points()[1:] + [P[:1]])


def test_frame_blocks_refuse_an_indefinite_matrix_and_refactorize_after(rng):
    """An indefinite matrix (a Newton matrix may be one) raises FloatingPointError; the
    next solve, of a positive definite matrix, factorizes afresh and succeeds."""
    from meshopt_toolkit.motion.frame_blocks import FrameBlocks

    n = 200
    laplacian = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n)).tocsr()
    b = rng.standard_normal(n)
    blocks = FrameBlocks([np.arange(n)])
    with pytest.raises(FloatingPointError):
        blocks.solve((laplacian - 0.5 * sp.eye(n)).tocsr(), b, 1e-8)
    assert blocks.stale
    spd = (laplacian + 0.1 * sp.eye(n)).tocsr()
    x = blocks.solve(spd, b, 1e-10)
    assert np.linalg.norm(spd @ x - b) <= 1e-9 * np.linalg.norm(b)


def test_discrete_geodesic_damps_more_where_the_newton_matrix_is_indefinite(
        disc, rng, monkeypatch):
    """A step whose solve meets non-positive curvature is rejected and the damping grows:
    the path still converges, to the same frames as without the failure."""
    from meshopt_toolkit.motion.frame_blocks import FrameBlocks

    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    free = np.ones((2, disc.n_vertices), bool)
    free[0] = False
    free[1, np.unique(disc.boundary_edges)] = False
    metric = GraphMetric(P, disc.triangles)
    frames = np.stack([P, P])
    anchor = metric.strain.values(target)
    reference = _geodesic(metric, frames, free, anchor=anchor, newton=True)
    calls = []
    solve = FrameBlocks.solve

    def fail_once(self, A, b, rtol):
        calls.append(len(calls))
        if len(calls) == 1:
            self.stale = True
            raise FloatingPointError("conjugate gradients broke down (pᵀAp ≤ 0)")
        return solve(self, A, b, rtol)

    monkeypatch.setattr(FrameBlocks, "solve", fail_once)
    result = _geodesic(metric, frames, free, anchor=anchor, newton=True)
    assert len(calls) > 1 and result.converged and reference.converged
    assert np.abs(result.points - reference.points).max() <= 1e-5 * np.abs(P).max()


def test_frame_blocks_redo_a_failed_single_precision_solve_in_double(monkeypatch):
    """Where CG does not converge on the float32 factors, the solve is redone (and the
    next ones made) on double-precision factors."""
    import meshopt_toolkit.motion.frame_blocks as frame_blocks
    from meshopt_toolkit.solvers import factorize_spd

    def float32_is_useless(A, ordering=None, single=False):  # stands for a bad float32 factor
        return (lambda v: v.copy()) if single else factorize_spd(A, ordering)

    monkeypatch.setattr(frame_blocks, "factorize_spd", float32_is_useless)
    monkeypatch.setattr(frame_blocks, "cholmod_available", lambda: False)  # SuperLU's case
    n = 2000
    A = (sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n)) + 1e-8 * sp.eye(n)).tocsr()
    b = np.random.default_rng(4).standard_normal(n)
    blocks = frame_blocks.FrameBlocks([np.arange(n)])
    assert blocks.single
    x = blocks.solve(A, b, 1e-10)
    assert not blocks.single
    assert np.linalg.norm(A @ x - b) <= 1e-9 * np.linalg.norm(b)


def test_frame_blocks_factorize_in_double_precision_with_cholmod(monkeypatch):
    """With CHOLMOD the blocks are its double-precision factors (never float32), in
    threads for large frames where its calls release the GIL (:mod:`._cholmod`), else one
    frame after another; without it, SuperLU's float32 factors, in threads."""
    import meshopt_toolkit._cholmod as native
    import meshopt_toolkit.motion.frame_blocks as frame_blocks
    import meshopt_toolkit.motion.frame_threads as frame_threads

    pool = frame_threads.frame_pool()

    n = frame_blocks.PARALLEL_FROM
    A = (sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(2 * n, 2 * n)) + 1e-2 * sp.eye(2 * n)
         ).tocsr()
    b = np.random.default_rng(5).standard_normal(2 * n)
    frames = [np.arange(n), np.arange(n, 2 * n)]
    blocks = frame_blocks.FrameBlocks(frames)
    assert not blocks.single
    assert blocks.threaded == (pool is not None and native.library() is not None)
    assert (blocks._map is map) != blocks.threaded
    exact = blocks.solve(A, b, 1e-12)
    assert np.linalg.norm(A @ exact - b) <= 1e-12 * np.linalg.norm(b)
    kept = list(blocks.factors)
    blocks.factorize((A + 0.5 * sp.eye(2 * n)).tocsr())  # refactorized on the analyses
    assert all(a is b for a, b in zip(blocks.factors, kept))
    assert np.linalg.norm(A @ blocks.solve(A, b, 1e-12) - b) <= 1e-12 * np.linalg.norm(b)
    monkeypatch.setattr(native, "library", lambda: None)  # CHOLMOD through cvxopt only
    serial = frame_blocks.FrameBlocks(frames)
    assert not serial.single and not serial.threaded and serial._map is map
    np.testing.assert_array_equal(serial.solve(A, b, 1e-12), exact)
    monkeypatch.setattr(frame_blocks, "cholmod_available", lambda: False)
    superlu = frame_blocks.FrameBlocks(frames)
    assert superlu.single and (superlu._map is map) == (pool is None)
    np.testing.assert_allclose(superlu.solve(A, b, 1e-12), exact, rtol=0,
                               atol=1e-9 * np.abs(exact).max())


def _straight_path(disc, rng, K=4):
    """Frames on the straight line to a random admissible target, ends fixed."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = free[-1] = False
    return frames, free, GraphMetric(P, disc.triangles)


def test_metric_applied_triangle_by_triangle_is_the_matrix(disc, rng):
    """``GraphMetric.apply`` is ``(M + w² JᵀJ) V`` with the assembled sparse Jacobian."""
    import scipy.sparse as sp

    metric = GraphMetric(disc.points, disc.triangles, 1.7,
                         triangle_weights=1 + rng.random(disc.n_triangles))
    Q = _random_admissible(disc, rng, 0.3)
    V = rng.standard_normal(Q.shape)
    _, blocks = metric.strain.values_and_jacobian(Q)
    J = sp.diags(metric.row_weights) @ metric.strain.jacobian_matrix(blocks)
    expected = (J.T @ (J @ V.ravel())).reshape(V.shape) + metric.mass[:, None] * V
    assert np.abs(metric.apply(Q, V) - expected).max() <= 1e-12 * np.abs(expected).max()


def test_discrete_geodesic_converges_and_lowers_energy(disc, rng):
    frames, free, metric = _straight_path(disc, rng)
    P, target = frames[0], frames[-1]
    r0, _ = GraphPath(metric, frames, free, None).evaluate(frames, jacobian=False)
    res = _geodesic(metric, frames, free, boundary_edges=disc.boundary_edges)
    assert res.converged and res.energy <= float(r0 @ r0)
    assert res.gradient_norm <= 1e-7 * max(1, np.sqrt(res.energy))
    assert np.array_equal(res.points[0], P) and np.array_equal(res.points[-1], target)


def test_discrete_geodesic_at_machine_precision_is_converged(disc):
    """With ``gtol = 0`` (unreachable) the path stops where no step can lower the energy
    beyond its rounding nor its gradient (steps E cannot judge are judged by |∇E|), and
    says converged, not stalled: the gradient is then at its floating-point floor (8e-13
    with this seed; judging those steps by E alone stopped at 2.6e-9)."""
    rng = np.random.default_rng(1)
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, 4)])
    free = np.ones((4, disc.n_vertices), bool)
    free[[0, -1]] = False
    res = _geodesic(GraphMetric(P, disc.triangles), frames, free, gtol=0.0,
                            max_iter=200)
    assert res.status == "converged" and res.nit < 200
    assert res.gradient_norm <= 1e-10 * max(1.0, np.sqrt(res.energy))


def test_discrete_geodesic_without_an_admissible_trial_is_stalled(disc, rng, monkeypatch):
    """Where every trial step leaves M+ nothing is known about the energy: the path says
    stalled, never converged."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, 4)])
    free = np.ones((4, disc.n_vertices), bool)
    free[[0, -1]] = False
    checks = []

    def only_the_start(self, frames):  # the initial path passes, no trial does
        checks.append(1)
        return len(checks) == 1

    monkeypatch.setattr(GraphPath, "admissible", only_the_start)
    res = _geodesic(GraphMetric(P, disc.triangles), frames, free)
    assert res.status == "stalled" and len(checks) == 31


def test_discrete_geodesic_relative_stop(disc, rng):
    """``rtol`` stops a relaxation once the gradient fell by that factor: converged, the
    gradient at most ``rtol`` times the first one, in fewer iterations than the full solve."""
    frames, free, metric = _straight_path(disc, rng)
    full = _geodesic(metric, frames, free)
    quick = _geodesic(metric, frames, free, rtol=1e-3)
    assert quick.converged and quick.nit < full.nit
    assert quick.gradient_norm <= 1e-3 * full.history[0][1]


def test_extension_through_kept_factors_matches_a_fresh_factorization(disc, rng):
    """A continuation reuses one factorization across its steps: the extension solved by
    PCG on a factorization made at another mesh is the one of a fresh factorization."""
    from meshopt_toolkit.motion.continuation import extend
    from meshopt_toolkit.motion.frame_blocks import FrameBlocks

    P = disc.points
    metric = GraphMetric(P, disc.triangles)
    handles = np.unique(disc.boundary_edges)
    Q = _random_admissible(disc, rng, 0.3)
    new = Q[handles] + 0.01 * rng.standard_normal((handles.size, 2))
    factors = FrameBlocks([np.arange(2 * (disc.n_vertices - handles.size))])
    extend(metric, P, handles, P[handles], factors)  # factorized at the reference
    assert not factors.stale
    fresh = extend(metric, Q, handles, new)
    reused = extend(metric, Q, handles, new, factors)
    assert np.array_equal(reused[handles], new)
    scale = np.abs(fresh - Q).max()
    assert np.abs(reused - fresh).max() <= 1e-6 * scale


# ------------------------------------------------------------------ similarity
@FAST
@given(angle=st.floats(-3.1, 3.1), scale=st.floats(0.1, 10), shift=st.tuples(
    st.floats(-10, 10), st.floats(-10, 10)))
def test_fit_similarity_recovers_a_similarity(angle, scale, shift):
    P = grid_mesh(3, jitter=0.3).points
    S = fit_similarity(P, _similar(P, angle, scale, shift))
    np.testing.assert_allclose(S(P), _similar(P, angle, scale, shift), atol=1e-9 * (1 + scale))
    np.testing.assert_allclose(S.inverse(S(P)), P, atol=1e-9)


@FAST
@given(angle=st.floats(-3.1, 3.1), scale=st.floats(0.2, 5), shift=st.tuples(
    st.floats(-5, 5), st.floats(-5, 5)))
def test_morph_between_similar_meshes_is_similar_in_every_frame(angle, scale, shift):
    mesh = grid_mesh(3, jitter=0.3)
    target = mesh.with_points(_similar(mesh.points, angle, scale, shift))
    result = distortion_morph(mesh, target, frames=4)
    ar0 = aspect_ratios(mesh.points, mesh.triangles)
    for Q in result.points:
        np.testing.assert_allclose(aspect_ratios(Q, mesh.triangles), ar0, rtol=1e-9)
    assert np.array_equal(result.points[-1], target.points)


@FAST
@given(angle=st.floats(-3.1, 3.1), scale=st.floats(0.2, 5), shift=st.tuples(
    st.floats(-5, 5), st.floats(-5, 5)))
def test_move_by_a_similarity_moves_the_whole_mesh_by_it(angle, scale, shift):
    mesh = grid_mesh(3, jitter=0.3)
    handles = np.unique(mesh.boundary_edges)
    targets = _similar(mesh.points[handles], angle, scale, shift)
    result = move(mesh, handles, targets, frames=3)
    assert np.array_equal(result.mesh.points[handles], targets)
    expected = _similar(mesh.points, angle, scale, shift)
    np.testing.assert_allclose(result.mesh.points, expected, atol=1e-9 * (1 + scale))
    for frame in result.frames:
        np.testing.assert_allclose(aspect_ratios(frame.points, mesh.triangles),
                                   aspect_ratios(mesh.points, mesh.triangles), rtol=1e-9)


# ------------------------------------------------------------------ move
@pytest.fixture(scope="module")
def annulus():
    pytest.importorskip("gmsh")
    from meshopt_toolkit.generate import annulus as make

    return make(0.1)


def _harmonic_inverts(mesh, handles, targets) -> int:
    """Harmonic extension with the same handles (the classical reference): inverted count."""
    import scipy.sparse.linalg as spla

    from meshopt_toolkit.fem.elasticity import p1_gradients

    P, T = mesh.points, mesh.triangles
    grads, area = p1_gradients(P, T)
    Ke = np.einsum("t,tid,tjd->tij", area, grads, grads)
    rows = np.repeat(T, 3, axis=1).ravel()
    cols = np.tile(T, (1, 3)).ravel()
    import scipy.sparse as sp

    L = sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(len(P),) * 2)
    free = np.setdiff1d(np.arange(len(P)), handles)
    Q = P.copy()
    Q[handles] = targets
    rhs = -(L[free][:, handles] @ targets)
    Q[free] = spla.spsolve(L[free][:, free].tocsc(), rhs)
    return int(np.sum(mesh.with_points(Q).signed_areas() <= 0))


@pytest.mark.parametrize("degrees", [90, 180])
def test_move_turns_the_annulus_hole_without_inverting(annulus, degrees):
    from meshopt_toolkit.generate import rotate_inner_boundary

    handles, targets = rotate_inner_boundary(annulus, degrees)
    assert _harmonic_inverts(annulus, handles, targets) > 0  # the classical method fails here
    result = move(annulus, handles, targets, frames=4)
    assert np.array_equal(result.mesh.points[handles], targets)  # bitwise
    for frame in result.frames:
        assert (frame.signed_areas() > 0).all()
    assert result.inverted == 0 and result.handle_error == 0.0
    assert np.array_equal(result.mesh.triangles, annulus.triangles)


def test_move_finishes_every_frame_and_keeps_the_proven_bound(annulus):
    """``frames=K``: every intermediate frame gets the quality step (it keeps the best of
    its rounds and the unfinished frame, so no frame gets worse — by construction; that
    some frame improves is what shows the step ran), the handles stay where
    the motion puts them at that time, and the quality bound 1/ψ ≤ exp(asinh(√2ℓ/w))/ψ0
    holds along the frames returned."""
    from meshopt_toolkit.generate import rotate_inner_boundary

    handles, targets = rotate_inner_boundary(annulus, 90)
    raw = move(annulus, handles, targets, frames=5, finish_frames=False)
    seen = []
    done = move(annulus, handles, targets, frames=5, progress=seen.append)
    assert np.all(np.diff(seen) >= 0) and seen[-1] == 1.0  # the frames' steps are counted
    assert (done.min_aspect_ratio >= raw.min_aspect_ratio).all()
    assert done.min_aspect_ratio[1:-1].min() > raw.min_aspect_ratio[1:-1].min()
    q0 = inverse_shape_quality(annulus.points, annulus.triangles)
    for a, b, ell in zip(raw.frames, done.frames, done.strain_bound):
        assert np.array_equal(a.points[handles], b.points[handles])
        assert (b.signed_areas() > 0).all()
        assert (inverse_shape_quality(b.points, annulus.triangles)
                <= shape_quality_bound(q0, np.full(len(q0), ell)) * (1 + 1e-9)).all()


def test_move_rejects_bad_input(annulus):
    b = np.unique(annulus.boundary_edges)
    with pytest.raises(InvalidMeshError, match="out of range"):
        move(annulus, np.array([annulus.n_vertices]), np.zeros((1, 2)))
    with pytest.raises(InvalidMeshError, match="not finite"):
        move(annulus, b[:2], np.array([[0.0, np.nan], [1.0, 1.0]]))
    with pytest.raises(InvalidMeshError, match="twice with different targets"):
        move(annulus, np.array([b[0], b[0]]), np.array([[0.0, 0.0], [1.0, 1.0]]))
    crossing = annulus.points[b].copy()
    inner = np.hypot(*crossing.T) < 0.5
    crossing[inner] += [0.9, 0.0]  # the hole's circle cuts the outer circle
    with pytest.raises(InvalidMeshError, match="cross itself"):
        move(annulus, b, crossing)


def test_move_reports_targets_without_admissible_interior(annulus):
    from meshopt_toolkit.motion.continuation import NoAdmissiblePathError

    b = np.unique(annulus.boundary_edges)
    outside = annulus.points[b].copy()
    inner = np.hypot(*outside.T) < 0.5
    outside[inner] *= 4.0  # the hole would enclose the outer circle: no mesh fits between
    with pytest.raises(NoAdmissiblePathError, match="no admissible"):
        move(annulus, b, outside, steps=2, max_splits=3)


# ------------------------------------------------------------------ morph
def test_morph_frames_stay_as_healthy_as_the_ends(annulus):
    """Every frame's min aspect ratio ≥ 0.9 × the worse end's, and never
    below linear or as-rigid-as-possible interpolation where those stay valid."""
    from meshopt_toolkit.generate import log_twist

    target = log_twist(annulus, 90)
    result = distortion_morph(annulus, target, frames=9)
    worse_end = min(aspect_ratios(annulus.points, annulus.triangles).min(),
                    aspect_ratios(target.points, target.triangles).min())
    assert result.converged
    assert (result.stats.inverted == 0).all()
    assert result.stats.min_aspect_ratio.min() >= 0.9 * worse_end
    for other in (result.linear, result.rigid):
        if (other.inverted == 0).all():
            assert result.stats.min_aspect_ratio.min() >= other.min_aspect_ratio.min() * (1 - 1e-9)
    q0 = inverse_shape_quality(annulus.points, annulus.triangles)
    for Q, ell in zip(result.points, result.strain_bound):  # the proven bound, every frame
        assert (inverse_shape_quality(Q, annulus.triangles)
                <= shape_quality_bound(q0, np.full(len(q0), ell)) * (1 + 1e-9)).all()


def test_move_filter_and_cli_agree(annulus, tmp_path):
    """The pipeline filter and ``meshopt move`` run the same operation."""
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import load, save
    from meshopt_toolkit.pipeline import Pipeline

    src = tmp_path / "annulus.msh"
    save(annulus, src)
    mapping = "x*cos(pi/3) - y*sin(pi/3); x*sin(pi/3) + y*cos(pi/3)"
    where = "x**2 + y**2 < 0.25"
    assert main(["move", str(src), "-o", str(tmp_path / "cli.msh"), "--map", mapping,
                 "--where", where]) == 0
    pipe = Pipeline.from_dict({"filters": [
        {"name": "apply_coord_prescribed_motion", "params": {"map": mapping, "where": where}}]})
    from meshopt_toolkit.pipeline import Document

    doc = Document()
    doc.add(annulus, name="annulus")
    pipe.run(doc)
    cli = load(tmp_path / "cli.msh")
    assert (cli.signed_areas() > 0).all()
    assert np.array_equal(doc.current_entry.mesh.points, cli.points)


def test_move_cli_errors_are_one_line(annulus, tmp_path, capsys):
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import save

    src = tmp_path / "annulus.msh"
    save(annulus, src)
    for extra, expected in ((["--map", "1/0; y"], "--map '1/0; y'"),
                            (["--map", "x; y +"], "--map 'x; y +': invalid syntax"),
                            (["--map", "x; q"], "--map 'x; q': unknown name 'q'"),
                            (["--map", "x; y", "--where", "x <"], "--where 'x <'"),
                            (["--map", "x; y", "--where", "z < 1"],
                             "--where 'z < 1': 'z': z is not defined for a planar mesh"),
                            (["--map", "x; y", "--frames", "1"], "--frames")):
        assert main(["move", str(src), "-o", str(tmp_path / "o.msh"), *extra]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expected in err[0] and "internal error" not in err[0]
        assert "syntax: invalid syntax" not in err[0]
    assert not (tmp_path / "o.msh").exists()

