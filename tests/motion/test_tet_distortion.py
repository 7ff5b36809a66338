"""The per-tet distortion φ, its derivatives, its graph metric and its proven bounds.

References are independent of the code under test: singular values (SVD of the edge
matrices), exact rational arithmetic for the mean ratio, central finite differences for
the assembled Jacobian; invariants and bounds on random meshes, motions and paths.
"""

from __future__ import annotations

from fractions import Fraction
from itertools import permutations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from motion_helpers import distortion_functional, random_rotation, rates

from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.kernels.cell_maps import REGULAR_TET_EDGES, tet_condition_numbers
from meshopt_toolkit.kernels.tetrahedra import mean_ratios, signed_volumes
from meshopt_toolkit.motion.tets.distortion import (
    TetDistortion,
    hencky_strains,
    sym_vec,
    tet_condition_bound,
    tet_path_condition_bound,
    tet_path_quality_bound,
    tet_quality_bound,
)
from meshopt_toolkit.motion.tets.metric import TetGraphMetric

FAST = settings(max_examples=12, deadline=None)


def cube_tets(n: int = 2, jitter: float = 0.25, seed: int = 0):
    """[0, 1]³ in n³ cubes of 6 Kuhn tets each (positively oriented), inner nodes jittered."""
    x = np.linspace(0.0, 1.0, n + 1)
    pts = np.stack(np.meshgrid(x, x, x, indexing="ij"), -1).reshape(-1, 3)
    inner = ((pts > 0) & (pts < 1)).all(1)
    pts[inner] += jitter / n * np.random.default_rng(seed).uniform(-1, 1, (inner.sum(), 3))
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    tets = []
    for i, j, k in np.ndindex(n, n, n):
        for perm in permutations(range(3)):
            corner, path = np.array([i, j, k]), [idx[i, j, k]]
            for axis in perm:
                corner[axis] += 1
                path.append(idx[tuple(corner)])
            tets.append(path)
    tets = np.array(tets)
    flip = signed_volumes(pts, tets) < 0
    tets[flip] = tets[flip][:, [1, 0, 2, 3]]
    return pts, tets


def random_admissible(points, tets, rng, amplitude):
    """An affine image (``A = I + a·B``, ``‖B‖₂ < 1``) plus noise halved until no tet inverts."""
    A = np.eye(3) + amplitude * rng.uniform(-0.5, 0.5, (3, 3)) / 1.5
    Q = points @ A.T + rng.uniform(-1, 1, 3)
    noise = 0.1 * amplitude * rng.standard_normal(Q.shape) / len(points) ** (1 / 3)
    while not (signed_volumes(Q + noise, tets) > 0).all():
        noise /= 2
    return Q + noise


def singular_values(P, Q, tets):
    D0 = np.stack([P[tets[:, j]] - P[tets[:, 0]] for j in (1, 2, 3)], axis=2)
    D1 = np.stack([Q[tets[:, j]] - Q[tets[:, 0]] for j in (1, 2, 3)], axis=2)
    return np.linalg.svd(D1 @ np.linalg.inv(D0))


@pytest.fixture(scope="module")
def mesh():
    return cube_tets(2, 0.25)


# ------------------------------------------------------------------ values
def test_values_are_sinh_of_the_log_strain(mesh, rng):
    """φ = (log det A/√3, vec(V sinh(2x) Vᵀ)/2), x = log σ − mean log σ, from the SVD."""
    P, T = mesh
    Q = random_admissible(P, T, rng, 0.6)
    phi = TetDistortion(P, T).values(Q)
    _, s, Vt = singular_values(P, Q, T)
    logs = np.log(s)
    np.testing.assert_allclose(np.sqrt(3) * phi[:, 0], logs.sum(1), atol=1e-12)
    x = logs - logs.mean(1, keepdims=True)
    Phi = np.einsum("tki,tk,tkj->tij", Vt, np.sinh(2 * x), Vt)
    np.testing.assert_allclose(phi[:, 1:], sym_vec(Phi) / 2, atol=1e-11)


