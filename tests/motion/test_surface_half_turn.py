"""A group of handles turned by a half turn (:func:`meshopt_toolkit.motion.surface.move.
clearer_half_turns`): the two ways round are equally short and the fit's rounding picks
one; a finger curled 180° back over its palm must go over it. On a coarse hand-like plate
whose fit takes the way under the palm (the handles pulled along it stop 0.84 short of
their targets, refused), the motion goes the other way: the tip follows the arc over the
palm, every frame is free of self-intersections (the exact kernel and ipctk), the handles
end exactly at their targets with no fold, and the result's worst triangle is no worse
than libigl's single-shot ARAP's."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.surface import aspect_ratios
from meshopt_toolkit.motion.engine.similarity import HandlePath, handle_groups
from meshopt_toolkit.motion.surface.move import clearer_half_turns, move_surface

ipctk = pytest.importorskip("ipctk")


def hand(size: float = 0.15):
    """The benchmark's hand-like plate (a 2×2×0.3 palm fused with a 0.6×2×0.3 finger, y
    from 2 to 4) meshed at ``size``, with its motion: the finger's tip band (y ≥ 3.8)
    turned 180° about the lateral axis through (·, 2.15, 0.45), landing 0.3 above the
    palm; the palm's bottom band fixed. Points, triangles, handles (the tip's first),
    targets, the tip's count and the benchmark's case."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from _surface_cases_contact import hand_surface
    from bench_surface import region_turn

    V, F = hand_surface(size)
    tip = V[:, 1] >= 3.8 - 1e-9
    case = region_turn("hand", V, F, tip, V[:, 1] <= 0.2 + 1e-9, [1, 0, 0], np.pi,
                       np.array([1.0, 2.15, 0.45]))
    return V, F, case.handles, case.path(1.0), int(tip.sum()), case


def test_a_half_turn_goes_the_way_that_sweeps_through_no_triangle():
    V, F, h, tg, k, _ = hand()
    path = HandlePath(V[h], tg, handle_groups(h, F, len(V)), motion="screw")
    assert path.half_turns() == [0]
    for way in (path, path.turned_the_other_way(0)):  # whichever way the fit took
        chosen = clearer_half_turns(way, V, F, h)
        np.testing.assert_array_equal(chosen(1.0), tg)
        for t in np.linspace(0.05, 0.95, 19):  # over the palm: the tip above its top
            assert chosen(t)[:k, 2].min() >= -1e-12
        # the other way passes under the palm (its tip below the bottom face)
        assert chosen.turned_the_other_way(0)(0.5)[:k, 2].max() < 0.0


