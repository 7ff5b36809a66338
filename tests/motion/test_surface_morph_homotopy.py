"""The homotopy start of a surface morph (:mod:`meshopt_toolkit.motion.surface.morph_homotopy`):
one connected strip whose flap, moved by either interpolation, passes through a ramp of the
same strip; pulled by the homotopy it slides off the ramp's edge, every frame clean by the
exact kernel, the motion between frames clean by ipctk's CCD, the last frame the target,
every frame at least as healthy as the worse end (the frames the relaxation leaves below
it polished, the path kept clean), also with the ends shaken by rounding; too few frames
for the clean path are refused."""

from __future__ import annotations

import numpy as np
import pytest

from meshopt_toolkit.errors import SelfIntersectionError
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.surface import aspect_ratios
import meshopt_toolkit as mt
from meshopt_toolkit.mesh import SurfaceMesh
from meshopt_toolkit.motion.surface.interpolation import arap_interpolation
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
    frames = list(morph_surface(V0, V1, F, 17).points)
    worst = _worst(frames, F)
    assert min(worst) >= min(worst[0], worst[-1]) * (1 - 1e-12)
    assert [len(self_intersections(Q, F)) for Q in frames] == [0] * 17
    assert _clean_steps(frames, F)


@pytest.mark.slow
def test_too_few_frames_for_the_homotopy_are_refused_with_the_count():
    V0, V1, F = ramp_and_flap()
    with pytest.raises(SelfIntersectionError, match=r"needs \d+ frames, 9 asked"):
        morph_surface(V0, V1, F, 9)


@pytest.mark.slow
def test_cli_writes_the_homotopys_clean_frames(tmp_path):
    from test_morph_self_intersection import _surface_file

    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import load_cells

    V0, V1, F = ramp_and_flap()
    a = _surface_file(tmp_path / "a.vtu", SurfaceMesh(V0, F))
    b = _surface_file(tmp_path / "b.vtu", SurfaceMesh(V1, F))
    out = tmp_path / "frames"
    assert main(["morph", str(a), str(b), "-o", str(out), "--frames", "17"]) == 0
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


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=SelfIntersectionError,
                   reason="both guides pull the band through the base: the homotopy stalls")
def test_a_band_swung_round_its_hinge_morphs_clean():
    V0, V1, F = hinge_band()
    frames = list(morph_surface(V0, V1, F, 17).points)
    assert [len(self_intersections(Q, F)) for Q in frames] == [0] * 17
    assert _clean_steps(frames, F)
