"""The 3D mesh-motion references of benchmarks/bench_move3d.py, checked against
independent ones: scikit-fem's linear elasticity, exact affine and rigid maps, the SVD form
of the mean ratio, Taylor tests of the careful optimizer's gradient."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from _anchors3d import (assemble_blocks, elasticity_blocks, elasticity_motion,  # noqa: E402
                        harmonic_motion, incremental_elasticity_motion, lame, laplacian)
from _careful3d import _Energy, careful_motion, inverse_mean_ratios  # noqa: E402

from meshopt_toolkit.diagnostics import check_gradient  # noqa: E402
from meshopt_toolkit.kernels.cell_maps import REGULAR_TET_EDGES  # noqa: E402
from meshopt_toolkit.kernels.tetrahedra import mean_ratios as tet_mean_ratios  # noqa: E402
from meshopt_toolkit.kernels.tetrahedra import signed_volumes as tet_signed_volumes  # noqa: E402

skfem = pytest.importorskip("skfem")


def jittered_cube(n: int = 3, jitter: float = 0.2, seed: int = 0):
    """scikit-fem's unit cube refined ``n`` times, interior nodes jittered, positively
    oriented tets; boundary node indices."""
    m = skfem.MeshTet().refined(n)
    p = m.p.T.copy()
    h = 0.5 ** n
    inner = ((p > 1e-9) & (p < 1 - 1e-9)).all(axis=1)
    p[inner] += jitter * h * np.random.default_rng(seed).uniform(-1, 1, (inner.sum(), 3))
    t = m.t.T.copy()
    flip = tet_signed_volumes(p, t) < 0
    t[flip] = t[flip][:, [0, 2, 1, 3]]
    return p, t, np.flatnonzero(~inner)


def skfem_elasticity(points, tets, lam, mu):
    """scikit-fem's P1 vector elasticity matrix, permuted to the dof ordering 3 v + i."""
    from skfem.models.elasticity import linear_elasticity

    mesh = skfem.MeshTet(points.T, tets.T)
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTetP1()))
    K = skfem.asm(linear_elasticity(lam, mu), basis)
    order = basis.nodal_dofs.T.ravel()  # our dof 3 v + i ↦ scikit-fem's dof
    return K[order][:, order]


def test_elasticity_matrix_equals_scikit_fem():
    p, t, _ = jittered_cube(2)
    lam, mu = lame(1.0, 0.3)
    ours = assemble_blocks(t, elasticity_blocks(p, t, lam, mu), len(p)).toarray()
    ref = skfem_elasticity(p, t, lam, mu).toarray()
    assert np.abs(ours - ref).max() <= 1e-12 * np.abs(ref).max()


def test_weighted_element_matrices_equal_scikit_fem_per_tet():
    p, t, _ = jittered_cube(1, seed=3)
    lam, mu = lame(1.0, 0.3)
    w = np.random.default_rng(1).uniform(0.5, 5.0, len(t))
    blocks = elasticity_blocks(p, t, lam, mu, w).reshape(len(t), 12, 12)
    for c, tet in enumerate(t):
        ref = skfem_elasticity(p[tet], np.arange(4)[None], lam, mu).toarray()
        assert np.abs(blocks[c] - w[c] * ref).max() <= 1e-12 * np.abs(ref).max()


def affine_path(points, handles, M, b):
    def path(s):
        return points[handles] + s * (points[handles] @ (M - np.eye(3)).T + b)
    return path


def test_harmonic_extension_reproduces_affine_maps():
    p, t, b = jittered_cube(3, seed=5)
    M = np.array([[1.3, 0.2, -0.1], [0.1, 0.8, 0.3], [-0.2, 0.1, 1.1]])
    shift = np.array([0.3, -0.2, 0.5])
    x = harmonic_motion(p, t, b, affine_path(p, b, M, shift))
    assert np.abs(x - (p @ M.T + shift)).max() < 1e-12


@pytest.mark.parametrize("motion, skew", [(elasticity_motion, 1.0),
                                           (incremental_elasticity_motion, 0.0)])
def test_elasticity_reproduces_strain_free_motions(motion, skew):
    """E = 1/V varies per tet, so only strain-free maps are reproduced exactly: a
    translation plus a skew (linearized rotation) displacement in one shot; a translation
    in increments (a skew map in increments strains the moved mesh)."""
    p, t, b = jittered_cube(2, seed=7)
    W = skew * np.array([[0.0, -0.3, 0.2], [0.3, 0.0, -0.1], [-0.2, 0.1, 0.0]])
    x = motion(p, t, b, affine_path(p, b, np.eye(3) + W, np.array([0.1, 0.2, -0.3])))
    assert np.abs(x - (p + p @ W.T + [0.1, 0.2, -0.3])).max() < 1e-12


def test_laplacian_annihilates_constants_and_is_symmetric():
    p, t, _ = jittered_cube(2)
    L = laplacian(p, t)
    assert np.abs(L @ np.ones(len(p))).max() < 1e-13
    assert abs(L - L.T).max() < 1e-15


