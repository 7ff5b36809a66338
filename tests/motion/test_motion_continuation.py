"""Admissible paths frame by frame (motion/engine/continuation.py): the one continuation loop
(its step control on a path whose admissible steps are known in closed form) and the
extension through kept factors.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from motion_helpers import _random_admissible

from meshopt_toolkit.motion.engine.continuation import NoAdmissiblePathError, march
from meshopt_toolkit.motion.planar.metric import GraphMetric


def test_extension_through_kept_factors_matches_a_fresh_factorization(disc, rng):
    """A continuation reuses one factorization across its steps: the extension solved by
    PCG on a factorization made at another mesh is the one of a fresh factorization."""
    from meshopt_toolkit.motion.planar.continuation import extend
    from meshopt_toolkit.motion.planar.frame_blocks import FrameBlocks

    P = disc.points
    metric = GraphMetric(P, disc.triangles)
    handles = np.unique(disc.boundary_edges)
    Q = _random_admissible(disc, rng, 0.3)
    new = Q[handles] + 0.01 * rng.standard_normal((handles.size, 2))
    factors = FrameBlocks([np.arange(2 * (disc.n_vertices - handles.size))])
    extend(metric, P, handles, P[handles], factors)  # factorized at the reference
    assert not factors.stale
    fresh = extend(metric, Q, handles, new)
    reused = extend(metric, Q, handles, new, factors)
    assert np.array_equal(reused[handles], new)
    scale = np.abs(fresh - Q).max()
    assert np.abs(reused - fresh).max() <= 1e-6 * scale


@settings(max_examples=30, deadline=None)
@given(longest=st.floats(0.01, 1.0), n_frames=st.integers(2, 6))
def test_march_halves_refused_steps_and_reaches_every_frame(longest, n_frames):
    """A path whose steps are admissible when no longer than ``longest``: every accepted
    step is, every frame time is reached exactly, the state is the sum of the steps, and
    the halvings are the refused trials."""
    times = np.linspace(0.0, 1.0, n_frames)
    steps, refused, reported = [], [0], []

    def advance(Q, s_now, s_try):
        if s_try - s_now > longest:
            refused[0] += 1
            return None
        steps.append(s_try - s_now)
        return Q + (s_try - s_now)

    frames, splits = march(np.zeros(1), times, advance, max_splits=12,
                           progress=reported.append)
    assert splits == refused[0]
    assert all(step <= longest for step in steps)
    np.testing.assert_allclose([F[0] for F in frames], times, atol=1e-12)
    assert reported[-1] == 1.0 and all(np.diff(reported) > 0)


def test_march_gives_up_after_max_splits_and_on_vanishing_steps():
    with pytest.raises(NoAdmissiblePathError, match="halved 3 times"):
        march(np.zeros(1), np.array([0.0, 1.0]), lambda Q, a, b: None, max_splits=3)
    # every step refused until it is tiny: the steps shrink towards s = 0
    with pytest.raises(NoAdmissiblePathError, match="shrink"):
        march(np.zeros(1), np.array([0.0, 1.0]), lambda Q, a, b: None, max_splits=60)
