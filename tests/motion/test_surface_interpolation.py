"""As-rigid-as-possible interpolation of two surface poses with local/global steps
(``motion/surface/interpolation.py``): the closed-form best rotations against the SVD,
a folded hinge followed exactly, the steps' energy never rising, rigid motions carried
along, and a bar twisted half a turn by libigl whose start is lifted to the target's
quality (no Levenberg–Marquardt step left to ``morph_surface``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from meshopt_toolkit.kernels.surface import aspect_ratios
from meshopt_toolkit.motion.surface.distortion import SurfaceDistortion
from meshopt_toolkit.motion.surface.interpolation import (
    _best_rotated,
    _plane_frames,
    arap_interpolation,
    continuous_rotation_vectors,
)
from meshopt_toolkit.motion.surface.morph import morph_surface
from meshopt_toolkit.motion.surface.folds import FoldTest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))


def sheet(nx=8, ny=4, width=2.0):
    """The rectangle [0, width]×[0, 1] in z = 0, a grid of squares cut in two."""
    x, y = np.meshgrid(np.linspace(0, width, nx + 1), np.linspace(0, 1, ny + 1), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    idx = np.arange(V.shape[0]).reshape(nx + 1, ny + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return V, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def unit_normals(X, F):
    n = np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])
    return n / np.linalg.norm(n, axis=1)[:, None]


def edge_lengths(X, F):
    return np.linalg.norm(X[F] - X[np.roll(F, 1, axis=1)], axis=2)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_closed_form_rotation_is_the_procrustes_optimum(seed):
    """R M for the best proper rotation R of |J − R M|, against the SVD with the sign
    of the last singular pair fixed (Umeyama)."""
    rng = np.random.default_rng(seed)
    J, M = rng.normal(size=(64, 3, 2)), rng.normal(size=(64, 3, 2))
    U, _, Vt = np.linalg.svd(J @ np.swapaxes(M, 1, 2))
    U[:, :, 2] *= np.sign(np.linalg.det(U @ Vt))[:, None]
    assert np.allclose(_best_rotated(J, _plane_frames(M)[2]), U @ Vt @ M, atol=1e-12)


@pytest.mark.parametrize("iterations", [0, 4])
@pytest.mark.parametrize("beta", [np.pi / 3, 0.9 * np.pi])
def test_folded_hinge_is_followed_exactly(beta, iterations):
    """Two panels of a sheet folded by β along x = 1: every rotation is about the hinge,
    the interpolated maps fit exactly, so the frame at t is the sheet folded by tβ
    (edge lengths of the source, the panels' normals tβ apart), with or without steps."""
    V0, F = sheet()
    c, s = np.cos(beta), np.sin(beta)
    V1 = V0.copy()
    right = V0[:, 0] > 1.0
    V1[right, 0], V1[right, 2] = 1.0 + c * (V0[right, 0] - 1.0), s * (V0[right, 0] - 1.0)
    times = np.linspace(0.0, 1.0, 6)
    centres = V0[F].mean(axis=1)[:, 0]
    for t, X in zip(times, arap_interpolation(V0, V1, F, times, iterations=iterations)):
        assert np.allclose(edge_lengths(X, F), edge_lengths(V0, F), atol=1e-9)
        n = unit_normals(X, F)
        assert np.allclose(n[centres < 1.0], n[0], atol=1e-9)
        assert np.allclose(n[centres > 1.0], n[-1], atol=1e-9)
        assert np.isclose(np.arccos(np.clip(n[0] @ n[-1], -1, 1)), t * beta, atol=1e-8)


def stretch(V0, V1, F):
    """Per triangle the symmetric factor S of A = R S (A the map of the source triangle,
    completed by its normal over √|n|, onto the target's): √(AᵀA), by eigh."""
    def frames(P):
        e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
        n = np.cross(e1, e2)
        return np.stack([e1, e2, n / np.sqrt(np.linalg.norm(n, axis=1))[:, None]], axis=2)

    A = frames(V1[F]) @ np.linalg.inv(frames(V0[F]))
    w, Q = np.linalg.eigh(np.swapaxes(A, 1, 2) @ A)
    return Q @ (np.sqrt(w)[:, :, None] * np.swapaxes(Q, 1, 2))


def arap_energy(V0, V1, F, t, X):
    """Σ a min_R |∇X − R M(t)|², M(t) = ((1 − t) I + t S) ∇X_0 (rank 2: the minimum is
    |J|² + |M|² − 2(σ₁ + σ₂) of J Mᵀ)."""
    dist = SurfaceDistortion(V0, F)
    M = ((1.0 - t) * np.eye(3) + t * stretch(V0, V1, F)) @ dist.affine_maps(V0)
    J = dist.affine_maps(X)
    sigma = np.linalg.svd(J @ np.swapaxes(M, 1, 2), compute_uv=False)
    P = V0[F]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    per = (J ** 2).sum(axis=(1, 2)) + (M ** 2).sum(axis=(1, 2)) - 2 * sigma[:, :2].sum(axis=1)
    return float(area @ per)


def random_pose(seed, V0):
    """A smooth random bend and stretch of the sheet, turned by a random rotation."""
    rng = np.random.default_rng(seed)
    k = rng.uniform(-2.5, 2.5, size=3)
    x, y = V0[:, 0], V0[:, 1]
    V1 = np.column_stack([x * (1 + 0.2 * k[2] * y), y, 0.3 * k[0] * x ** 2 + 0.3 * k[1] * x * y])
    return V1 @ Rotation.random(random_state=seed).as_matrix().T


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.1, 0.9))
def test_local_global_steps_never_raise_the_energy(seed, t):
    V0, F = sheet()
    V1 = random_pose(seed, V0)
    energies = [arap_energy(V0, V1, F, t, arap_interpolation(V0, V1, F, [t], iterations=k)[0])
                for k in range(5)]
    scale = energies[0] + 1e-12
    assert all(b <= a + 1e-12 * scale for a, b in zip(energies, energies[1:]))


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_rigid_motion_of_both_poses_moves_every_frame(seed):
    V0, F = sheet()
    V1 = random_pose(seed, V0)
    Q = Rotation.random(random_state=(seed + 1) % 2**32).as_matrix()
    c = np.random.default_rng(seed).normal(size=3)
    times = np.linspace(0.0, 1.0, 5)
    plain = arap_interpolation(V0, V1, F, times, iterations=3)
    moved = arap_interpolation(V0 @ Q.T + c, V1 @ Q.T + c, F, times, iterations=3)
    for X, Y in zip(plain, moved):
        assert np.allclose(X @ Q.T + c, Y, atol=1e-9)


