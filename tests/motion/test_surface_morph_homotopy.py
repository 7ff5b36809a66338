"""The homotopy start of a surface morph (:mod:`meshopt_toolkit.motion.surface.morph_homotopy`):
one connected strip whose flap, moved by either interpolation, passes through a ramp of the
same strip; without the long way round (:func:`.interpolation.fold_crossings` finding no
pair) the homotopy pulls it off the ramp's edge, every frame clean by the exact kernel, the
motion between frames clean by ipctk's CCD, the last frame the target, every frame at least
as healthy as the worse end (the frames the relaxation leaves below it polished, the path
kept clean), also with the ends shaken by rounding; too few frames for the clean path are
refused. With it, the morph starts from the interpolation that turns the strip's folded
hinges the long way round, as it does a band swung round its hinge and random hinged
flaps."""

from __future__ import annotations

import io
import sys
from contextlib import contextmanager

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from meshopt_toolkit.errors import SelfIntersectionError
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.surface import aspect_ratios
import meshopt_toolkit as mt
from meshopt_toolkit.mesh import SurfaceMesh
from meshopt_toolkit.motion.engine import contact as engine_contact
from meshopt_toolkit.motion.surface import morph as smorph
from meshopt_toolkit.motion.surface import morph_homotopy
from meshopt_toolkit.motion.surface.interpolation import arap_interpolation, fold_crossings
from meshopt_toolkit.motion.surface.morph import morph_surface

ipctk = pytest.importorskip("ipctk")


def ramp_and_flap(nu: int = 4, nv: int = 3):
    """One strip (width along x in [0.2, 0.8]) of 3 nu × nv quads: a ramp z = -0.3 y from its
    free edge y = 0.4 to y = -1, a band folded back over it (through (y, z) = (0.3, 1)) to
    an upright flap (plane y = 0.35, z in [0.5, 1.5]) above the ramp; the target has the flap 2 lower, under the
    ramp, its band passing over the ramp and beyond its free edge."""
    R = np.array([-1.0, 0.3])
    u, v = np.linspace(0, 3, 3 * nu + 1), np.linspace(0, 1, nv + 1)
    U, W = (a.ravel() for a in np.meshgrid(u, v, indexing="ij"))

    def pose(drop):
        y_r = 0.4 - 1.4 * np.clip(U, 0, 1)
        T = np.array([0.35, 1.5 - drop])
        mid = np.array([0.6, 0.3]) if drop else np.array([0.3, 1.0])
        s = np.clip(2 * (U - 1), 0, 1)[:, None]
        s2 = np.clip(2 * (U - 1.5), 0, 1)[:, None]
        band = np.where(U[:, None] <= 1.5, (1 - s) * R + s * mid, (1 - s2) * mid + s2 * T)
        flap = np.c_[np.full(len(U), 0.35), 1.5 - drop - (U - 2)]
        yz = np.where(U[:, None] <= 1, np.c_[y_r, -0.3 * y_r],
                      np.where(U[:, None] <= 2, band, flap))
        return np.c_[0.2 + 0.6 * W, yz]

    n = nv + 1
    i, j = (a.ravel() for a in np.meshgrid(np.arange(3 * nu), np.arange(nv), indexing="ij"))
    a, b = i * n + j, (i + 1) * n + j
    F = np.vstack([np.c_[a, b, b + 1], np.c_[a, b + 1, a + 1]])
    return pose(0.0), pose(2.0), F


@contextmanager
def _short_way_only():
    """The morph with no pair of neighbours found crossing the fold: no long way round."""
    def none(V0, V1, F):
        return sp.csr_matrix((len(F), len(F)))

    with pytest.MonkeyPatch.context() as mp:
        for module in (smorph, morph_homotopy):
            mp.setattr(module, "fold_crossings", none)
        yield


def _clean_steps(frames, F) -> bool:
    """ipctk's own CCD over each straight segment between consecutive frames."""
    E = ipctk.edges(F.astype(np.int32))
    mesh = ipctk.CollisionMesh(frames[0], E, F.astype(np.int32))
    return all(ipctk.is_step_collision_free(mesh, a, b) for a, b in zip(frames[:-1], frames[1:]))


def _worst(frames, F) -> list:
    q0 = aspect_ratios(frames[0], F)
    return [float((aspect_ratios(Q, F) / q0).min()) for Q in frames]


