"""move_surface: handles exact, rigid motions followed exactly, the twisted bar against
libigl ARAP, the bending energy's derivatives and the stated bounds."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.errors import InvalidMeshError, NotAdmissibleError
from meshopt_toolkit.kernels.cell_maps import surface_inverse_shape_quality
from meshopt_toolkit.motion.surface.bending import (ShellBending, diamonds_and_triangles,
                                                    dihedral_angles, edge_diamonds)
from meshopt_toolkit.motion.surface.distortion import SurfaceDistortion, surface_quality_bound
from meshopt_toolkit.motion.surface.move import SurfaceMoveOptions, move_surface
from meshopt_toolkit.motion.engine.similarity import HandlePath, handle_groups
from meshopt_toolkit.motion.surface.folds import FoldTest, best_rotations

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
import _surface_measures as sm  # noqa: E402
import bench_surface as bench  # noqa: E402


def random_rotation(rng) -> np.ndarray:
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q *= np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1
    return Q


def sphere(subdivisions=2):
    trimesh = pytest.importorskip("trimesh")
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def coarse_bar(angle_deg: float, spacing: float = 0.25) -> bench.Case:
    """bench_surface's bar (6×1×1, one cap turned about the long axis), coarser."""
    V, F = bench.box_surface([6.0, 1.0, 1.0], spacing)
    fixed = np.flatnonzero(V[:, 0] < 1e-9)
    end = np.flatnonzero(V[:, 0] > 6.0 - 1e-9)
    moved = bench.turning(V[end], np.array([6.0, 0.5, 0.5]), [1, 0, 0], np.deg2rad(angle_deg))
    b = np.concatenate([end, fixed])
    return bench.Case("bar", V, F, b, lambda t: np.concatenate([moved(t), V[fixed]]),
                      np.r_[np.ones(len(end)), np.zeros(len(fixed))])


@pytest.fixture(scope="module")
def bar90():
    case = coarse_bar(90.0)
    return case, move_surface(case.V, case.F, case.handles, case.path(1.0), steps=4)


def test_handles_land_bitwise_and_nothing_folds(bar90):
    case, r = bar90
    assert np.array_equal(r.points[case.handles], case.path(1.0))
    assert r.handle_error == 0.0
    assert sm.fold_count(case.V, r.points, case.F, case.handles) == 0 == r.folds
    s = r.summary()
    assert s["worst_relative_quality"] == pytest.approx(
        sm.worst_relative_quality(case.V, r.points, case.F, case.handles), rel=1e-12)
    assert s["steps"] == 4 and s["seconds"] > 0


def test_rigid_motion_of_all_handles_is_followed_exactly():
    V, F = sphere(2)
    rng = np.random.default_rng(3)
    R, b = random_rotation(rng), rng.normal(size=3)
    handles = np.flatnonzero(V[:, 2] > 0.6)  # a cap, so the free part has to follow
    r = move_surface(V, F, handles, V[handles] @ R.T + b, steps=3)
    assert np.abs(r.points - (V @ R.T + b)).max() < 1e-12
    assert r.worst_quality == pytest.approx(1.0, abs=1e-12)


def test_separate_handle_groups_moved_by_one_similarity_keep_the_shape():
    V, F = sphere(2)
    handles = np.flatnonzero(np.abs(V[:, 2]) > 0.8)  # two caps: two groups
    assert len(handle_groups(handles, F, len(V))) == 2
    R = bench.rotation([1, 2, 0.5], 1.0)
    r = move_surface(V, F, handles, 1.5 * V[handles] @ R.T, steps=2)
    assert np.abs(r.points - 1.5 * V @ R.T).max() < 1e-12