@pytest.mark.slow
def test_the_finger_curls_over_the_palm_clean():
    V, F, h, tg, k, case = hand()
    res = move_surface(V, F, h, tg)
    assert [float(X[h[:k], 2].min()) >= -1e-12 for X in res.frames] == [True] * len(
        res.frames)  # the tip's arc over the palm
    mesh = ipctk.CollisionMesh(V, ipctk.edges(F.astype(np.int32)), F.astype(np.int32))
    assert [len(self_intersections(X, F)) + int(ipctk.has_intersections(mesh, X))
            for X in res.frames] == [0] * len(res.frames)
    np.testing.assert_array_equal(res.points[h], tg)
    assert res.folds == 0 and res.handle_error == 0.0
    pytest.importorskip("igl")
    from bench_surface import arap_single

    U = arap_single(case)  # libigl's single-shot ARAP, 100 iterations
    arap = float((aspect_ratios(U, F) / aspect_ratios(V, F)).min())
    assert res.worst_quality >= arap


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_the_two_ways_of_a_half_turn_are_mirror_arcs(seed):
    """Turned by ±tπ about the axis ``(u, p)``, a point's two images sum to
    ``2p + 2 cos(tπ) r⊥ + 2 r∥`` (``r = x − p`` split along ``u``); both end at the targets."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    p = rng.normal(size=3)
    X = rng.normal(size=(5, 3))
    tg = (X - p) @ Rotation.from_rotvec(np.pi * u).as_matrix().T + p
    path = HandlePath(X, tg, [np.arange(5)], motion="screw")
    assert path.half_turns() == [0]
    other = path.turned_the_other_way(0)
    np.testing.assert_array_equal(other(1.0), tg)
    r = X - p
    along = np.outer(r @ u, u)
    for t in (0.1, 0.37, 0.5, 0.9):
        expected = 2 * p + 2 * np.cos(t * np.pi) * (r - along) + 2 * along
        np.testing.assert_allclose(path(t) + other(t), expected, atol=1e-9)
        assert np.abs(path(t) - other(t)).max() > 1e-3  # two ways, not one


def twisted_box(angle: float, rotation=None, size=(3.0, 1.0, 1.0), spacing=0.5):
    """A box's cap x = size[0] turned by ``angle`` about the long axis through its centre,
    the cap x = 0 fixed, the whole scene turned by ``rotation`` (3×3): points, triangles,
    handles (the cap's first), targets."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from scipy.spatial.transform import Rotation

    from bench_surface import box_surface

    V, F = box_surface(list(size), spacing)
    cap, fixed = np.flatnonzero(V[:, 0] > size[0] - 1e-9), np.flatnonzero(V[:, 0] < 1e-9)
    centre = np.array([size[0], size[1] / 2, size[2] / 2])
    turn = Rotation.from_rotvec([angle, 0.0, 0.0]).as_matrix()
    h = np.concatenate([cap, fixed])
    tg = np.vstack([(V[cap] - centre) @ turn.T + centre, V[fixed]])
    R = np.eye(3) if rotation is None else rotation
    return V @ R.T, F, h, tg @ R.T


#: a half turn a rounding error either way of π, about the axis and against it
NEAR_HALF_TURNS = (np.pi - 1e-13, np.pi + 1e-13, -np.pi + 1e-13, -np.pi - 1e-13)


def oriented(V, F, h, tg):
    from meshopt_toolkit.motion.surface.move import lumped_mass

    m = lumped_mass(V, F)
    path = HandlePath(V[h], tg, handle_groups(h, F, len(V)), motion="screw")
    assert path.half_turns() == [0]
    return path.oriented_half_turns(m @ V / m.sum())


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_a_twist_by_a_half_turn_goes_one_way_whatever_the_rounding(seed):
    """The twisted box's cap turns right-handed about the axis from the box's centroid
    towards the cap, whichever side of π the targets were rounded to and however the
    scene is turned: the path of a turned scene is the turned path."""
    from scipy.spatial.transform import Rotation

    R = Rotation.random(random_state=seed).as_matrix()
    V, F, h, tg = twisted_box(np.pi)
    k = int(np.sum(V[:, 0] > 3.0 - 1e-9))
    right = Rotation.from_rotvec([np.pi / 2, 0.0, 0.0]).as_matrix()
    half = (V[h[:k]] - [3.0, 0.5, 0.5]) @ right.T + [3.0, 0.5, 0.5]  # a quarter turn, +x
    for angle in NEAR_HALF_TURNS:
        np.testing.assert_allclose(oriented(*twisted_box(angle))(0.5)[:k], half, atol=1e-9)
        turned = oriented(*twisted_box(angle, R))
        np.testing.assert_allclose(turned(0.5)[:k], half @ R.T, atol=1e-9)
        np.testing.assert_array_equal(turned(1.0), twisted_box(angle, R)[3])


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_a_cap_folded_about_a_hinge_beside_the_body_swings_towards_it(seed):
    """A cap turned by a half turn about an axis off its centroid (the bar folded back
    onto itself): its centroid passes, half way, nearer the body's centroid, in any
    rotated scene and whichever side of π the fit was given."""
    from scipy.spatial.transform import Rotation

    from meshopt_toolkit.motion.surface.move import lumped_mass

    R = Rotation.random(random_state=seed).as_matrix()
    V, F = twisted_box(0.0)[:2]
    cap, fixed = np.flatnonzero(V[:, 0] > 3.0 - 1e-9), np.flatnonzero(V[:, 0] < 1e-9)
    h = np.concatenate([cap, fixed])
    hinge = np.array([1.5, 1.6, 0.5])
    m = lumped_mass(V, F)
    centre = m @ V / m.sum()
    for angle in NEAR_HALF_TURNS:
        turn = Rotation.from_rotvec([0.0, 0.0, angle]).as_matrix()
        tg = np.vstack([(V[cap] - hinge) @ turn.T + hinge, V[fixed]])
        path = oriented(V @ R.T, F, h, tg @ R.T)
        mid = path(0.5)[:len(cap)].mean(axis=0)
        other = path.turned_the_other_way(0)(0.5)[:len(cap)].mean(axis=0)
        assert np.linalg.norm(mid - centre @ R.T) < np.linalg.norm(other - centre @ R.T) - 0.5


def test_the_twisted_box_moves_the_same_whatever_the_rounding():
    """``move_surface`` of the twisted box: the targets a rounding error either side of a
    half turn, the scene turned or not, give the same motion (turned with the scene)."""
    from scipy.spatial.transform import Rotation

    R = Rotation.random(random_state=7).as_matrix()
    runs = [(move_surface(*twisted_box(a, R if turned else None), steps=4,
                          options={"polish": 0}), turned)
            for a in NEAR_HALF_TURNS[:2] for turned in (False, True)]
    base = runs[0][0].frames[2]
    for res, turned in runs:
        np.testing.assert_allclose(res.frames[2] @ R if turned else res.frames[2], base,
                                   atol=1e-6)