def test_both_interpolations_of_the_strip_cross_it_between_clean_ends():
    V0, V1, F = ramp_and_flap()
    assert not len(self_intersections(V0, F)) and not len(self_intersections(V1, F))
    ts = np.linspace(0.0, 1.0, 9)
    for path in ([(1 - t) * V0 + t * V1 for t in ts], arap_interpolation(V0, V1, F, ts),
                 arap_interpolation(V0, V1, F, ts, iterations=10)):
        assert max(len(self_intersections(Q, F)) for Q in path) > 0


@pytest.fixture(scope="module")
def strip_morph():
    V0, V1, F = ramp_and_flap()
    with _short_way_only():
        res = mt.morph(SurfaceMesh(V0, F), SurfaceMesh(V1, F), 17)
    return res, [np.asarray(f.points) for f in res.frames], V0, V1, F


@pytest.mark.slow
def test_the_morph_starts_from_the_homotopy_with_clean_frames(strip_morph):
    res, frames, V0, V1, F = strip_morph
    assert res.morph.initial_path == "homotopy"
    np.testing.assert_array_equal(frames[0], V0)
    np.testing.assert_array_equal(frames[-1], V1)
    assert [len(self_intersections(Q, F)) for Q in frames] == [0] * 17
    assert _clean_steps(frames, F)


@pytest.mark.slow
def test_the_homotopy_morph_s_frames_are_as_healthy_as_the_worse_end(strip_morph):
    res, frames, _, _, F = strip_morph
    worst = _worst(frames, F)
    assert min(worst) >= min(worst[0], worst[-1]) * (1 - 1e-12)
    assert res.morph.polished > 0  # the relaxation alone stops below it


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_ends_shaken_by_rounding_morph_as_healthy_and_clean(seed):
    """Each point of both ends moved by about 1e-9: the same guarantees, no hang."""
    V0, V1, F = ramp_and_flap()
    rng = np.random.default_rng(seed)
    V0, V1 = (V + 1e-9 * rng.standard_normal(V.shape) for V in (V0, V1))
    with _short_way_only():
        frames = list(morph_surface(V0, V1, F, 17).points)
    worst = _worst(frames, F)
    assert min(worst) >= min(worst[0], worst[-1]) * (1 - 1e-12)
    assert [len(self_intersections(Q, F)) for Q in frames] == [0] * 17
    assert _clean_steps(frames, F)


@pytest.mark.slow
def test_too_few_frames_for_the_homotopy_are_refused_with_the_count(monkeypatch):
    """Two frames, the ends alone: the straight motion between them passes through the
    ramp, so the morph is refused with the frames the clean path needs, which morph
    clean; the first homotopy's 3 frames end the search (no path needs fewer)."""
    V0, V1, F = ramp_and_flap()
    assert not _clean_steps([V0, V1], F)
    runs = []
    path = morph_homotopy.homotopy_path
    monkeypatch.setattr(morph_homotopy, "homotopy_path",
                        lambda *a, **k: runs.append(1) or path(*a, **k))
    with _short_way_only(), pytest.raises(SelfIntersectionError,
                                          match=r"needs 3 frames, 2 asked") as refusal:
        morph_surface(V0, V1, F, 2)
    assert len(runs) == 1
    needed = int(str(refusal.value).split("needs ")[1].split()[0])
    with _short_way_only():
        _assert_clean_and_healthy(morph_surface(V0, V1, F, needed), V0, V1, F)


@pytest.mark.slow
def test_the_homotopy_morphs_the_strip_clean_in_nine_frames():
    """The ends lie closer than the strip's own d̂ (the morph's is below half their closest
    pair); the homotopy's barrier keeps the surface's own, its iterates further from the
    ramp and its clear chords long enough for nine frames."""
    V0, V1, F = ramp_and_flap()
    with _short_way_only():
        res = morph_surface(V0, V1, F, 9)
    assert res.initial_path == "homotopy"
    _assert_clean_and_healthy(res, V0, V1, F)


@pytest.mark.slow
def test_the_homotopy_widens_its_barrier_for_five_frames(monkeypatch):
    """With a segment test a hundred times coarser (its floor 10⁻² of the diagonal), the
    strip's clean path at its own d̂ needs more than five frames; with a wider barrier the
    iterates keep further from the ramp, their clear chords longer."""
    monkeypatch.setattr(engine_contact, "SEGMENT_FLOOR", 1e-2)
    V0, V1, F = ramp_and_flap()
    problem = smorph._PathProblem(V0, V1, F, smorph.WEIGHT, smorph.BENDING)
    contact = smorph._path_contact(problem, V0, V1, 5, True)
    with pytest.raises(SelfIntersectionError, match=r"needs \d+ frames, 5 asked"):
        morph_homotopy.homotopy_path(problem, contact, V0, V1,
                                     lambda ts: arap_interpolation(V0, V1, F, ts), 4)
    with _short_way_only():
        res = morph_surface(V0, V1, F, 5)
    assert res.initial_path == "homotopy"
    _assert_clean_and_healthy(res, V0, V1, F)