def test_mean_ratio_of_the_regular_tet_is_one():
    x = REGULAR_TET_EDGES.T
    pts = np.vstack([np.zeros(3), x])
    tet = np.arange(4)[None]
    assert tet_mean_ratios(pts, tet)[0] == pytest.approx(1.0, abs=1e-14)
    q, g = inverse_mean_ratios(pts * 2.7 + 1.0, tet)  # invariant to scale and translation
    assert q[0] == pytest.approx(1.0, abs=1e-14)
    assert np.abs(g).max() < 1e-12  # the regular tet minimizes 1/η


def test_inverse_mean_ratio_equals_its_svd_form():
    """1/η = ‖S‖²_F / (3 det(S)^{2/3}) with S = D W⁻¹ the map from the regular tet."""
    rng = np.random.default_rng(11)
    pts = rng.normal(size=(400, 3))
    tets = np.array([rng.choice(400, 4, replace=False) for _ in range(300)])
    flip = tet_signed_volumes(pts, tets) < 0
    tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    D = np.swapaxes(pts[tets][:, 1:] - pts[tets][:, :1], 1, 2)
    s = np.linalg.svd(D @ np.linalg.inv(REGULAR_TET_EDGES), compute_uv=False)
    ref = (s ** 2).sum(1) / (3.0 * np.prod(s, axis=1) ** (2.0 / 3.0))
    q, _ = inverse_mean_ratios(pts, tets)
    assert np.allclose(q, ref, rtol=1e-10)
    assert np.allclose(1.0 / q, tet_mean_ratios(pts, tets), rtol=1e-10)


@pytest.mark.parametrize("sharpness", [0.5, 4.0])
def test_careful_energy_gradient_passes_taylor_test(sharpness):
    p, t, b = jittered_cube(2, seed=2)
    free = np.ones(len(p), bool)
    free[b] = False
    energy = _Energy(t, len(p), free, sharpness)

    def full(y):
        x = p.copy()
        x[free] = y
        return x

    result = check_gradient(lambda y: energy(full(y))[0], lambda y: energy(full(y))[1],
                            p[free], eps0=1e-3, rng=0)
    assert result.passed


def test_careful_energy_refuses_inverted_tets():
    p, t, b = jittered_cube(1)
    free = np.ones(len(p), bool)
    free[b] = False
    x = p.copy()
    x[t[0, 0]] = x[t[0, 1:]].mean(0) * 2 - x[t[0, 0]]  # reflect a corner: inverts tet 0
    assert np.isinf(_Energy(t, len(p), free, 1.0)(x)[0])


def test_careful_motion_turns_a_cube_face_without_inverting():
    """The top face of the cube twisted 30° about the vertical axis; exact handles, no
    inverted tet, and over the tets it can change (those with a free corner) a worst
    mean ratio above the one-shot harmonic extension's."""
    p, t, b = jittered_cube(2, jitter=0.0)
    top = p[b, 2] > 1 - 1e-9
    c = np.array([0.5, 0.5, 0.0])

    def path(s):
        a = np.radians(30.0) * s
        R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        out = p[b].copy()
        out[top] = (out[top] - c) @ R.T + c
        return out

    x = careful_motion(p, t, b, path, steps=4, iterations=30, final_iterations=200)
    eta = tet_mean_ratios(x, t)
    assert np.abs(x[b] - path(1.0)).max() == 0.0
    assert eta.min() > 0.0
    free = ~np.isin(t, b).all(axis=1)
    harmonic = tet_mean_ratios(harmonic_motion(p, t, b, path), t)
    assert eta[free].min() > harmonic[free].min() + 0.01


def test_arap_reproduces_rigid_motions():
    """The whole boundary turned 120° and shifted: ARAP's energy is zero on the rigid map
    (to libigl's polar-decomposition accuracy, ~1e-8 here)."""
    pytest.importorskip("igl")
    from _anchors3d import arap_motion

    p, t, b = jittered_cube(2, seed=4)
    a = np.radians(120.0)
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    x = arap_motion(p, t, b, lambda s: p[b] @ R.T + [0.5, 0, 0])
    assert np.abs(x - (p @ R.T + [0.5, 0, 0])).max() < 1e-6


def test_tmop_improves_the_mean_shape_of_a_valid_start():
    """TMOP's metric 303 is 1/η − 1 against the regular tet: from a valid start it lowers
    its integral, keeps the handles and inverts nothing."""
    pytest.importorskip("mfem")
    from _anchors3d import tmop_motion

    p, t, b = jittered_cube(2, jitter=0.3, seed=9)
    top = p[b, 2] > 1 - 1e-9

    def path(s):
        out = p[b].copy()
        out[top, 0] += 0.15 * s
        return out

    start = incremental_elasticity_motion(p, t, b, path)
    x = tmop_motion(p, t, b, path)
    vol = np.abs(tet_signed_volumes(p, t))
    assert np.abs(x[b] - path(1.0)).max() < 1e-12
    assert tet_mean_ratios(x, t).min() > 0
    assert (vol / tet_mean_ratios(x, t)).sum() < (vol / tet_mean_ratios(start, t)).sum()
