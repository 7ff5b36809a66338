"""Coarse-to-fine morphs of pairs made by uniform refinement."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh

import meshopt_toolkit as mt
from meshopt_toolkit.generate import twisted
from meshopt_toolkit.motion.planar.morph import distortion_morph
from meshopt_toolkit.motion.planar.refinement import refine_frames, unrefined


@pytest.mark.parametrize("levels", [1, 2])
def test_unrefined_recovers_the_coarse_mesh(levels):
    coarse = mt.load(mt.data_path("disc_146.msh")).as_planar()
    fine = coarse
    for _ in range(levels):
        fine = fine.refine()
    found = unrefined(fine.points, fine.triangles)
    assert found is not None
    expected = coarse
    for _ in range(levels - 1):
        expected = expected.refine()
    assert np.array_equal(found.triangles, expected.triangles)
    assert np.array_equal(found.points, expected.points)


def test_unrefined_refuses_what_refine_did_not_make():
    mesh = grid_mesh(4, jitter=0.3)
    assert unrefined(mesh.points, mesh.triangles) is None  # 32 triangles, not a split
    fine = mesh.refine()
    swapped = fine.triangles.copy()
    swapped[[0, 5]] = swapped[[5, 0]]
    assert unrefined(fine.points, swapped) is None
    rotated = fine.triangles.copy()
    rotated[3] = np.roll(rotated[3], 1)  # the same triangle, another first vertex
    assert unrefined(fine.points, rotated) is None
    assert unrefined(fine.points, fine.triangles[:-4]) is None


def test_refine_frames_is_refine_of_every_frame(rng):
    coarse = grid_mesh(3, jitter=0.3)
    frames = coarse.points[None] + 0.01 * rng.standard_normal((3, coarse.n_vertices, 2))
    refined = refine_frames(frames, coarse)
    for Q, R in zip(frames, refined):
        np.testing.assert_array_equal(R, coarse.with_points(Q).refine().points)


def test_coarse_to_fine_morph_reaches_the_same_geodesic():
    """The coarse level only changes the start: the finest level converges to the same
    frames as the morph started from the rigid interpolation."""
    fine = mt.load(mt.data_path("disc_541.msh")).as_planar().refine()
    target = twisted(fine)
    one = distortion_morph(fine, target, frames=5, coarse_min_triangles=10**9)
    two = distortion_morph(fine, target, frames=5, coarse_min_triangles=500)
    assert one.converged and two.converged
    assert [lv["triangles"] for lv in one.summary()["levels"]] == [fine.n_triangles]
    levels = two.summary()["levels"]
    assert [lv["triangles"] for lv in levels] == [fine.n_triangles // 4, fine.n_triangles]
    assert two.initial_path.startswith("coarse-to-fine")
    assert (two.stats.inverted == 0).all()
    assert abs(two.energy - one.energy) <= 1e-9 * one.energy
    edges = fine.points[fine.edges]
    shortest = np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1).min()
    assert np.abs(two.points - one.points).max() <= 1e-3 * shortest


def test_morph_stops_at_its_gradient_tolerance():
    """``gtol`` is the reported test, on every level of a coarse-to-fine morph."""
    fine = mt.load(mt.data_path("disc_146.msh")).as_planar().refine()
    target = twisted(fine)
    loose = distortion_morph(fine, target, frames=5, coarse_min_triangles=100, gtol=1e-2)
    tight = distortion_morph(fine, target, frames=5, coarse_min_triangles=100, gtol=1e-8)
    assert len(loose.details["levels"]) == 2
    for res in (loose, tight):
        assert res.converged
        assert all(level["status"] == "converged" for level in res.details["levels"])
    assert loose.gradient_norm <= 1e-2 * np.sqrt(loose.energy)
    assert tight.gradient_norm < loose.gradient_norm
    assert tight.nit > loose.nit