def test_bar_twisted_180_beats_libigl_arap_single_shot():
    case = coarse_bar(180.0)
    r = move_surface(case.V, case.F, case.handles, case.path(1.0))
    q = sm.worst_relative_quality(case.V, r.points, case.F, case.handles)
    assert sm.fold_count(case.V, r.points, case.F, case.handles) == 0
    try:
        import igl  # noqa: F401
    except ImportError:
        assert q > 0.5  # libigl ARAP single shot gets 0.27 with a fold on this bar
        return
    arap = bench.arap_single(case)
    arap10 = bench.arap_incremental(case)
    assert q > sm.worst_relative_quality(case.V, arap, case.F, case.handles)
    assert q >= sm.worst_relative_quality(case.V, arap10, case.F, case.handles)
    assert sm.arap_energy(case.V, r.points, case.F) <= 1.5 * sm.arap_energy(case.V, arap10, case.F)


def test_bending_gradient_and_jacobian_taylor():
    V, F = sphere(2)
    rng = np.random.default_rng(0)
    Q = V + 0.05 * rng.normal(size=V.shape)
    shell = ShellBending(V, F)
    assert check_gradient(shell.energy, shell.gradient, Q).passed
    c = rng.normal(size=len(shell.diamonds))  # the Jacobian through a random combination
    assert check_gradient(lambda X: float(c @ shell.residuals(X)),
                          lambda X: (shell.jacobian_matrix(X).T @ c).reshape(-1, 3), Q).passed


@pytest.mark.parametrize("alpha", [0.3, 1.0, np.pi / 2, 2.5])
def test_dihedral_angle_of_a_hinge_is_pi_minus_its_opening(alpha):
    # two unit right triangles on the edge (0,0,0)–(1,0,0), opening α between them
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, np.cos(alpha), np.sin(alpha)]], float)
    F = np.array([[0, 1, 2], [1, 0, 3]])
    D = edge_diamonds(F)
    assert D.tolist() == [[0, 1, 2, 3]]
    assert abs(dihedral_angles(V, D)[0]) == pytest.approx(np.pi - alpha, abs=1e-14)


def test_diamonds_cover_interior_edges_only():
    V, F = sphere(1)
    assert len(edge_diamonds(F)) == 3 * len(F) // 2
    open_F = F[V[F].mean(axis=1)[:, 2] < 0.5]  # a sphere with a hole
    E = np.concatenate([open_F[:, [0, 1]], open_F[:, [1, 2]], open_F[:, [2, 0]]])
    _, counts = np.unique(np.sort(E, axis=1), axis=0, return_counts=True)
    assert len(edge_diamonds(open_F)) == int(np.sum(counts == 2))


def test_each_diamond_names_the_triangles_that_hold_its_half_edges():
    """Triangle ``t1`` holds i→j with corner k, ``t2`` holds j→i with corner l (as cyclic
    orders of their rows), on a sphere with a hole."""
    V, F = sphere(1)
    F = F[V[F].mean(axis=1)[:, 2] < 0.5]
    D, T = diamonds_and_triangles(F)
    assert np.array_equal(D, edge_diamonds(F)) and len(D)

    def rolls(rows):  # the three cyclic orders of each row
        return [np.roll(rows, -r, axis=1) for r in range(3)]

    for corners, t in ((D[:, [0, 1, 2]], T[:, 0]), (D[:, [1, 0, 3]], T[:, 1])):
        assert np.any([np.all(r == corners, axis=1) for r in rolls(F[t])], axis=0).all()


def test_fold_test_agrees_with_the_benchmark_measure():
    V, F = sphere(2)
    rng = np.random.default_rng(5)
    fold = FoldTest(V, F)
    for scale in (0.02, 0.1, 0.3):
        Q = V @ random_rotation(rng).T + scale * rng.normal(size=V.shape)
        assert np.array_equal(fold.mask(Q), sm.fold_mask(V, Q, F))


def test_handle_path_interpolates_the_rotation_angle():
    V, F = sphere(2)
    handles = np.flatnonzero(V[:, 2] > 0.6)
    R = bench.rotation([0, 0, 1], 2.0)
    path = HandlePath(V[handles], V[handles] @ R.T, [np.arange(len(handles))], motion="screw")
    assert np.array_equal(path(1.0), V[handles] @ R.T)
    assert np.allclose(path(0.0), V[handles], atol=1e-14)
    assert np.allclose(path(0.5), V[handles] @ bench.rotation([0, 0, 1], 1.0).T, atol=1e-12)