@pytest.mark.slow
def test_cli_writes_the_homotopys_clean_frames(tmp_path, monkeypatch):
    """... and its progress bar, on a terminal, shows the search for the start."""
    from test_morph_self_intersection import _surface_file

    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import load_cells

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    V0, V1, F = ramp_and_flap()
    a = _surface_file(tmp_path / "a.vtu", SurfaceMesh(V0, F))
    b = _surface_file(tmp_path / "b.vtu", SurfaceMesh(V1, F))
    out = tmp_path / "frames"
    monkeypatch.setattr(sys, "stderr", Terminal())
    with _short_way_only():
        assert main(["morph", str(a), str(b), "-o", str(out), "--frames", "17"]) == 0
    assert "start path: the homotopy, increment" in sys.stderr.getvalue()
    frames = [np.asarray(load_cells(p).points) for p in sorted(out.glob("frame_*.vtu"))]
    assert len(frames) == 17
    assert [len(self_intersections(Q, F)) for Q in frames] == [0] * 17
    assert _clean_steps(frames, F)


def hinge_band(angle: float = 170.0, nu: int = 4, nv: int = 2):
    """One strip of 2 nu × nv quads (x in [0, 1]): a base y in [−1, 0], z = 0, and a band
    hinged on its edge y = 0 turned by ``angle`` degrees about the x axis (folded back over
    the base); the target has it turned by −``angle`` (folded under the base): the band
    must swing the long way round its hinge."""
    u, v = np.linspace(-1, 1, 2 * nu + 1), np.linspace(0, 1, nv + 1)
    U, W = (a.ravel() for a in np.meshgrid(u, v, indexing="ij"))
    s = np.clip(U, 0, None)

    def pose(degrees):
        t = np.radians(degrees)
        return np.c_[W, np.where(U <= 0, U, s * np.cos(t)), s * np.sin(t)]

    n = nv + 1
    i, j = (a.ravel() for a in np.meshgrid(np.arange(2 * nu), np.arange(nv), indexing="ij"))
    a, b = i * n + j, (i + 1) * n + j
    F = np.vstack([np.c_[a, b, b + 1], np.c_[a, b + 1, a + 1]])
    return pose(angle), pose(-angle), F


def test_the_hinge_band_s_interpolations_cross_between_clean_ends():
    V0, V1, F = hinge_band()
    assert not len(self_intersections(V0, F)) and not len(self_intersections(V1, F))
    ts = np.linspace(0.0, 1.0, 17)
    linear = [(1 - t) * V0 + t * V1 for t in ts]
    assert max(len(self_intersections(Q, F)) for Q in linear) > 0
    assert not _clean_steps(arap_interpolation(V0, V1, F, ts), F)


def _assert_clean_and_healthy(res, V0, V1, F):
    frames = list(res.points)
    np.testing.assert_array_equal(frames[0], V0)
    np.testing.assert_array_equal(frames[-1], V1)
    assert [len(self_intersections(Q, F)) for Q in frames] == [0] * len(frames)
    assert _clean_steps(frames, F)
    worst = _worst(frames, F)
    assert min(worst) >= min(worst[0], worst[-1]) * (1 - 1e-12)


def test_a_band_swung_round_its_hinge_morphs_clean():
    V0, V1, F = hinge_band()
    res = morph_surface(V0, V1, F, 17)
    assert res.initial_path == "long_way"
    _assert_clean_and_healthy(res, V0, V1, F)


def test_the_strip_morphs_clean_the_long_way_round():
    V0, V1, F = ramp_and_flap()
    res = morph_surface(V0, V1, F, 9)  # fewer than the homotopy needs
    assert res.initial_path == "long_way"
    _assert_clean_and_healthy(res, V0, V1, F)


def _centred(V, F):
    a = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    c = (a[:, None] * V[F].mean(1)).sum(0) / a.sum()
    return V - c


