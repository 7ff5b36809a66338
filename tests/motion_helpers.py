"""Shared by the tests of the motion package (tests/motion/test_motion_*.py): hypothesis settings,
similar and random admissible meshes, a straight path."""

from __future__ import annotations

import numpy as np
from hypothesis import settings

from meshopt_toolkit.motion.planar.metric import GraphMetric


FAST = settings(max_examples=15, deadline=None)



def _similar(points, angle, scale, shift):
    c, s = np.cos(angle), np.sin(angle)
    return scale * points @ np.array([[c, -s], [s, c]]).T + np.asarray(shift)



def _random_admissible(mesh, rng, amplitude):
    """An affine image of ``mesh`` plus a small perturbation, admissible by construction:
    ``A = I + a·B`` with ``‖B‖₂ ≤ ‖B‖_F ≤ 1`` and ``a < 1`` keeps ``det A > 0``; the noise is
    halved until no triangle inverts (the affine image alone is admissible)."""
    assert amplitude < 1
    A = np.eye(2) + amplitude * rng.uniform(-0.5, 0.5, (2, 2))
    Q = mesh.points @ A.T + rng.uniform(-1, 1, 2)
    noise = 0.05 * amplitude / np.sqrt(mesh.n_vertices) * rng.standard_normal(Q.shape)
    while not (mesh.with_points(Q + noise).signed_areas() > 0).all():
        noise /= 2
    return Q + noise



def _straight_path(disc, rng, K=4):
    """Frames on the straight line to a random admissible target, ends fixed."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = free[-1] = False
    return frames, free, GraphMetric(P, disc.triangles)


def record_damped_steps(monkeypatch, module) -> list:
    """``(damping, DampedStep)`` of every call of ``module.damped_step`` from now on (the
    least-squares step a minimizer takes, :mod:`meshopt_toolkit.least_squares`)."""
    steps, damped_step = [], module.damped_step

    def spy(solve, try_step, damping, **kwargs):
        out = damped_step(solve, try_step, damping, **kwargs)
        steps.append((damping, out))
        return out

    monkeypatch.setattr(module, "damped_step", spy)
    return steps