def test_handle_path_turns_about_the_hinge_along_the_arc():
    """A group turned about an axis line off its centroid travels along the arc about that
    line (closed form), not along the chord; a shift along the axis is added linearly."""
    V, F = sphere(2)
    handles = np.flatnonzero(V[:, 2] > 0.6)
    axis, pivot, lift = np.array([0.0, 1.0, 0.0]), np.array([0.4, 0.0, -0.7]), 0.3
    R = bench.rotation(axis, 1.9)
    X = V[handles]
    path = HandlePath(X, pivot + (X - pivot) @ R.T + lift * axis, [np.arange(len(handles))],
                      motion="screw")
    for t in (0.25, 0.5, 0.8):
        arc = pivot + (X - pivot) @ bench.rotation(axis, 1.9 * t).T + t * lift * axis
        assert np.allclose(path(t), arc, atol=1e-12)


def test_bad_input_raises():
    V, F = sphere(1)
    with pytest.raises(InvalidMeshError):
        move_surface(V, F, [0, 0], V[[0, 0]])
    with pytest.raises(InvalidMeshError):
        move_surface(V, F, [0, 1], V[[0]])
    with pytest.raises(InvalidMeshError):
        move_surface(V, F, [0], V[[0]], options=SurfaceMoveOptions(anchor="nope"))


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), angle=st.floats(0.2, 1.2),
       weight=st.floats(0.3, 3.0), anchor=st.sampled_from(["rest", "previous"]))
def test_phi_lengths_within_path_length_over_w_and_quality_bound(seed, angle, weight, anchor):
    V, F = sphere(1)
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    top = np.flatnonzero(V[:, 2] > 0.5)
    bottom = np.flatnonzero(V[:, 2] < -0.5)
    handles = np.concatenate([top, bottom])
    targets = np.concatenate([V[top] @ bench.rotation(axis, angle).T, V[bottom]])
    r = move_surface(V, F, handles, targets, steps=3,
                     options=SurfaceMoveOptions(weight=weight, anchor=anchor))
    # the stated bound: every triangle's summed φ-change is at most ℓ/w
    assert np.all(r.phi_lengths <= r.length / weight * (1 + 1e-12))
    frames = np.array(r.frames)
    phi = [SurfaceDistortion(V, F).values(X) for X in frames]
    summed = np.sum(np.linalg.norm(np.diff(phi, axis=0), axis=2), axis=0)
    assert np.allclose(summed, r.phi_lengths, rtol=1e-12, atol=1e-14)
    # from the rest: 1/ψ ≤ 1/ψ(rest)·exp(asinh(√2|φ|)) in every triangle
    inv_rest = surface_inverse_shape_quality(V, F)
    inv_end = surface_inverse_shape_quality(r.points, F)
    end_phi = SurfaceDistortion(V, F).values(r.points)
    bound = surface_quality_bound(inv_rest, np.linalg.norm(end_phi, axis=1))
    assert np.all(inv_end <= bound * (1 + 1e-10))
    assert r.folds == 0 and np.array_equal(r.points[handles], targets)


@pytest.mark.slow
def test_bunny_ear_against_libigl_arap():
    pytest.importorskip("igl")
    case = bench.bunny()
    r = move_surface(case.V, case.F, case.handles, case.path(1.0))
    ours, arap = bench.measure(case, r.points, r.seconds), bench.measure(
        case, bench.arap_incremental(case), 0.0)
    assert ours["folds"] == 0 and ours["handle error"] == 0.0
    assert ours["quality"] >= max(arap["quality"], 0.1)
    assert ours["ARAP energy"] <= 1.5 * arap["ARAP energy"]