def test_steps_end_where_until_accepts():
    """``until`` is asked before each step: True at once leaves Alexa et al.'s fit bitwise,
    True after k asks gives k steps."""
    V0, F = sheet()
    V1 = random_pose(7, V0)
    times = np.linspace(0.0, 1.0, 5)
    plain = arap_interpolation(V0, V1, F, times)
    assert all(np.array_equal(a, b) for a, b in
               zip(plain, arap_interpolation(V0, V1, F, times, iterations=10,
                                             until=lambda frames: True)))
    asked = []
    after_two = arap_interpolation(V0, V1, F, times, iterations=10,
                                   until=lambda frames: asked.append(1) or len(asked) > 2)
    assert len(asked) == 3
    assert all(np.array_equal(a, b) for a, b in
               zip(after_two, arap_interpolation(V0, V1, F, times, iterations=2)))


def test_a_step_with_a_degenerate_triangle_is_not_taken(monkeypatch):
    """Where the closed-form rotation is undefined (a triangle of a frame degenerate), the
    frames of the last step are kept."""
    import meshopt_toolkit.motion.surface.interpolation as si

    V0, F = sheet()
    V1 = random_pose(11, V0)
    times = np.linspace(0.0, 1.0, 5)
    one = arap_interpolation(V0, V1, F, times, iterations=1)
    calls = []
    real = si._best_rotated

    def second_step_degenerates(J, m):
        calls.append(1)
        out = real(J, m)
        if len(calls) > len(times) - 2:  # every frame of the second step
            out[0] = np.nan
        return out

    monkeypatch.setattr(si, "_best_rotated", second_step_degenerates)
    kept = arap_interpolation(V0, V1, F, times, iterations=5)
    assert all(np.array_equal(a, b) for a, b in zip(one, kept))


