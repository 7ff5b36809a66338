"""As-rigid-as-possible interpolation (the morph's initial path)."""

from __future__ import annotations

import numpy as np
from conftest import grid_mesh

from meshopt_toolkit.datasets import data_path
from meshopt_toolkit.kernels.triangles import signed_areas
from meshopt_toolkit.fem.interpolation import arap_interpolation, rotation_angles
from meshopt_toolkit.io import load
from meshopt_toolkit.generate import twisted


def _rot(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def test_global_affine_map_is_interpolated_in_closed_form():
    mesh = grid_mesh(5, jitter=0.3)
    Q0 = mesh.points
    S = np.array([[1.4, 0.3], [0.3, 0.8]])  # symmetric positive definite
    angle = np.deg2rad(130.0)
    A = _rot(angle) @ S
    shift = np.array([0.7, -0.2])
    Q1 = Q0 @ A.T + shift
    times = np.array([0.0, 0.25, 0.5, 0.9, 1.0])
    P = arap_interpolation(Q0, Q1, mesh.triangles, times)
    # no vertex is fixed: the one closest to the centroid follows the straight line
    c = int(np.argmin(np.sum((Q0 - Q0.mean(0)) ** 2, axis=1)))
    for s, frame in zip(times, P):
        J = _rot(s * angle) @ ((1 - s) * np.eye(2) + s * S)
        qc = (1 - s) * Q0[c] + s * Q1[c]
        assert np.allclose(frame, (Q0 - Q0[c]) @ J.T + qc, atol=1e-12)
    assert np.array_equal(P[0], Q0) and np.array_equal(P[-1], Q1)


def test_rigid_rotation_stays_rigid():
    mesh = grid_mesh(4, jitter=0.2)
    Q0 = mesh.points
    Q1 = Q0 @ _rot(np.deg2rad(-100.0)).T
    theta, stretch = rotation_angles(Q0, Q1, mesh.triangles)
    assert np.allclose(theta, np.deg2rad(-100.0)) and np.allclose(stretch, np.eye(2))
    e = mesh.edges
    length0 = np.linalg.norm(Q0[e[:, 0]] - Q0[e[:, 1]], axis=1)
    for frame in arap_interpolation(Q0, Q1, mesh.triangles, np.linspace(0, 1, 7)):
        assert np.allclose(np.linalg.norm(frame[e[:, 0]] - frame[e[:, 1]], axis=1), length0)


def test_twist_angles_are_unwrapped_and_frames_admissible():
    disc = load(data_path("disc_541.msh")).as_planar()
    Q1 = twisted(disc, degrees=300.0).points
    theta, _ = rotation_angles(disc.points, Q1, disc.triangles)
    # continuous across every interior edge, and beyond π at the centre (300° twist)
    adj = disc.triangle_adjacency
    a, b = (adj.nonzero() if hasattr(adj, "nonzero") else np.nonzero(adj))
    assert np.abs(theta[a] - theta[b]).max() < 0.5 * np.pi  # no 2π jumps
    assert theta.max() > np.pi and theta.min() > -np.pi
    P = arap_interpolation(disc.points, Q1, disc.triangles, np.linspace(0, 1, 17))
    assert all(signed_areas(p, disc.triangles).min() > 0 for p in P)
    b = disc.boundary_vertices
    assert np.array_equal(P[:, b], np.broadcast_to(disc.points[b], P[:, b].shape))
    # the same angles whatever the triangle order (the anchor is the least rotated one),
    # also with the most rotated triangle (beyond π) first
    perm = np.argsort(-theta)
    theta_perm, _ = rotation_angles(disc.points, Q1, disc.triangles[perm])
    assert np.allclose(theta_perm, theta[perm])


def test_refuses_nothing_and_keeps_fixed_vertices():
    mesh = grid_mesh(3, jitter=0.1)
    P = arap_interpolation(mesh.points, mesh.points, mesh.triangles, [0.0, 0.5, 1.0])
    assert np.array_equal(P, np.broadcast_to(mesh.points, P.shape))


def test_vertices_still_up_to_round_off_stay_put():
    """A clamped boundary that went through a similarity equal to the identity up to
    round-off (the morph's residual target) is still pinned: the same frames as with the
    boundary exactly equal."""
    disc = load(data_path("disc_541.msh")).as_planar()
    Q1 = twisted(disc).points
    noisy = Q1 * (1.0 + 2.0 ** -52)  # every coordinate one ulp-ish off, the boundary too
    b = disc.boundary_vertices
    assert not np.array_equal(noisy[b], disc.points[b])
    times = np.linspace(0, 1, 5)
    exact = arap_interpolation(disc.points, Q1, disc.triangles, times)
    rounded = arap_interpolation(disc.points, noisy, disc.triangles, times)
    np.testing.assert_allclose(rounded[1:-1], exact[1:-1], atol=1e-12)
    assert np.array_equal(rounded[1:-1, b], exact[1:-1, b])