def test_values_at_the_reference_are_zero_and_reference_is_checked(mesh):
    P, T = mesh
    assert np.abs(TetDistortion(P, T).values(P)).max() < 1e-13
    with pytest.raises(InvalidMeshError, match="tet 3"):
        TetDistortion(P, np.concatenate([T[:3], T[3:4, [1, 0, 2, 3]]]))


# ------------------------------------------------------------------ derivatives
@pytest.mark.parametrize("at_reference", [True, False])
def test_jacobian_and_second_order_taylor(mesh, rng, at_reference):
    P, T = mesh
    dist = TetDistortion(P, T)
    Q = P.copy() if at_reference else random_admissible(P, T, rng, 0.5)
    f, grad, hvp = distortion_functional(dist, rng.standard_normal((len(T), 7)), dist.columns())
    first = check_gradient(f, grad, Q, eps0=1e-3, rng=rng)
    assert abs(first.order - 2) < 0.2, first
    second = check_hvp(f, grad, hvp, Q, eps0=1e-3, rng=rng)
    assert second.order > 2.8, second  # a wrong Hessian gives 2; a tiny cubic term > 3
    H = dist.second_order(Q, rng.standard_normal((len(T), 7)))
    assert np.abs(H - np.swapaxes(H, 1, 2)).max() <= 1e-12 * np.abs(H).max()


def test_assembled_jacobian_and_metric_match_finite_differences(rng):
    """J from COO index arrays and (M + w²JᵀJ)V, against a dense central-difference J."""
    P, T = cube_tets(1, 0.0)
    metric = TetGraphMetric(P, T, weight=1.7)
    Q = random_admissible(P, T, rng, 0.4)
    h, x = 1e-6, Q.ravel()
    J_fd = np.empty((7 * len(T), x.size))
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = h
        J_fd[:, k] = (metric.strain.values((x + e).reshape(Q.shape)).ravel()
                      - metric.strain.values((x - e).reshape(Q.shape)).ravel()) / (2 * h)
    J = metric.jacobian(Q).toarray()
    assert np.abs(J - J_fd).max() < 1e-7 * np.abs(J).max()
    V = rng.standard_normal(Q.shape)
    expected = np.repeat(metric.mass, 3) * V.ravel() + 1.7**2 * J_fd.T @ (J_fd @ V.ravel())
    np.testing.assert_allclose(metric.apply(Q, V).ravel(), expected, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(metric.matrix(Q) @ V.ravel(), metric.apply(Q, V).ravel(), rtol=1e-12)
    # the lumped mass: Σ m_i = 1/spread, Σ m_i |v_i − centroid|² = 1
    c = (metric.mass @ P) / metric.mass.sum()
    assert abs(metric.mass @ np.sum((P - c) ** 2, axis=1) - 1) < 1e-12


@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.0, 0.8))
def test_metric_dominates_half_the_affine_invariant_metric(seed, amplitude):
    """|J V| ≥ ½‖C^{-½} Ċ C^{-½}‖_F for every tet (equality at the reference): the lemma
    behind every path bound."""
    P, T = cube_tets(1, 0.2, seed)
    rng = np.random.default_rng(seed)
    dist = TetDistortion(P, T)
    Q = random_admissible(P, T, rng, amplitude) if amplitude else P
    rate, affine = rates(dist, Q, rng.standard_normal(Q.shape))
    assert (rate >= affine * (1 - 1e-10)).all()
    if not amplitude:
        np.testing.assert_allclose(rate, affine, rtol=1e-10)


# ------------------------------------------------------------------ invariances
@FAST
@given(scale=st.floats(0.01, 100), shift=st.tuples(*[st.floats(-1e3, 1e3)] * 3),
       seed=st.integers(0, 2**16))