def _rotation_checks(S, R):
    """R is a rotation (det +1) attaining the Kabsch maximum of tr(R S), the SVD's."""
    ref = sm.best_rotations(S)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    scale = np.linalg.norm(S.reshape(len(S), 9), axis=1)
    gap = np.einsum("tij,tji->t", ref, S) - np.einsum("tij,tji->t", R, S)
    assert np.all(np.abs(gap) <= 1e-12 * np.maximum(scale, 1e-300))
    return ref


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(
    ["general", "reflection", "rotation", "rank2", "rank1", "zero", "close"]))
def test_best_rotations_by_eigh_agree_with_the_svd(seed, kind):
    rng = np.random.default_rng(seed)
    n = 200
    S = rng.normal(size=(n, 3, 3)) * 10.0 ** rng.uniform(-6, 6, size=(n, 1, 1))
    if kind == "reflection":  # det S < 0: the smallest singular direction is flipped
        S[:, :, 0] *= np.where(np.linalg.det(S) > 0, -1.0, 1.0)[:, None]
    elif kind == "rotation":  # S a rotation times a positive diagonal: R its transpose
        S = np.array([random_rotation(rng) @ np.diag(rng.uniform(0.5, 2, 3)) for _ in range(n)])
    elif kind == "rank2":  # coplanar rest edges (a flat fan)
        S[:, 2, :] = 0.0
    elif kind == "rank1":
        S = rng.normal(size=(n, 3, 1)) * rng.normal(size=(n, 1, 3))
    elif kind == "zero":
        S[::2] = 0.0
    elif kind == "close":  # two nearly equal singular values
        U = np.array([random_rotation(rng) for _ in range(n)])
        W = np.array([random_rotation(rng) for _ in range(n)])
        S = U @ np.diag([2.0, 1.0 + 1e-9, 1.0])[None] @ W
    R = best_rotations(S)
    ref = _rotation_checks(S, R)
    if kind in ("general", "reflection", "rotation", "rank2"):  # unique optimum: equal
        np.testing.assert_allclose(R, ref, atol=1e-9)


def test_normal_matrix_is_the_lower_triangle_of_jtj_plus_m_at_the_free_coordinates():
    # against scipy's own sparse product of the stacked Jacobian (an independent assembly)
    import scipy.sparse as sp

    from meshopt_toolkit.motion.surface import least_squares as ls
    from meshopt_toolkit.motion.surface import move as smv

    V, F = sphere(2)
    handles = np.flatnonzero(V[:, 2] > 0.5)
    problem = ls.Problem(V, F, handles, 1.3, 0.2, smv.lumped_mass(V, F))
    problem.phi_ref = np.zeros((len(F), 3))
    Q = V + 0.05 * np.random.default_rng(1).normal(size=V.shape)
    rm, Jm, rb, Jb = problem.linearization(Q)
    got = problem.normal_matrix(Jm, Jb)
    rows = np.repeat(np.arange(len(Jb)), 12)
    Jb_mat = sp.coo_matrix((Jb.ravel(), (rows, problem.shell.columns().ravel())),
                           shape=(len(Jb), 3 * len(V)))
    J = sp.vstack([problem.membrane.jacobian_matrix(Jm), Jb_mat]).tocsc()
    full = (J.T @ J + sp.diags(np.repeat(problem.mass, 3))).tocsr()
    ref = sp.tril(full[problem.free][:, problem.free]).toarray()
    np.testing.assert_allclose(got.toarray(), ref, rtol=0, atol=1e-13 * np.abs(ref).max())
    assert np.all(np.diff(got.indptr) > 0) and got.has_sorted_indices


@pytest.mark.parametrize("shape", [(7, 3, 9), (11, 12)])
def test_upper_products_are_the_upper_triangles_of_jtj(shape):
    from meshopt_toolkit.motion.surface.normal_equations import upper_products

    J = np.random.default_rng(2).normal(size=shape)
    J3 = J[:, None, :] if J.ndim == 2 else J
    full = np.einsum("bik,bil->bkl", J3, J3)
    a, b = np.triu_indices(shape[-1])
    np.testing.assert_allclose(upper_products(J), full[:, a, b], rtol=1e-14, atol=1e-14)


