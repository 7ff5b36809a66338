"""The membrane distortion of triangle surfaces in R³: the planar φ through the first
fundamental form, its derivatives, invariances and proven bounds.

References: the planar ``TriangleDistortion`` on flat meshes, singular values from the
frame-free Gram matrices of the edges, Taylor tests, random meshes, motions and paths.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh
from hypothesis import given, settings
from hypothesis import strategies as st
from motion_helpers import distortion_functional, random_rotation, rates

from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.kernels.cell_maps import surface_inverse_shape_quality
from meshopt_toolkit.kernels.triangles import inverse_shape_quality
from meshopt_toolkit.motion.planar.distortion import TriangleDistortion
from meshopt_toolkit.motion.surface.distortion import (
    SurfaceDistortion,
    surface_path_quality_bound,
    surface_quality_bound,
)

FAST = settings(max_examples=12, deadline=None)


def bumpy(n: int = 4, seed: int = 0):
    """A jittered grid lifted onto the graph of a smooth bump: (N, 3) points, triangles."""
    mesh = grid_mesh(n, jitter=0.3, seed=seed)
    x, y = mesh.points.T
    return np.column_stack([x, y, 0.4 * np.sin(3 * x) * y + 0.2 * x**2]), mesh.triangles


def random_motion(points, rng, amplitude):
    """A rotated affine image of ``points`` plus noise (no triangle degenerates)."""
    A = np.eye(3) + amplitude * rng.uniform(-0.5, 0.5, (3, 3)) / 1.5
    Q = points @ (random_rotation(rng) @ A).T + rng.uniform(-1, 1, 3)
    return Q + 0.1 * amplitude * rng.standard_normal(Q.shape) / np.sqrt(len(points))


def gram_singular_values(P, Q, tri):
    """Singular values of the map between rest and current triangle from the edges' Gram
    matrices only (no frame): σ² are the eigenvalues of G₀⁻¹G₁."""
    def gram(X):
        E = np.stack([X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]], axis=2)
        return np.swapaxes(E, 1, 2) @ E
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(gram(P), gram(Q))).real, axis=1)[:, ::-1]
    return np.sqrt(lam)


@pytest.fixture(scope="module")
def surface():
    return bumpy(4)


def test_values_are_the_planar_closed_forms(surface, rng):
    P, T = surface
    Q = random_motion(P, rng, 0.6)
    phi = SurfaceDistortion(P, T).values(Q)
    s = gram_singular_values(P, Q, T)
    np.testing.assert_allclose(np.sqrt(2) * phi[:, 0], np.log(s[:, 0] * s[:, 1]), atol=1e-11)
    kappa = s[:, 0] / s[:, 1]
    np.testing.assert_allclose(np.sqrt(2) * np.hypot(phi[:, 1], phi[:, 2]), (kappa - 1 / kappa) / 2,
                               rtol=1e-9, atol=1e-12)
    assert np.abs(SurfaceDistortion(P, T).values(P)).max() < 1e-13


def test_flat_meshes_give_the_planar_distortion_turned_per_triangle(rng):
    """On a mesh in the plane z = 0: φ_0 and |F| are the planar ones, F is the planar one
    turned by −2θ (θ the angle of the rest edge 0→1), so are the Jacobian's rows (the z
    columns zero) and the metric ``JᵀJ`` is the planar one."""
    mesh = grid_mesh(4, jitter=0.3)
    P2, T = mesh.points, mesh.triangles
    Q2 = P2 + 0.03 * rng.standard_normal(P2.shape)
    lift = lambda X: np.column_stack([X, np.zeros(len(X))])  # noqa: E731
    surf, plane = SurfaceDistortion(lift(P2), T), TriangleDistortion(P2, T)
    a, Ja = surf.values_and_jacobian(lift(Q2))
    b, Jb = plane.values_and_jacobian(Q2)
    e = P2[T[:, 1]] - P2[T[:, 0]]
    turn = np.exp(-2j * np.arctan2(e[:, 1], e[:, 0]))
    np.testing.assert_allclose(a[:, 0], b[:, 0], atol=1e-13)
    np.testing.assert_allclose(a[:, 1] + 1j * a[:, 2], turn * (b[:, 1] + 1j * b[:, 2]), atol=1e-13)
    Ja = Ja.reshape(len(T), 3, 3, 3)
    assert np.abs(Ja[..., 2]).max() < 1e-13
    Jxy = Ja[..., :2].reshape(len(T), 3, 6)
    np.testing.assert_allclose(Jxy[:, 0], Jb[:, 0], atol=1e-12)
    np.testing.assert_allclose(Jxy[:, 1] + 1j * Jxy[:, 2],
                               turn[:, None] * (Jb[:, 1] + 1j * Jb[:, 2]), atol=1e-12)
    np.testing.assert_allclose(np.swapaxes(Jxy, 1, 2) @ Jxy, np.swapaxes(Jb, 1, 2) @ Jb, atol=1e-11)


@pytest.mark.parametrize("at_reference", [True, False])
def test_jacobian_and_second_order_taylor(surface, rng, at_reference):
    P, T = surface
    dist = SurfaceDistortion(P, T)
    Q = P.copy() if at_reference else random_motion(P, rng, 0.5)
    f, grad, hvp = distortion_functional(dist, rng.standard_normal((len(T), 3)), dist.columns())
    first = check_gradient(f, grad, Q, eps0=1e-3, rng=rng)
    assert abs(first.order - 2) < 0.2, first
    second = check_hvp(f, grad, hvp, Q, eps0=1e-3, rng=rng)
    assert second.order > 2.8, second  # a wrong Hessian gives 2; a tiny cubic term > 3


@FAST
@given(scale=st.floats(0.01, 100), shift=st.tuples(*[st.floats(-1e3, 1e3)] * 3),
       seed=st.integers(0, 2**16))
def test_rotations_even_per_triangle_leave_phi_and_scaling_moves_the_area_part(scale, shift, seed):
    P, T = bumpy(3, seed)
    rng = np.random.default_rng(seed)
    dist = SurfaceDistortion(P, T)
    Q = random_motion(P, rng, 0.5)
    phi = dist.values(Q)
    moved = dist.values(scale * Q @ random_rotation(rng).T + np.asarray(shift))
    np.testing.assert_allclose(moved[:, 1:], phi[:, 1:], atol=1e-9 * (1 + np.abs(phi).max()))
    np.testing.assert_allclose(moved[:, 0] - phi[:, 0], np.sqrt(2) * np.log(scale), atol=1e-9)
    # a triangle soup: every triangle turned by its own rotation
    soup = np.arange(3 * len(T)).reshape(-1, 3)
    turned = np.concatenate([(Q[t] - Q[t[0]]) @ random_rotation(rng).T for t in T])
    np.testing.assert_allclose(SurfaceDistortion(P[T.ravel()], soup).values(turned), phi,
                               atol=1e-9 * (1 + np.abs(phi).max()))


def test_barrier_blows_up_when_a_triangle_degenerates(surface):
    P, T = surface
    dist = SurfaceDistortion(P, T)
    t = T[9]
    mid = 0.5 * (P[t[1]] + P[t[2]])
    norms = []
    for gap in 10.0 ** -np.arange(1, 7):
        Q = P.copy()
        Q[t[0]] = mid + gap * (P[t[0]] - mid)
        norms.append(np.linalg.norm(dist.values(Q)[9]))
    assert np.all(np.diff(norms) > 0) and norms[-1] > 1e4
    Q = P.copy()
    Q[t[0]] = mid
    assert np.isinf(dist.values(Q)[9]).all()
    with pytest.raises(InvalidMeshError, match="triangle 9"):
        SurfaceDistortion(Q, T)


@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.0, 0.8))
def test_metric_dominates_half_the_affine_invariant_metric(seed, amplitude):
    """|J V| ≥ ½‖C^{-½} Ċ C^{-½}‖_F per triangle, equality at the reference."""
    P, T = bumpy(2, seed)
    rng = np.random.default_rng(seed)
    dist = SurfaceDistortion(P, T)
    Q = random_motion(P, rng, amplitude) if amplitude else P
    rate, affine = rates(dist, Q, rng.standard_normal(Q.shape))
    assert (rate >= affine * (1 - 1e-10)).all()
    if not amplitude:
        np.testing.assert_allclose(rate, affine, rtol=1e-10)


def test_surface_quality_is_the_planar_one_for_flat_meshes():
    mesh = grid_mesh(3, jitter=0.3)
    lifted = np.column_stack([mesh.points, np.zeros(mesh.n_vertices)])
    R = random_rotation(np.random.default_rng(0))
    np.testing.assert_allclose(surface_inverse_shape_quality(lifted @ R.T, mesh.triangles),
                               inverse_shape_quality(mesh.points, mesh.triangles), rtol=1e-12)


@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.05, 0.8))
def test_random_paths_keep_every_triangle_below_its_bound(seed, amplitude):
    """From the reference: ``1/ψ(Q_k) ≤ surface_quality_bound(1/ψ(Q_0), S_k)`` with
    ``S_k = Σ |φ(Q_{i+1}) − φ(Q_i)| ≥ |φ(Q_k)|``; from a later start, the φ-length bound
    (``S`` of a fine subdivision, 1e-3 slack for its O(h²) underestimate)."""
    P, T = bumpy(3, seed)
    rng = np.random.default_rng(seed)
    nodes = [P] + [random_motion(P, rng, amplitude) for _ in range(3)]
    steps = np.linspace(0, 1, 17)[1:]
    frames = [P] + [a + s * (b - a) for a, b in zip(nodes[:-1], nodes[1:]) for s in steps]
    dist = SurfaceDistortion(P, T)
    phis = np.array([dist.values(Q) for Q in frames])
    frames = [Q for Q, phi in zip(frames, phis) if np.isfinite(phi).all()]
    phis = np.array([dist.values(Q) for Q in frames])
    S = np.concatenate([np.zeros((1, len(T))),
                        np.cumsum(np.linalg.norm(np.diff(phis, axis=0), axis=2), axis=0)])
    q0 = surface_inverse_shape_quality(P, T)
    for k, Q in enumerate(frames):
        bound = surface_quality_bound(q0, S[k])
        assert (surface_inverse_shape_quality(Q, T) <= bound * (1 + 1e-12)).all()
    start = len(frames) // 3
    qs = surface_inverse_shape_quality(frames[start], T)
    for k in range(start, len(frames)):
        bound = surface_path_quality_bound(qs, (S[k] - S[start]) * (1 + 1e-3))
        assert (surface_inverse_shape_quality(frames[k], T) <= bound * (1 + 1e-12)).all()


@pytest.mark.parametrize("u", [0.01, 0.03])
def test_path_bound_is_attained_for_a_small_stretch_of_a_needle(u):
    """A needle triangle along its axis, stretched by ``exp(t·u·diag(1, −1))`` in its
    plane (the plane turned in R³): ``1/ψ ≤ 1/ψ₀ e^{√2 L}`` is an equality up to O(u²)."""
    rest = np.array([[0.0, 0.0], [1e3, 0.0], [500.0, np.sqrt(3) / 2]])
    R = random_rotation(np.random.default_rng(5))[:, :2]  # an isometry of the plane into R³
    tri = np.array([[0, 1, 2]])
    dist = SurfaceDistortion(rest @ R.T, tri)
    frames = [(rest * np.exp(t * u * np.array([1.0, -1.0]))) @ R.T for t in np.linspace(0, 1, 65)]
    phis = np.array([dist.values(Q)[0] for Q in frames])
    L = np.linalg.norm(np.diff(phis, axis=0), axis=1).sum()
    bound = surface_path_quality_bound(surface_inverse_shape_quality(frames[0], tri), L)
    ratio = bound / surface_inverse_shape_quality(frames[-1], tri)
    assert 1.0 <= ratio[0] < 1 + 4 * u**2