def test_rotations_and_translations_leave_phi_and_scaling_moves_the_volume_part(scale, shift, seed):
    P, T = cube_tets(1, 0.2, seed)
    rng = np.random.default_rng(seed)
    dist = TetDistortion(P, T)
    Q = random_admissible(P, T, rng, 0.5)
    phi = dist.values(Q)
    moved = dist.values(scale * Q @ random_rotation(rng).T + np.asarray(shift))
    np.testing.assert_allclose(moved[:, 1:], phi[:, 1:], atol=1e-9 * (1 + np.abs(phi).max()))
    np.testing.assert_allclose(moved[:, 0] - phi[:, 0], np.sqrt(3) * np.log(scale), atol=1e-9)
    # infinitesimally: J (ω × Q) = 0 and J Q = (√3, 0, …, 0) in every tet
    _, blocks = dist.values_and_jacobian(Q)
    cols = dist.columns()
    W = rng.standard_normal((3, 3))
    for V, expected in ((Q @ (W - W.T).T, 0.0), (Q, np.sqrt(3))):
        rate = np.einsum("tij,tj->ti", blocks, V.ravel()[cols])
        np.testing.assert_allclose(rate[:, 0], expected, atol=1e-9)
        assert np.abs(rate[:, 1:]).max() < 1e-9 * (1 + np.abs(blocks).max())


def test_barrier_blows_up_when_a_tet_flattens_or_becomes_a_needle(mesh):
    P, T = mesh
    dist = TetDistortion(P, T)
    t = T[7]
    foot = P[t[1:]].mean(0)  # a point in the plane of the opposite face
    norms = []
    for gap in 10.0 ** -np.arange(1, 7):
        Q = P.copy()
        Q[t[0]] = foot + gap * (P[t[0]] - foot)
        norms.append(np.linalg.norm(dist.values(Q)[7]))
    assert np.all(np.diff(norms) > 0) and norms[-1] > 1e4
    Q = P.copy()
    Q[t[0]] = foot
    assert np.isinf(dist.values(Q)[7]).all()
    # volume kept, shape degenerating: only the shape part grows, without bound
    for s, floor in ((10.0, 20.0), (1e3, 2e5)):
        phi = dist.values(P @ np.diag([s, s, 1 / s**2]))
        assert np.abs(phi[:, 0]).max() < 1e-12
        assert (np.linalg.norm(phi[:, 1:], axis=1) > floor).all()


# ------------------------------------------------------------------ quality bounds
def test_mean_ratio_and_condition_number_closed_forms():
    """Regular tets score 1; η³ of rational tets equals the exact rational value."""
    R = np.linalg.qr(np.random.default_rng(3).standard_normal((3, 3)))[0]
    regular = np.vstack([np.zeros(3), REGULAR_TET_EDGES.T]) @ R.T * 2.5 + 1.0
    tet = np.array([[0, 1, 2, 3]]) if np.linalg.det(R) > 0 else np.array([[1, 0, 2, 3]])
    np.testing.assert_allclose(mean_ratios(regular, tet), 1.0, rtol=1e-12)
    np.testing.assert_allclose(tet_condition_numbers(regular, tet), 1.0, rtol=1e-12)
    pts = [[0, 0, 0], [3, 0, 0], [1, 2, 0], [1, 1, 5]]
    F = [[Fraction(c) for c in p] for p in pts]
    sq = sum(sum((F[i][k] - F[j][k]) ** 2 for k in range(3)) for i in range(4) for j in range(i))
    e = [[F[j][k] - F[0][k] for k in range(3)] for j in (1, 2, 3)]
    det6 = (e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2]
            - e[1][2] * e[2][0]) + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]))
    exact_cube = Fraction(12) ** 3 * (det6 / 2) ** 2 / sq**3  # η³ = 12³ (3V)² / (Σℓ²)³
    eta = mean_ratios(np.array(pts, float), np.array([[0, 1, 2, 3]]))[0]
    assert abs(eta**3 - float(exact_cube)) < 1e-14