def test_every_vertex_a_handle_is_moved_to_its_target():
    """With no free vertex there is nothing to solve: each increment is the handles' path
    and the result is the targets, bitwise (a rigid motion and a non-rigid one)."""
    V, F = sphere(1)
    rng = np.random.default_rng(3)
    R = random_rotation(rng)
    handles = np.arange(len(V))
    for targets in (V @ R.T + [0.3, -0.1, 2.0], V * [1.0, 1.2, 0.9]):
        res = move_surface(V, F, handles, targets, steps=3)
        assert np.array_equal(res.points, targets)
        assert res.iterations == 0


def test_chord_steps_of_the_last_increment_reach_the_minimizer_of_full_gauss_newton():
    """The last increment on a kept factor (renewed only where its shortened steps stall)
    ends where Gauss–Newton renewing its factor after every shortened step ends, both run
    to a tight tolerance, with fewer factorizations; at the defaults too (one increment:
    the bar turned 90° at once, whose steps are shortened). Plain chord steps
    (``cg_iterations=0``, the default); steps of four conjugate gradients on
    the kept factor end there too, on no more factorizations."""
    case = coarse_bar(90.0)
    args = (case.V, case.F, case.handles, case.path(1.0))
    # without contact: its barrier's pairs, not the steps' lengths, decide the renewals
    tight = dict(final_iterations=400, final_rtol=1e-13, polish=0)
    full = move_surface(*args, steps=1, contact=False,
                        options=SurfaceMoveOptions(final_stall=None, cg_iterations=0, **tight))
    chord = move_surface(*args, steps=1, contact=False,
                         options=SurfaceMoveOptions(final_stall=0.1, cg_iterations=0, **tight))
    assert np.array_equal(chord.points[case.handles], case.path(1.0)) and chord.folds == 0
    assert np.abs(chord.points - full.points).max() < 1e-5 * np.ptp(case.V, axis=0).max()
    assert sm.arap_energy(case.V, chord.points, case.F) == pytest.approx(
        sm.arap_energy(case.V, full.points, case.F), rel=1e-6)
    assert chord.worst_quality == pytest.approx(full.worst_quality, abs=1e-6)
    assert chord.factorizations < full.factorizations
    default_full = move_surface(*args, steps=1, contact=False,
                                options=SurfaceMoveOptions(final_stall=None, cg_iterations=0))
    default = move_surface(*args, steps=1, contact=False, options=SurfaceMoveOptions(cg_iterations=0))
    assert default.factorizations < default_full.factorizations
    assert default.folds == 0 and np.array_equal(default.points[case.handles], case.path(1.0))
    assert sm.fold_count(case.V, default.points, case.F, case.handles) == 0
    cg = move_surface(*args, steps=1, contact=False, options=SurfaceMoveOptions(cg_iterations=4, **tight))
    assert np.abs(cg.points - full.points).max() < 1e-5 * np.ptp(case.V, axis=0).max()
    assert cg.factorizations <= chord.factorizations and cg.folds == 0


@pytest.mark.slow
def test_strip_rolled_into_a_quarter_circle_is_rolled_isometrically():
    """bench_surface's rolled strip: the exact answer bends the 4×1 strip into a quarter
    cylinder of radius 8/π without stretching it; its centre line lies on that circle."""
    case = bench.plate_bent()
    r = move_surface(case.V, case.F, case.handles, case.path(1.0))
    assert r.folds == 0 and r.handle_error == 0.0
    mid = np.flatnonzero(np.abs(case.V[:, 1] - 0.5) < 1e-9)
    mid = mid[np.argsort(case.V[mid, 0])]
    P = r.points[mid]
    radius = 4.0 / (np.pi / 2)
    np.testing.assert_allclose(np.hypot(P[:, 0], P[:, 2] - radius), radius, atol=0.02)
    np.testing.assert_allclose(P[:, 1], 0.5, atol=0.01)
    length = np.linalg.norm(np.diff(P, axis=0), axis=1).sum()
    assert abs(length - 4.0) < 0.01
    assert r.worst_quality >= 0.99


