"""The case builders of ``bench_surface.py --unseen2``: valid rest meshes, finite rigid
handle paths, and the generated surfaces against closed forms (areas, Euler
characteristics, where the turned ends go)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import _surface_measures as sm  # noqa: E402

bench = pytest.importorskip("bench_surface")
pytest.importorskip("trimesh")
pytest.importorskip("gmsh")
import _surface_cases_contact as cc  # noqa: E402


def triangle_areas(V, F):
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]),
                                axis=1)


def euler_characteristic(V, F):
    edges = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]),
                              axis=1), axis=0)
    return len(V) - len(edges) + len(F)


def boundary_edge_count(F):
    half = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, counts = np.unique(np.sort(half, axis=1), axis=0, return_counts=True)
    return int(np.sum(counts == 1))


#: the cases of ``--unseen2``, ``--contact`` and ``--contact2``
CHECKED = {**bench.UNSEEN2, **bench.CONTACT, **cc.CONTACT2}


@pytest.mark.parametrize("name", list(CHECKED))
def test_case_is_a_valid_rest_mesh_with_two_handle_groups_and_finite_targets(name):
    from meshopt_toolkit.mesh.surface import SurfaceMesh

    case = CHECKED[name]()
    assert SurfaceMesh(case.V, case.F).problems == []
    assert sm.aspect_ratios(case.V, case.F).min() > 0.005
    assert len(case.handles) == len(np.unique(case.handles)) == len(case.groups)
    groups, counts = np.unique(case.groups, return_counts=True)
    assert list(groups) == [0, 1] and counts.min() >= 50
    P = case.path(1.0)
    assert P.shape == (len(case.handles), 3) and np.isfinite(P).all()
    moved = np.abs(P - case.V[case.handles]).max(axis=1)
    assert moved[case.groups == 0].max() == 0.0  # the fixed group stays
    assert moved[case.groups == 1].max() > 0.01 * np.ptp(case.V, axis=0).max()


@pytest.mark.parametrize("name", list(CHECKED))
def test_case_path_starts_at_rest_and_moves_each_group_rigidly(name):
    case = CHECKED[name]()
    np.testing.assert_allclose(case.path(0.0), case.V[case.handles], atol=1e-14)
    for t in (0.37, 1.0):
        P = case.path(t)
        for g in (0, 1):
            i = np.flatnonzero(case.groups == g)[::7][:60]
            R = case.V[case.handles[i]]
            d0 = np.linalg.norm(R[:, None] - R, axis=2)
            d1 = np.linalg.norm(P[i][:, None] - P[i], axis=2)
            np.testing.assert_allclose(d1, d0, atol=1e-12)


def test_tube_is_an_open_outward_cylinder_of_the_polygon_area():
    V, F = bench.tube_surface(4.0, 0.5, 0.0625)
    nv = 50  # 2π·0.5 / 0.0625 rounded
    assert len(F) == 2 * 64 * nv
    assert euler_characteristic(V, F) == 0 and boundary_edge_count(F) == 2 * nv
    # the prism over a regular nv-gon inscribed in the circle
    area = 4.0 * nv * 2 * 0.5 * np.sin(np.pi / nv)
    assert triangle_areas(V, F).sum() == pytest.approx(area, rel=1e-12)
    n = sm.normals(V, F)
    radial = V[F].mean(axis=1) * [0, 1, 1]
    assert (np.einsum("ij,ij->i", n, radial) > 0).all()


def test_tube_twist_turns_the_end_half_way_round_and_tube_bent_ends_on_the_arc():
    case = bench.tube_twist()
    end = case.groups == 1
    Q = case.V[case.handles[end]]
    np.testing.assert_allclose(case.path(1.0)[end], Q * [1, -1, -1], atol=1e-12)
    bent = bench.tube_bent()
    end = bent.groups == 1
    P, Q = bent.path(1.0)[end], bent.V[bent.handles[end]]
    r = 4.0 / (np.pi / 2)
    ring = Q[:, 0] == 4.0
    np.testing.assert_allclose(P[ring].mean(0), [r, r, 0.0], atol=1e-12)
    # the end ring now lies in a plane y = r, its axis along +y
    np.testing.assert_allclose(P[ring, 1], r, atol=1e-12)
    np.testing.assert_allclose(P[:, 2], Q[:, 2], atol=1e-12)


def test_plate_is_a_closed_thin_box_and_its_cap_turns_a_quarter():
    V, F = bench.box_surface([4.0, 1.0, 0.1], 0.05)
    assert euler_characteristic(V, F) == 2 and boundary_edge_count(F) == 0
    signed_volume = np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6
    assert signed_volume == pytest.approx(0.4, rel=1e-12)
    case = bench.plate_twist()
    end = case.groups == 1
    Q = case.V[case.handles[end]]
    assert (Q[:, 0] == 4.0).all()
    expected = np.column_stack([Q[:, 0], 0.5 - (Q[:, 2] - 0.05), 0.05 + (Q[:, 1] - 0.5)])
    np.testing.assert_allclose(case.path(1.0)[end], expected, atol=1e-12)


def test_holed_strip_is_an_annulus_missing_about_the_disc_area():
    V, F = bench.holed_strip(4.0, 1.0, 0.05, [2.0, 0.5], 0.25)
    assert euler_characteristic(V, F) == 0  # a disc with one hole
    assert len(np.unique(F)) == len(V)  # no unused vertex
    hole = 4.0 - triangle_areas(V, F).sum()
    assert hole == pytest.approx(np.pi * 0.25**2, rel=0.05)
    assert (sm.normals(V, F)[:, 2] > 0).all()
    # nothing inside the hole, the outer boundary untouched
    centres = V[F].mean(axis=1)
    assert np.linalg.norm(centres[:, :2] - [2.0, 0.5], axis=1).min() > 0.25 - 0.05
    np.testing.assert_array_equal(V.min(0), [0, 0, 0])
    np.testing.assert_array_equal(V.max(0), [4, 1, 0])


def test_disc_is_the_outer_polygon_triangulated_facing_up():
    rings = 30
    V, F = bench.disc_surface(rings)
    assert len(V) == 1 + 3 * rings * (rings + 1)
    assert euler_characteristic(V, F) == 1 and boundary_edge_count(F) == 6 * rings
    m = 6 * rings
    assert triangle_areas(V, F).sum() == pytest.approx(0.5 * m * np.sin(2 * np.pi / m),
                                                       rel=1e-12)
    assert (sm.normals(V, F)[:, 2] > 0).all()
    case = bench.disc_bump()
    middle = case.groups == 1
    r = np.linalg.norm(case.V[case.handles, :2], axis=1)
    assert (r[middle] <= 0.2 + 1e-9).all() and (r[~middle] >= 0.95 - 1e-9).all()
    lift = case.path(0.5)[middle] - case.V[case.handles[middle]]
    np.testing.assert_allclose(lift, np.tile([0, 0, 0.2], (middle.sum(), 1)), atol=1e-15)


def test_real_mesh_cases_pick_the_named_parts():
    ear = bench.bunny_front_ear()
    tip = ear.V[ear.handles[ear.groups == 1]]
    assert (tip[:, 0] < -0.05).all() and (tip[:, 1] > 0.165).all()
    assert ear.path(1.0)[ear.groups == 1][:, 2].min() < tip[:, 2].min()  # outwards, −z
    tail = bench.bob_tail()
    T = tail.V[tail.handles[tail.groups == 1]]
    assert (T[:, 0] > 0.6).all() and (T[:, 1] > 0.03).all() and len(T) == 234
    assert tail.path(1.0)[tail.groups == 1][:, 2].mean() > T[:, 2].mean() + 0.05  # to +z
    arm = bench.armadillo_tail()
    T = arm.V[arm.handles[arm.groups == 1]]
    assert (T[:, 2] < -0.2).all() and np.abs(T[:, 0]).max() < 0.05 and len(T) == 797


# ``--unseen3`` (benchmarks/_surface_cases3.py): one builder test per case

c3 = pytest.importorskip("_surface_cases3")


def assert_valid_case(case, moved_at_least):
    """Rest mesh valid, two handle groups, finite targets, each group moved rigidly (the
    fixed one not at all) along the whole path."""
    from meshopt_toolkit.mesh.surface import SurfaceMesh

    assert SurfaceMesh(case.V, case.F).problems == []
    assert sm.aspect_ratios(case.V, case.F).min() > 0.005
    assert len(case.handles) == len(np.unique(case.handles)) == len(case.groups)
    groups, counts = np.unique(case.groups, return_counts=True)
    assert list(groups) == [0, 1] and counts.min() >= 50
    np.testing.assert_allclose(case.path(0.0), case.V[case.handles], atol=1e-14)
    P = case.path(1.0)
    assert P.shape == (len(case.handles), 3) and np.isfinite(P).all()
    moved = np.abs(P - case.V[case.handles]).max(axis=1)
    assert moved[case.groups == 0].max() == 0.0
    assert moved[case.groups == 1].max() > moved_at_least
    for t in (0.37, 1.0):
        P = case.path(t)
        for g in (0, 1):
            i = np.flatnonzero(case.groups == g)[::5][:80]
            R = case.V[case.handles[i]]
            d0 = np.linalg.norm(R[:, None] - R, axis=2)
            d1 = np.linalg.norm(P[i][:, None] - P[i], axis=2)
            np.testing.assert_allclose(d1, d0, atol=1e-12)


def test_armadillo_head_turns_the_head_in_front_of_the_body_about_the_vertical():
    case = c3.armadillo_head()
    assert_valid_case(case, 0.05)
    head = case.V[case.handles[case.groups == 1]]
    assert (head[:, 2] > 0.12).all() and (np.abs(head[:, 0]) < 0.15).all()
    assert (case.V[case.handles[case.groups == 0], 1] < case.V[:, 1].min() + 0.06).all()
    P = case.path(1.0)[case.groups == 1]
    np.testing.assert_allclose(P[:, 1], head[:, 1], atol=1e-14)  # a turn about y
    # the snout's direction from the pivot turned by 45° in the x–z plane
    c0, c1 = head.mean(0), P.mean(0)
    pivot = bench.boundary_pivot(case.V, case.F, np.isin(np.arange(len(case.V)),
                                                          case.handles[case.groups == 1]))
    a, b = (c0 - pivot)[[0, 2]], (c1 - pivot)[[0, 2]]
    cos = a @ b / np.linalg.norm(a) / np.linalg.norm(b)
    assert cos == pytest.approx(np.cos(np.pi / 4), abs=1e-12)


def test_spot_nod_lowers_the_head_front():
    case = c3.spot_nod()
    assert_valid_case(case, 0.05)
    head = case.V[case.handles[case.groups == 1]]
    assert (head[:, 2] < -0.25).all()
    P = case.path(1.0)[case.groups == 1]
    np.testing.assert_allclose(P[:, 0], head[:, 0], atol=1e-14)  # a turn about x
    front = head[:, 2] < np.quantile(head[:, 2], 0.1)
    assert P[front, 1].mean() < head[front, 1].mean() - 0.05  # the muzzle goes down


def test_dome_is_an_outward_unit_hemisphere_and_its_top_turns_a_quarter():
    rings = 30
    V, F = c3.dome_surface(rings)
    np.testing.assert_allclose(np.linalg.norm(V, axis=1), 1.0, atol=1e-14)
    assert V[:, 2].min() == pytest.approx(0.0, abs=1e-15)
    assert euler_characteristic(V, F) == 1 and boundary_edge_count(F) == 6 * rings
    # inscribed in the hemisphere: its area a little under 2π, converging
    area = triangle_areas(V, F).sum()
    assert 2 * np.pi * 0.99 < area < 2 * np.pi
    assert (np.einsum("ij,ij->i", sm.normals(V, F), V[F].mean(axis=1)) > 0).all()
    case = c3.dome_twist()
    assert_valid_case(case, 0.3)
    top = case.groups == 1
    Q = case.V[case.handles[top]]
    assert (Q[:, 2] >= np.cos(np.pi / 6) - 1e-9).all()
    # (x, y, z) ↦ (−y, x, z)
    np.testing.assert_allclose(case.path(1.0)[top], Q[:, [1, 0, 2]] * [-1, 1, 1], atol=1e-14)
    assert (case.V[case.handles[~top], 2] <= np.cos(0.95 * np.pi / 2) + 1e-9).all()


def test_l_plate_is_the_square_less_a_corner_and_its_arm_rolls_upwards():
    V, F = c3.l_plate(3.0, 1.0, 0.05)
    assert euler_characteristic(V, F) == 1 and len(np.unique(F)) == len(V)
    assert triangle_areas(V, F).sum() == pytest.approx(9.0 - 4.0, rel=1e-12)
    assert (sm.normals(V, F)[:, 2] > 0).all()
    assert not ((V[:, 0] > 1 + 1e-9) & (V[:, 1] > 1 + 1e-9)).any()
    # the boundary: 2·3 + 2·2 + 2·1 of length, in edges of 0.05
    assert boundary_edge_count(F) == round(12.0 / 0.05)
    case = c3.l_plate_roll()
    assert_valid_case(case, 0.5)
    end = case.groups == 1
    Q, P = case.V[case.handles[end]], case.path(1.0)[end]
    r = 2.0 / (np.pi / 2)
    tip = Q[:, 1] == 3.0
    # the end edge goes to the top of the quarter circle, standing upright: (x, 1 + r, r)
    np.testing.assert_allclose(P[tip], np.column_stack([Q[tip, 0], np.full(tip.sum(), 1 + r),
                                                        np.full(tip.sum(), r)]), atol=1e-12)
    assert (case.V[case.handles[~end], 0] >= 2.9 - 1e-9).all()


def test_capped_cylinder_is_closed_outward_and_of_the_prism_volume():
    V, F = c3.capped_cylinder(4.0, 0.5, 8)
    assert euler_characteristic(V, F) == 2 and boundary_edge_count(F) == 0
    n = 48  # points per ring: the prism over a regular 48-gon inscribed in the circle
    volume = np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6
    assert volume == pytest.approx(4.0 * n / 2 * 0.25 * np.sin(2 * np.pi / n), rel=1e-12)
    case = c3.cylinder_bent()
    assert_valid_case(case, 1.0)
    end = case.groups == 1
    Q, P = case.V[case.handles[end]], case.path(1.0)[end]
    assert (Q[:, 0] == 4.0).all() and (case.V[case.handles[~end], 0] == 0.0).all()
    r = 4.0 / (np.pi / 3)
    # the cap's centre to the arc's end, its normal along the arc's tangent (60° in x–y)
    np.testing.assert_allclose(Q.mean(0), [4.0, 0.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(P.mean(0), [r * np.sin(np.pi / 3), r / 2, 0.0], atol=1e-12)
    np.testing.assert_allclose(P[:, 2], Q[:, 2], atol=1e-12)


def test_torus_is_closed_outward_and_its_far_segment_tilts():
    V, F = c3.torus_surface(1.0, 0.3, 0.05)
    nu, nv = 126, 38
    assert len(V) == nu * nv and euler_characteristic(V, F) == 0
    assert boundary_edge_count(F) == 0
    w = np.hypot(V[:, 0], V[:, 1])
    np.testing.assert_allclose(np.hypot(w - 1.0, V[:, 2]), 0.3, atol=1e-14)
    # the enclosed volume tends to 2π²Rr² from below (inscribed polyhedron)
    volume = np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6
    assert 0.99 * 2 * np.pi**2 * 0.09 < volume < 2 * np.pi**2 * 0.09
    case = c3.torus_tilt()
    assert_valid_case(case, 0.1)
    seg = case.groups == 1
    Q, P = case.V[case.handles[seg]], case.path(1.0)[seg]
    assert (Q[:, 0] < -np.cos(np.radians(10)) * 0.7 + 1e-9).all()
    np.testing.assert_allclose(P[:, 0], Q[:, 0], atol=1e-14)  # a turn about x
    c, s = np.cos(np.pi / 3), np.sin(np.pi / 3)
    np.testing.assert_allclose(P[:, 1:], Q[:, 1:] @ np.array([[c, s], [-s, c]]), atol=1e-14)


def test_bar_folded_lands_the_cap_over_the_bar_and_bunny_120_turns_a_third():
    bar = bench.bar_folded()
    cap = bar.groups == 1
    np.testing.assert_allclose(bar.path(1.0)[cap].mean(0), [3.0, 1.7, 0.5], atol=1e-12)
    ear = bench.bunny_ear_120()
    ninety = bench.bunny()
    np.testing.assert_array_equal(ear.handles, ninety.handles)
    tip = ear.groups == 1
    # both turn the tip about the z axis: the x–y parts of its chords turn by 120° and 90°
    a, b, c = ear.V[ear.handles][tip], ninety.path(1.0)[tip], ear.path(1.0)[tip]

    def turned(u, v):
        return np.arctan2(u[0] * v[1] - u[1] * v[0], u[0] * v[0] + u[1] * v[1])

    i, j = 0, int(np.argmax(np.linalg.norm(a[:, :2] - a[0, :2], axis=1)))
    assert turned(a[j] - a[i], c[j] - c[i]) == pytest.approx(-2 * np.pi / 3, abs=1e-9)
    assert turned(a[j] - a[i], b[j] - b[i]) == pytest.approx(-np.pi / 2, abs=1e-9)


def test_hand_is_closed_outward_of_the_boxes_volume_and_its_finger_lands_over_the_palm():
    V, F = cc.hand_surface()
    assert euler_characteristic(V, F) == 2 and boundary_edge_count(F) == 0
    volume = np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6
    assert volume == pytest.approx(2.0 * 2.0 * 0.3 + 0.6 * 2.0 * 0.3, rel=1e-9)
    assert not sm.self_intersecting_faces(V, F)
    case = cc.hand_finger()
    tip = case.groups == 1
    Q, P = case.V[case.handles[tip]], case.path(1.0)[tip]
    assert (Q[:, 1] >= 3.8 - 1e-9).all() and (case.V[case.handles[~tip], 1] <= 0.2).all()
    # a half turn about x through (·, 2.15, 0.45): y ↦ 4.3 − y, z ↦ 0.9 − z
    np.testing.assert_allclose(P, np.c_[Q[:, 0], 4.3 - Q[:, 1], 0.9 - Q[:, 2]], atol=1e-12)
    assert P[:, 2].min() == pytest.approx(0.3 + 0.3)  # 0.3 above the palm's top face
    assert case.path(0.5)[tip][:, 2].min() > 0.3  # over the palm, not under it


def test_sheet_fold_lands_the_end_band_over_the_fixed_one():
    case = cc.sheet_fold()
    assert boundary_edge_count(case.F) > 0  # open
    end = case.groups == 1
    Q, P = case.V[case.handles[end]], case.path(1.0)[end]
    np.testing.assert_allclose(P, np.c_[4.0 - Q[:, 0], Q[:, 1], np.full(len(Q), 0.1)],
                               atol=1e-12)
    assert case.path(0.5)[end][:, 2].min() > 0.1  # turned upwards


def test_frame_intersections_names_the_frame_and_pair_that_pass_through_each_other():
    # two triangles apart, then the second stood up through the first's middle
    F = np.array([[0, 1, 2], [3, 4, 5]])
    apart = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 1], [2, 0, 1], [0, 2, 1.0]])
    through = apart.copy()
    through[3:] = [[0.5, 0.5, -1], [0.5, 0.5, 1], [0.2, 0.2, 0.5]]
    case = bench.Case("two", apart, F, np.array([0]), lambda t: apart[:1], np.zeros(1))
    bad = bench.frame_intersections(case, [apart, through, apart])
    assert [(k, faces, pairs.tolist()) for k, faces, pairs in bad] == [(1, 2, [[0, 1]])]