@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.01, 0.9))
def test_quality_bounds_from_the_reference_hold_for_every_tet(seed, amplitude):
    P, T = cube_tets(2, 0.3, seed)
    rng = np.random.default_rng(seed)
    Q = random_admissible(P, T, rng, amplitude)
    dist = TetDistortion(P, T)
    change = np.linalg.norm(dist.values(Q), axis=1)
    assert (hencky_strains(dist.affine_maps(Q)) <= change * (1 + 1e-12) + 1e-15).all()
    eta0, kappa0 = mean_ratios(P, T), tet_condition_numbers(P, T)
    assert (mean_ratios(Q, T) >= tet_quality_bound(eta0, change) * (1 - 1e-12)).all()
    assert (tet_condition_numbers(Q, T) <= tet_condition_bound(kappa0, change) * (1 + 1e-12)).all()


@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.05, 0.8), weight=st.floats(0.2, 5))
def test_random_paths_keep_every_tet_above_its_bound(seed, amplitude, weight):
    """Along a piecewise-linear path from the reference, each tet's summed increments
    ``S_k = Σ |φ(Q_{i+1}) − φ(Q_i)| ≥ |φ(Q_k)|`` are at most ℓ_k/w, and bound its quality.
    From a start other than the reference, the tet's Hencky strain relative to the start
    is at most its φ-length (``S`` of a fine subdivision; ``S`` underestimates the length
    by O(h²), the 1e-3 slack)."""
    P, T = cube_tets(1, 0.3, seed)
    rng = np.random.default_rng(seed)
    nodes = [P] + [random_admissible(P, T, rng, amplitude) for _ in range(3)]
    steps = np.linspace(0, 1, 17)[1:]
    frames = [P] + [a + s * (b - a) for a, b in zip(nodes[:-1], nodes[1:]) for s in steps]
    frames = [Q for Q in frames if (signed_volumes(Q, T) > 0).all()]
    metric = TetGraphMetric(P, T, weight)
    phis = np.array([metric.strain.values(Q) for Q in frames])
    S = np.concatenate([np.zeros((1, len(T))),
                        np.cumsum(np.linalg.norm(np.diff(phis, axis=0), axis=2), axis=0)])
    ell = np.concatenate([[0.0], np.cumsum(metric.segment_lengths(np.array(frames)))])
    assert (S <= ell[:, None] / weight * (1 + 1e-12) + 1e-14).all()
    eta0, kappa0 = mean_ratios(P, T), tet_condition_numbers(P, T)
    for k, Q in enumerate(frames):
        assert (mean_ratios(Q, T) >= tet_quality_bound(eta0, S[k]) * (1 - 1e-12)).all()
        kappa = tet_condition_numbers(Q, T)
        assert (kappa <= tet_condition_bound(kappa0, S[k]) * (1 + 1e-12)).all()
    start = len(frames) // 3  # a start that is not the reference
    A_start = metric.strain.affine_maps(frames[start])
    eta_s, kappa_s = mean_ratios(frames[start], T), tet_condition_numbers(frames[start], T)
    for k in range(start, len(frames)):
        L = S[k] - S[start]
        B = metric.strain.affine_maps(frames[k]) @ np.linalg.inv(A_start)
        assert (hencky_strains(B) <= L * (1 + 1e-3) + 1e-12).all()
        eta = mean_ratios(frames[k], T)
        assert (eta >= tet_path_quality_bound(eta_s, L * (1 + 1e-3))).all()
        assert (tet_condition_numbers(frames[k], T)
                <= tet_path_condition_bound(kappa_s, L * (1 + 1e-3)) * (1 + 1e-12)).all()


@pytest.mark.parametrize("u", [0.05, 0.7, 3.0])
def test_condition_bound_is_attained_by_a_volume_keeping_stretch(u):
    """For ``A = R diag(e^u, 1, e^{-u})`` the bound ``κ(A) ≤ exp(asinh(√2|φ|))`` is an
    equality: the constant cannot be improved."""
    P, T = cube_tets(1, 0.0)
    R = random_rotation(np.random.default_rng(1))
    Q = P @ (R @ np.diag([np.exp(u), 1.0, np.exp(-u)]) @ R.T).T
    phi = TetDistortion(P, T).values(Q)
    kappa = np.linalg.cond(TetDistortion(P, T).affine_maps(Q))
    np.testing.assert_allclose(tet_condition_bound(1.0, np.linalg.norm(phi, axis=1)), kappa,
                               rtol=1e-10)