def test_morph_falls_back_to_the_fit_without_steps(monkeypatch):
    """Where the stepped start is not admissible, ``morph_surface`` starts from Alexa et
    al.'s fit without steps, not from linear interpolation."""
    import meshopt_toolkit.motion.surface.morph as smorph

    V0, F = sheet()
    V1 = random_pose(5, V0)
    asked = []

    def collapsed_when_stepped(*args, iterations=0, until=None):
        asked.append(iterations)
        frames = arap_interpolation(*args, iterations=iterations, until=until)
        if iterations:
            frames[1:-1] = [np.zeros_like(X) for X in frames[1:-1]]  # degenerate frames
        return frames

    monkeypatch.setattr(smorph, "arap_interpolation", collapsed_when_stepped)
    r = smorph.morph_surface(V0, V1, F, 5)
    assert asked == [smorph.START_ITERATIONS, 0] and r.initial_path == "arap"
    assert r.folds.sum() == 0


@pytest.fixture(scope="module")
def libigl_bar():
    """A 3×1×1 box (spacing 0.1), the cap x = 3 turned 180° by libigl ARAP in 10 steps of
    50 iterations (as bench_surface.py): the twist stays near the turned cap."""
    igl = pytest.importorskip("igl")
    import bench_surface as bench

    V, F = bench.box_surface([3.0, 1.0, 1.0], 0.1)
    fixed, end = np.flatnonzero(V[:, 0] < 1e-9), np.flatnonzero(V[:, 0] > 3.0 - 1e-9)
    data = igl.ARAPData()
    data.max_iter = 50
    igl.arap_precomputation(V, F, 3, np.concatenate([end, fixed]).astype(np.int32), data)
    U = V.copy()
    for k in range(1, 11):
        turned = bench.turning(V[end], np.array([3.0, 0.5, 0.5]), [1, 0, 0], np.pi)(k / 10)
        U = np.asarray(igl.arap_solve(np.concatenate([turned, V[fixed]]), data, U))
    return V, F, U


def test_half_turned_bar_start_is_lifted_to_the_target(libigl_bar):
    V0, F, V1 = libigl_bar
    q0, folds = aspect_ratios(V0, F), FoldTest(V0, F)
    floor = float((aspect_ratios(V1, F) / q0).min())
    times = np.linspace(0.0, 1.0, 9)
    worst = [float((aspect_ratios(X, F) / q0).min())
             for X in arap_interpolation(V0, V1, F, times)[1:-1]]
    assert min(worst) < floor - 0.03  # the frames Alexa et al.'s rotations give dip
    lifted = arap_interpolation(V0, V1, F, times, iterations=10, until=lambda frames: all(
        (aspect_ratios(X, F) / q0).min() >= floor for X in frames[1:-1]))
    for X in lifted[1:-1]:
        assert float((aspect_ratios(X, F) / q0).min()) >= floor
        assert not folds.mask(X).any()
    # all frames took the same steps, the fewest that lift every frame to the floor
    lowest = [min(float((aspect_ratios(X, F) / q0).min()) for X in
                  arap_interpolation(V0, V1, F, times, iterations=k)[1:-1]) for k in range(11)]
    k = next(k for k, q in enumerate(lowest) if q >= floor)
    assert k >= 2
    assert all(np.array_equal(a, b) for a, b in
               zip(lifted, arap_interpolation(V0, V1, F, times, iterations=k)))
    r = morph_surface(V0, V1, F, 9)
    assert r.status == "healthy" and r.iterations == 0 and r.factorizations == 0
    assert r.worst_quality.min() >= floor and r.folds.sum() == 0
    assert all(np.array_equal(a, b) for a, b in zip(r.points, lifted))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), turns=st.floats(0.2, 1.6))