def _bar_problem(seed=0):
    """A coarse bar's increment problem at a perturbed state, and the exact normal matrix
    ``JᵀJ + M`` at the free coordinates built from the sparse Jacobian (independently of the
    blocks' assembly and products)."""
    import scipy.sparse as sp

    from meshopt_toolkit.motion.surface import least_squares as ls
    from meshopt_toolkit.motion.surface import move as smv

    case = coarse_bar(90.0)
    V, F = case.V, case.F
    problem = ls.Problem(V, F, case.handles, 1.0, 0.3, smv.lumped_mass(V, F))
    problem.phi_ref = np.zeros((len(F), 3))
    Q0 = V + 0.01 * np.random.default_rng(seed).normal(size=V.shape)

    def exact(Q):
        _, Jm, _, Jb = problem.linearization(Q)
        rows = np.repeat(np.arange(len(Jb)), 12)
        Jb_mat = sp.coo_matrix((Jb.ravel(), (rows, problem.shell.columns().ravel())),
                               shape=(len(Jb), 3 * len(V)))
        J = sp.vstack([problem.membrane.jacobian_matrix(Jm), Jb_mat]).tocsc()
        A = (J.T @ J + sp.diags(np.repeat(problem.mass, 3))).tocsc()
        return A[problem.free][:, problem.free], Jm, Jb

    return problem, Q0, exact


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_vertex_rotations_of_a_rigid_motion_are_its_rotation(seed):
    V, F = sphere(1)
    rng = np.random.default_rng(seed)
    A = V * rng.uniform(0.5, 2.0, 3)  # any shape, then turned rigidly
    R = random_rotation(rng)
    got = FoldTest(V, F).vertex_rotations(A, A @ R.T + rng.normal(size=3))
    np.testing.assert_allclose(got, np.broadcast_to(R, got.shape), atol=1e-10)


def test_a_kept_factor_turned_with_a_rotated_surface_solves_its_matrix():
    """φ and the bending are invariant under rotations: at a rigidly turned state the
    normal matrix is ``R A Rᵀ``, and the factor of ``A`` turned by the vertex rotations
    solves it; unturned it is far off."""
    import scipy.sparse.linalg as sla

    from meshopt_toolkit.motion.surface.normal_equations import turned_solve
    from meshopt_toolkit.solvers import factorize_spd

    problem, Q0, exact = _bar_problem()
    factor = factorize_spd(exact(Q0)[0])
    R = random_rotation(np.random.default_rng(4))
    Q = Q0 @ R.T + [1.0, -2.0, 0.5]
    A, _, _ = exact(Q)
    g = np.random.default_rng(5).normal(size=A.shape[0])
    want = sla.spsolve(A, g)
    rotations = problem.folds.vertex_rotations(Q0, Q)[problem.free[::3]]
    turned = turned_solve(factor, rotations)(g)
    assert np.linalg.norm(turned - want) < 1e-9 * np.linalg.norm(want)
    assert np.linalg.norm(factor(g) - want) > 0.1 * np.linalg.norm(want)


