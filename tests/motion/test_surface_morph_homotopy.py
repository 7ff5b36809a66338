"""The homotopy start of a surface morph (:mod:`meshopt_toolkit.motion.surface_morph_homotopy`):
one connected strip whose flap, pulled straight down, passes through a ramp of the same
strip; pulled by the homotopy it slides off the ramp's edge, every frame clean by the exact
kernel, the motion between frames clean by ipctk's CCD, the last frame the target, every
frame as healthy as the worse end; too few frames for the clean path are refused."""

from __future__ import annotations

import numpy as np
import pytest

from meshopt_toolkit.errors import SelfIntersectionError
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.surface import aspect_ratios
from meshopt_toolkit.motion import surface_morph as sm
from meshopt_toolkit.motion.contact import pair_contact
from meshopt_toolkit.motion.surface_morph_contact import PathContact
from meshopt_toolkit.motion.surface_morph_homotopy import homotopy_path

ipctk = pytest.importorskip("ipctk")


def ramp_and_flap(nu: int = 4, nv: int = 3):
    """One strip (width along x in [0.2, 0.8]) of 3 nu × nv quads: a ramp z = -0.3 y from its
    free edge y = 0.4 to y = -1, a band folded back over it up to an upright flap (plane
    y = 0.35, z in [0.5, 1.5]) above the ramp; the target has the flap 2 lower, under the
    ramp, its band passing over the ramp and beyond its free edge."""
    u, v = np.linspace(0, 3, 3 * nu + 1), np.linspace(0, 1, nv + 1)
    U, W = (a.ravel() for a in np.meshgrid(u, v, indexing="ij"))

    def pose(drop):
        y_r = 0.4 - 1.4 * np.clip(U, 0, 1)
        R, T = np.array([-1.0, 0.3]), np.array([0.35, 1.5 - drop])
        mid = np.array([0.6, 0.3]) if drop else 0.5 * (R + T)
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


def _setup(frames):
    V0, V1, F = ramp_and_flap()
    problem = sm._PathProblem(V0, V1, F, sm.WEIGHT, sm.BENDING)
    contact = PathContact(pair_contact(V0, V1, F), frames, problem.sqrt_m ** 2)
    return V0, V1, F, problem, contact


def _linear(V0, V1):
    return lambda ts: [(1.0 - t) * V0 + t * V1 for t in ts]


def test_the_strip_crosses_itself_between_clean_ends():
    V0, V1, F = ramp_and_flap()
    assert not len(self_intersections(V0, F)) and not len(self_intersections(V1, F))
    assert len(self_intersections(0.5 * (V0 + V1), F))


@pytest.mark.slow
def test_the_homotopy_slides_the_flap_off_the_ramp_with_clean_frames():
    V0, V1, F, problem, contact = _setup(17)
    frames = homotopy_path(problem, contact, V0, V1, _linear(V0, V1), 16)
    assert len(frames) == 17
    np.testing.assert_array_equal(frames[0], V0)
    np.testing.assert_array_equal(frames[-1], V1)
    assert [len(self_intersections(Q, F)) for Q in frames] == [0] * 17
    E = ipctk.edges(F.astype(np.int32))
    mesh = ipctk.CollisionMesh(V0, E, F.astype(np.int32))
    assert all(ipctk.is_step_collision_free(mesh, a, b) for a, b in zip(frames[:-1], frames[1:]))
    q0 = aspect_ratios(V0, F)
    worst = [float((aspect_ratios(Q, F) / q0).min()) for Q in frames]
    assert min(worst) >= min(worst[0], worst[-1]) * (1.0 - 1e-12)


def test_too_few_frames_for_the_homotopy_are_refused_with_the_count():
    V0, V1, F, problem, contact = _setup(9)
    with pytest.raises(SelfIntersectionError, match=r"needs \d+ frames, 9 asked"):
        homotopy_path(problem, contact, V0, V1, _linear(V0, V1), 8)