def test_continuous_rotation_vectors_follow_a_turn_past_half_a_turn(seed, turns):
    """A field of turns growing along a strip to ``turns`` full turns about a tilted axis,
    given by its principal rotation vectors (angles in [0, π]): the chosen branches are
    the same rotations and the field itself, angles beyond π included (closed form), up to
    one whole number of turns for all (the least turned triangle turns less than π)."""
    rng = np.random.default_rng(seed)
    V, F = sheet(nx=60, ny=3, width=6.0)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    x = V[F].mean(axis=1)[:, 0]
    true = (2.0 * np.pi * turns * x / 6.0)[:, None] * axis
    principal = Rotation.from_rotvec(true).as_rotvec()
    out = continuous_rotation_vectors(principal, V, F)
    whole = np.round((out - true) @ axis / (2.0 * np.pi))
    assert np.all(whole == whole[0])
    np.testing.assert_allclose(out, true + (2.0 * np.pi * whole)[:, None] * axis, atol=1e-9)
    assert np.linalg.norm(out, axis=1).min() < np.pi
    same = Rotation.from_rotvec(out).inv() * Rotation.from_rotvec(principal)
    assert np.all(same.magnitude() < 1e-9)


def twisted_box(degrees: float, power: float = 3.0):
    """bench_surface's box surface 3×1×1 (spacing 0.1) and its pose twisted about the long
    axis by ``degrees · (x/3)^power``."""
    import bench_surface as bench

    V, F = bench.box_surface([3.0, 1.0, 1.0], 0.1)
    a = np.deg2rad(degrees) * (V[:, 0] / 3.0) ** power
    y, z = V[:, 1] - 0.5, V[:, 2] - 0.5
    T = V.copy()
    T[:, 1], T[:, 2] = 0.5 + np.cos(a) * y - np.sin(a) * z, 0.5 + np.sin(a) * y + np.cos(a) * z
    return V, T, F


@pytest.mark.parametrize("degrees", [225.0, 270.0])
def test_a_box_twisted_past_half_a_turn_is_morphed(degrees):
    """Twisted by 225° and 270° at the far end, most of the twist near it: the residual
    turns pass half a turn, which the principal rotation vectors would interpolate the
    other way round (both interpolations fold); every frame is healthy and fold-free."""
    pytest.importorskip("trimesh")
    V, T, F = twisted_box(degrees)
    morph = morph_surface(V, T, F, 9)
    rest = aspect_ratios(V, F)
    floor = (aspect_ratios(T, F) / rest).min()
    folds = FoldTest(V, F)
    for X in morph.points:
        assert (aspect_ratios(X, F) / rest).min() >= floor - 1e-12
        assert not folds.mask(X).any()


@pytest.mark.parametrize("iterations", [0, 3])
def test_pieces_translated_apart_move_each_along_its_line(iterations):
    """Two pieces (a sheet and an upright flap above it), the flap lowered and the sheet
    shifted sideways: each piece's frames are its own translation at time t. (The
    Laplacian leaves each piece's translation free: one vertex of each is pinned.)"""
    x = np.linspace(0.0, 1.0, 4)
    U, W = (a.ravel() for a in np.meshgrid(x, x, indexing="ij"))
    idx = np.arange(16).reshape(4, 4)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.vstack([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    sheet = np.c_[U, W, np.zeros(16)]
    flap = np.c_[0.3 + 0.4 * U, np.full(16, 0.5), 0.5 + W]
    V0 = np.vstack([sheet, flap])
    shift = np.r_[np.tile([0.2, -0.1, 0.0], (16, 1)), np.tile([0.0, 0.0, -0.4], (16, 1))]
    V1 = V0 + shift
    times = np.linspace(0.0, 1.0, 5)
    frames = arap_interpolation(V0, V1, np.vstack([F, F + 16]), times, iterations=iterations)
    for t, X in zip(times, frames):
        np.testing.assert_allclose(X, V0 + t * shift, atol=1e-9)