def test_conjugate_gradients_on_a_stale_factor_reach_the_fresh_step():
    """At a state turned and deformed since the factorization, conjugate gradients
    preconditioned by the turned stale factor (matrix-free products) reach the step of the
    exact normal matrix, without a factorization; two of them already
    decrease the Gauss–Newton model more than the stale factor's own solve."""
    import scipy.sparse.linalg as sla

    problem, Q0, exact = _bar_problem(1)
    _, Jm0, _, Jb0 = problem.linearization(Q0)
    problem.refactorize(Jm0, Jb0, Q0)
    problem.fresh = False
    R = random_rotation(np.random.default_rng(6))
    Q = (Q0 + 0.02 * np.random.default_rng(7).normal(size=Q0.shape)) @ R.T
    A, Jm, Jb = exact(Q)
    op = problem.normal_operator(Jm, Jb)
    x = np.random.default_rng(8).normal(size=A.shape[0])
    np.testing.assert_allclose(op @ x, A @ x, rtol=1e-12, atol=1e-12 * np.abs(A @ x).max())
    g = np.random.default_rng(9).normal(size=A.shape[0])
    want = sla.spsolve(A, g)
    problem.cg_iterations = 2
    two = problem.kept_step(Jm, Jb, g, Q)
    problem.cg_iterations, problem.cg_rtol = 300, 1e-12
    many = problem.kept_step(Jm, Jb, g, Q)
    assert np.linalg.norm(many - want) < 1e-8 * np.linalg.norm(want)
    assert problem.factorizations == 1
    # the Gauss–Newton model's decrease gᵀs − ½ sᵀAs (its maximum ½ gᵀA⁻¹g at the step)
    model = [g @ s - 0.5 * s @ (A @ s) for s in (want, two, problem.factor(g))]
    assert model[1] > model[2] and model[1] > 0.45 * model[0]


@pytest.mark.slow
def test_steps_on_kept_factors_need_fewer_factorizations_at_the_same_quality():
    """bench_surface's bar twisted 180° in 10 increments: steps of four conjugate gradients
    on the kept factor against plain chord steps (counted by a spy on the factorization),
    the default."""
    from meshopt_toolkit.motion.surface import least_squares as ls

    case = coarse_bar(180.0, spacing=0.1)
    args = (case.V, case.F, case.handles, case.path(1.0))
    counts = []
    original = ls.Problem.refactorize

    def spy(self, *a):
        counts[-1] += 1
        return original(self, *a)

    results = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ls.Problem, "refactorize", spy)
        for k in (0, 4):
            counts.append(0)
            # without contact: its barrier's pairs, not the steps, decide the renewals
            results.append(move_surface(*args, contact=False, options=SurfaceMoveOptions(cg_iterations=k)))
    chord, cg = results
    assert counts == [chord.factorizations, cg.factorizations] and chord.cg_iterations == 0
    assert counts[1] < counts[0]
    assert cg.folds == 0 and cg.handle_error == 0.0
    assert sm.fold_count(case.V, cg.points, case.F, case.handles) == 0
    assert cg.worst_quality >= chord.worst_quality - 0.005
    assert sm.arap_energy(case.V, cg.points, case.F) <= 1.02 * sm.arap_energy(
        case.V, chord.points, case.F)


def test_a_halved_increment_grows_back_and_only_halvings_in_a_row_count(monkeypatch):
    """An increment that cannot be taken is halved; after two taken in a row it doubles
    again (up to 1/steps), and ``max_halvings`` bounds how small an increment gets, not
    the halvings of the whole motion (here two, one apart, with ``max_halvings=1``); an
    increment refused again and again ends in a refusal."""
    import meshopt_toolkit.motion.surface.move as surface_move

    case = coarse_bar(90.0)
    step, calls = surface_move.solve_increment, []

    def refusing(*args, **kwargs):  # the 2nd and 5th increments tried cannot be taken
        calls.append(1)
        return None if len(calls) in (2, 5) else step(*args, **kwargs)

    monkeypatch.setattr(surface_move, "solve_increment", refusing)
    res = move_surface(case.V, case.F, case.handles, case.path(1.0), steps=4, contact=False,
                       options=SurfaceMoveOptions(polish=0, max_halvings=1))
    np.testing.assert_allclose(res.times, [0.0, 0.25, 0.375, 0.5, 0.625, 0.75, 1.0])
    assert np.array_equal(res.points[case.handles], case.path(1.0)) and res.folds == 0

    def alternating(*args, **kwargs):  # every other increment refused: dt would shrink
        calls.append(1)
        return None if len(calls) % 2 else step(*args, **kwargs)

    monkeypatch.setattr(surface_move, "solve_increment", alternating)
    with pytest.raises(NotAdmissibleError):
        move_surface(case.V, case.F, case.handles, case.path(1.0), steps=4, contact=False,
                     options=SurfaceMoveOptions(polish=0, max_halvings=3))