def test_the_long_way_round_turns_the_band_rigidly_through_flat():
    """Closed form: at time t the band is turned by 170° − 340° t about its hinge, the
    base still (up to the translation of the centroid); the hinge pairs are those found
    crossing the fold, and the short way turns the band through the base instead."""
    V0, V1, F = hinge_band()
    pairs = fold_crossings(V0, V1, F)
    hinge = {tuple(sorted(f)) for f in zip(*pairs.nonzero())}
    on_hinge = [i for i, f in enumerate(F) if np.isclose(V0[f, 1], 0.0).sum() == 2
                and np.isclose(V0[f, 2], 0.0).all()]
    assert len(hinge) == 2 and all(any(i in h for h in hinge) for i in on_hinge)
    ts = np.linspace(0.0, 1.0, 9)
    for t, Q in zip(ts, arap_interpolation(V0, V1, F, ts, long_way=True)):
        exact = hinge_band(170.0 - 340.0 * t)[0]
        np.testing.assert_allclose(_centred(Q, F), _centred(exact, F), atol=1e-9)
    short = arap_interpolation(V0, V1, F, [0.5])[0]
    np.testing.assert_allclose(_centred(short, F), _centred(hinge_band(180.0)[0], F),
                               atol=1e-9)


def hinged_flap(a: float, b: float, axis: int, rotvec):
    """A square base (2 × 2 quads) in z = 0 and a flap of 2 × 2 quads hinged on its edge
    ``axis = 0``: x = 1 (folded about the y axis), ``1``: y = 1 (about x); turned by
    ``a`` degrees (over the base) at the source and by −``b`` (under it) at the target,
    the target also moved rigidly (rotation vector ``rotvec``, a shift)."""
    u = np.linspace(0, 2, 5)
    v = np.linspace(0, 1, 3)
    U, W = (x.ravel() for x in np.meshgrid(u, v, indexing="ij"))
    n = len(v)
    i, j = (x.ravel() for x in np.meshgrid(np.arange(len(u) - 1), np.arange(len(v) - 1),
                                           indexing="ij"))
    p, q = i * n + j, (i + 1) * n + j
    F = np.vstack([np.c_[p, q, q + 1], np.c_[p, q + 1, p + 1]])
    s = np.clip(U - 1, 0, None)

    def pose(degrees):
        t = np.radians(degrees)
        along = np.where(U <= 1, U, 1 + s * np.cos(t))
        P = np.c_[along, W, s * np.sin(t)]
        return P if axis == 0 else np.c_[W, along, -s * np.sin(t)]

    if axis == 1:
        F = F[:, [0, 2, 1]]  # the same outward side up
    V1 = pose(-b) @ Rotation.from_rotvec(rotvec).as_matrix().T + np.array([0.3, -0.2, 0.1])
    return pose(a), V1, F


@pytest.mark.slow
@settings(max_examples=6, deadline=None, derandomize=True, database=None)
@given(a=st.floats(150.0, 175.0), b=st.floats(150.0, 175.0), axis=st.sampled_from([0, 1]),
       rotvec=st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3))
def test_random_hinged_flaps_morph_clean_the_long_way_round(a, b, axis, rotvec):
    """The flap folded over the base at the source and under it at the target, about
    either axis, the target moved rigidly: the as-rigid-as-possible interpolation turns the
    flap through the base; the morph's frames and the motion between them are clean, every
    frame as healthy as the worse end, from the long way round where the straight
    interpolation crosses too."""
    V0, V1, F = hinged_flap(a, b, axis, rotvec)
    assert not len(self_intersections(V0, F)) and not len(self_intersections(V1, F))
    ts = np.linspace(0.0, 1.0, 17)
    assert not _clean_steps(arap_interpolation(V0, V1, F, ts), F)  # through the base
    linear = [(1 - t) * V0 + t * V1 for t in ts]
    res = morph_surface(V0, V1, F, 17)
    assert res.initial_path == ("linear" if _clean_steps(linear, F) else "long_way")
    _assert_clean_and_healthy(res, V0, V1, F)


def test_a_flap_ending_close_to_the_base_is_approached_geometrically():
    """Turned to 0.01° under the base (a pair 2·10⁻⁵ of the size apart at the target), the
    long way round's last even step closes that pair from 0.3 through the step check's
    floor: not clear. The frames are picked among samples halving their time towards the
    target, each segment clear, every frame as healthy as the worse end."""
    V0, V1, F = hinged_flap(160.0, 179.99, 1, [0.48, 0.19, 0.15])
    problem = smorph._PathProblem(V0, V1, F, smorph.WEIGHT, smorph.BENDING)
    contact = smorph._path_contact(problem, V0, V1, 9, True)
    even = arap_interpolation(V0, V1, F, np.linspace(0.0, 1.0, 9), long_way=True)
    assert not all(contact.segment_clear(a, b) for a, b in zip(even[:-1], even[1:]))
    res = morph_surface(V0, V1, F, 9)
    assert res.initial_path == "long_way"
    _assert_clean_and_healthy(res, V0, V1, F)