@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.0, 0.9))
def test_distortion_from_regular_tets_bounds_absolute_quality(seed, amplitude):
    """Against regular tets of the same volumes: φ_0 = 0 at the mesh itself, φ = 0 exactly
    for regular tets, and η(Q) ≥ exp(−asinh(2|φ(Q)|)) for every tet."""
    P, T = cube_tets(1, 0.3, seed)
    rng = np.random.default_rng(seed)
    Q = random_admissible(P, T, rng, amplitude) if amplitude else P
    dist = TetDistortion.regular(Q, T)
    assert np.array_equal(dist.reference, Q) and dist.n_vertices == len(Q)
    phi = dist.values(Q)
    assert np.abs(phi[:, 0]).max() < 1e-12
    assert (mean_ratios(Q, T) >= tet_quality_bound(1.0, np.linalg.norm(phi, axis=1))
            * (1 - 1e-12)).all()
    R = random_rotation(rng)
    regular = (np.vstack([np.zeros(3), REGULAR_TET_EDGES.T]) @ R.T) * (1 + amplitude)
    tet = np.array([[0, 1, 2, 3]])
    assert np.abs(TetDistortion.regular(regular, tet).values(regular)).max() < 1e-12


@pytest.mark.parametrize("length, u", [(1e2, 2.0), (1e3, 3.0)])
def test_mean_ratio_bound_is_attained_in_the_limit(length, u):
    """A needle stretched along its axis by ``diag(e^{2u}, e^{-u}, e^{-u})``: η approaches
    ``η₀ exp(−asinh(2|φ|))`` as the needle and the stretch grow (the constant 2 is sharp)."""
    P = np.vstack([np.zeros(3), REGULAR_TET_EDGES.T]) @ np.diag([length, 1.0, 1.0])
    Q = P @ np.diag([np.exp(2 * u), np.exp(-u), np.exp(-u)])
    T = np.array([[0, 1, 2, 3]])
    change = np.linalg.norm(TetDistortion(P, T).values(Q), axis=1)
    ratio = mean_ratios(Q, T) / tet_quality_bound(mean_ratios(P, T), change)
    assert 1.0 <= ratio[0] < 1.001


@pytest.mark.parametrize("stretch, needle", [((1.0, 0.0, -1.0), 1.0), ((2.0, -1.0, -1.0), 1e3)])
def test_path_bounds_are_attained_for_small_stretches(stretch, needle):
    """``A(t) = exp(t·u·diag(stretch))`` from the reference, u small: the φ-length is the
    Hencky strain to first order, so ``κ ≤ κ₀ e^{√2 L}`` (stretch (1, 0, −1)) and, on a
    needle along the first axis, ``η ≥ η₀ e^{−2√(2/3) L}`` (stretch (2, −1, −1)) are
    equalities up to O(u²)."""
    u = 0.02
    P = np.vstack([np.zeros(3), REGULAR_TET_EDGES.T]) @ np.diag([needle, 1.0, 1.0])
    T = np.array([[0, 1, 2, 3]])
    dist = TetDistortion(P, T)
    frames = [P @ np.diag(np.exp(t * u * np.array(stretch))) for t in np.linspace(0, 1, 65)]
    phis = np.array([dist.values(Q)[0] for Q in frames])
    L = np.linalg.norm(np.diff(phis, axis=0), axis=1).sum()
    kappa_bound = tet_path_condition_bound(tet_condition_numbers(P, T), L)
    kappa_ratio = kappa_bound / tet_condition_numbers(frames[-1], T)
    eta_ratio = mean_ratios(frames[-1], T) / tet_path_quality_bound(mean_ratios(P, T), L)
    assert kappa_ratio[0] >= 1 and eta_ratio[0] >= 1
    assert min(kappa_ratio[0], eta_ratio[0]) < 1 + 4 * u**2
