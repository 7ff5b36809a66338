"""The triangle distortion φ (motion/planar/distortion.py): closed forms, Taylor tests of its
Jacobian and second derivatives, invariances, and the per-triangle quality bound.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh
from hypothesis import given
from hypothesis import strategies as st
from motion_helpers import FAST, _random_admissible, _similar, distortion_functional

from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.kernels.cell_maps import coordinate_columns
from meshopt_toolkit.kernels.triangles import inverse_shape_quality
from meshopt_toolkit.motion.planar.assembly import upper_to_blocks
from meshopt_toolkit.motion.planar.distortion import (
    TriangleDistortion,
    shape_quality_bound,
    stretch_ratios,
)


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
    # a scalar functional of φ tests every row
    f, grad, _ = distortion_functional(dist, rng.standard_normal((len(T), 3)),
                                       coordinate_columns(T, 2))
    result = check_gradient(f, grad, Q, eps0=1e-3, rng=rng)
    assert abs(result.order - 2) < 0.2, result


@pytest.mark.parametrize("at_reference", [True, False])
def test_distortion_second_order_taylor(disc, rng, at_reference):
    """``second_order(Q, ρ)`` is the Hessian of ``Σ ρ·φ``: second-order Taylor test."""
    P, T = disc.points, disc.triangles
    dist = TriangleDistortion(P, T)
    Q = P.copy() if at_reference else _random_admissible(disc, rng, 0.3)
    f, grad, hvp = distortion_functional(dist, rng.standard_normal((len(T), 3)),
                                         coordinate_columns(T, 2), second=upper_to_blocks)
    result = check_hvp(f, grad, hvp, Q, eps0=1e-3, rng=rng)
    assert abs(result.order - 3) < 0.2, result


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