@pytest.mark.slow
def test_the_homotopy_along_the_long_way_splits_its_chords_at_its_iterates():
    """Pulled round the hinge the long way, the homotopy's chords are split at their middle
    iterates (not midpoints, which shrink a turning band): every frame admissible (no
    fold), the path clean."""
    V0, V1, F = hinge_band()
    problem = smorph._PathProblem(V0, V1, F, smorph.WEIGHT, smorph.BENDING)
    contact = smorph._path_contact(problem, V0, V1, 17, True)
    frames = morph_homotopy.homotopy_path(
        problem, contact, V0, V1, lambda ts: arap_interpolation(V0, V1, F, ts, long_way=True),
        16)
    assert len(frames) == 17 and _clean_steps(frames, F)
    assert all(problem.admissible(Q) for Q in frames[1:-1])


def test_a_flap_ending_close_to_the_base_morphs_clean_in_five_frames():
    """Turned to 0.01° under the base: the long way round's samples make a clean path of
    5 frames, every frame as healthy as the worse end."""
    V0, V1, F = hinged_flap(160.0, 179.99, 1, [0.48, 0.19, 0.15])
    res = morph_surface(V0, V1, F, 5)
    assert res.initial_path == "long_way"
    _assert_clean_and_healthy(res, V0, V1, F)


@pytest.mark.slow
def test_the_homotopy_to_a_flap_ending_close_to_the_base_keeps_its_pairs_apart():
    """Pulled the long way round to the flap 0.01° under the base, the homotopy's
    iterates keep every pair at least half the morph's d̂ apart (not pressed onto the
    contact, where tight-inclusion CCD grinds) and its 6 frames are clean."""
    V0, V1, F = hinged_flap(160.0, 179.99, 1, [0.48, 0.19, 0.15])
    problem = smorph._PathProblem(V0, V1, F, smorph.WEIGHT, smorph.BENDING)
    contact = smorph._path_contact(problem, V0, V1, 6, True)
    frames = morph_homotopy.homotopy_path(
        problem, contact, V0, V1, lambda ts: arap_interpolation(V0, V1, F, ts, long_way=True),
        5)
    assert len(frames) == 6 and _clean_steps(frames, F)
    assert [len(self_intersections(Q, F)) for Q in frames] == [0] * 6
    keep = morph_homotopy.KEEP * contact.contact.dhat
    assert min(contact.contact.minimum_distance(Q) for Q in frames[1:-1]) > keep


def _turning_triangle(gap: float):
    """A small fixed triangle at height ``gap`` over (0.5, 0.5) and a triangle in z = 0
    whose corner (1, 0, 0) turns by 90° about the z axis to (0, 1, 0): the straight piece
    between the two poses carries that corner to (0.5, 0.5, 0), ``gap`` under the small
    triangle, while both ends keep it about 0.6 away; the scene turned off the axes (else
    the pair's swept boxes would not meet, and the segment test would not test it)."""
    small = np.array([[0.5, 0.4, gap], [0.6, 0.55, gap], [0.4, 0.55, gap]])
    turning = np.array([[1.0, 0.0, 0.0], [2.0, 0.3, 0.0], [2.0, -0.3, 0.0]])
    quarter = Rotation.from_rotvec([0.0, 0.0, np.pi / 2]).as_matrix()
    F = np.array([[0, 1, 2], [3, 4, 5]])
    tilt = Rotation.from_rotvec([0.3, -0.4, 0.2]).as_matrix().T
    return (np.vstack([small, turning]) @ tilt, np.vstack([small, turning @ quarter.T]) @ tilt,
            F)


@pytest.mark.parametrize("gap, clear", [(1e-2, True), (1e-5, False)])
def test_the_last_piece_s_samples_agree_with_the_segment_test(gap, clear, monkeypatch):
    """A piece that dips below the segment test's floor between ends far from contact is
    refused by its samples (the test not run), as the test refuses it; one that keeps
    above it passes both."""
    V0, V1, F = _turning_triangle(gap)
    problem = smorph._PathProblem(V0, V1, F, smorph.WEIGHT, smorph.BENDING)
    contact = smorph._path_contact(problem, V0, V1, 3, True)
    assert contact.segment_clear(V0, V1) == clear
    if not clear:
        monkeypatch.setattr(contact, "segment_clear", lambda *a: pytest.fail("tested"))
    assert morph_homotopy._piece_clear(contact, V0, V1) == clear
