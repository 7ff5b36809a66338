"""An open tube whose end band is turned by a half turn about its axis (the benchmark's
tube twist on a coarser mesh): the twisted tube buckles and its flattened walls are pressed
together, the barrier's ``κ`` doubled many times, so that the last increment needs far
more Gauss–Newton steps than the others to reach its minimizer (and the result is the
better of that iterate and the one after 30 steps). The result must be clean, its handles
exact and its worst triangle clearly better than the closed-form twist
(each ring turned about the axis by its share of the turn, its radius kept: an
independent clean deformation with the same handles)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.surface import aspect_ratios
from meshopt_toolkit.motion.surface.move import move_surface

ipctk = pytest.importorskip("ipctk")


def twisted_tube(spacing: float = 0.07):
    """The tube (length 4, radius 0.5) of ``spacing``, its bands x ≤ 1.6·spacing fixed and
    x ≥ 4 − 1.6·spacing turned by π about the axis; points, triangles, handles, targets and
    the closed-form twist."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from bench_surface import region_turn, tube_surface

    V, F = tube_surface(4.0, 0.5, spacing)
    band = 1.6 * spacing
    case = region_turn("tube", V, F, V[:, 0] > 4.0 - band - 1e-9, V[:, 0] < band + 1e-9,
                       [1, 0, 0], np.pi, np.array([4.0, 0.0, 0.0]))
    share = np.clip((V[:, 0] - band) / (4.0 - 2.0 * band), 0.0, 1.0)
    angle = np.arctan2(V[:, 2], V[:, 1]) + np.pi * share
    twist = np.stack([V[:, 0], 0.5 * np.cos(angle), 0.5 * np.sin(angle)], axis=1)
    return V, F, case.handles, case.path(1.0), twist


@pytest.mark.slow
def test_a_twisted_tube_ends_clean_and_better_than_the_closed_form_twist():
    V, F, h, tg, twist = twisted_tube()
    free = ~np.isin(F, h).all(axis=1)

    def worst(X):
        return float((aspect_ratios(X, F) / aspect_ratios(V, F))[free].min())

    np.testing.assert_allclose(twist[h], tg, atol=1e-12)  # the closed form's handles
    assert not self_intersections(twist, F).size
    res = move_surface(V, F, h, tg)
    np.testing.assert_array_equal(res.points[h], tg)
    assert res.folds == 0 and res.handle_error == 0.0
    mesh = ipctk.CollisionMesh(V, ipctk.edges(F.astype(np.int32)), F.astype(np.int32))
    assert not self_intersections(res.points, F).size
    assert not ipctk.has_intersections(mesh, res.points)
    assert worst(res.points) >= worst(twist) + 0.1
    # the last increment stopped at its first 30 steps: never better than the result
    short = move_surface(V, F, h, tg, options={"final_late_iterations": 30})
    assert worst(short.points) <= worst(res.points)
