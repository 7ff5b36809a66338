"""Admissible paths frame by frame (motion/engine/continuation.py): the one continuation loop
(its step control on a path whose admissible steps are known in closed form) and the
extension through kept factors.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
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


def _toy(longest: float, log: list):
    """A path whose steps are admissible when no longer than ``longest``: the state is the
    sum of the steps taken; ``log`` gets each trial's (s_now, s_try, taken)."""

    def advance(Q, s_now, s_try):
        ok = s_try - s_now <= longest
        log.append((s_now, s_try, ok))
        return Q + (s_try - s_now) if ok else None

    return advance


def test_growing_steps_halve_a_refused_step_and_double_back_after_two_taken():
    """The recurrence by hand: steps of 1/4, the 2nd and 5th trials refused."""
    from meshopt_toolkit.motion.engine.continuation import GrowingSteps

    trials, times = [], [0.0]

    def advance(Q, s_now, s_try):
        trials.append(s_try)
        return None if len(trials) in (2, 5) else Q + (s_try - s_now)

    rule = GrowingSteps(0.25, 3, lambda s: AssertionError(s))
    frames, splits = march(np.zeros(1), [0.0, 1.0], advance, rule=rule, every_step=True,
                           progress=times.append)
    assert trials == [0.25, 0.5, 0.375, 0.5, 0.75, 0.625, 0.75, 1.0]
    assert times == [0.0, 0.25, 0.375, 0.5, 0.625, 0.75, 1.0] and splits == 2
    assert [F[0] for F in frames] == times  # every accepted step a frame


@settings(max_examples=40, deadline=None)
@given(longest=st.floats(0.002, 1.0), steps=st.integers(1, 8), n_frames=st.integers(2, 4))
@example(longest=0.9999999999999999, steps=1, n_frames=2)  # the first step just too long
def test_growing_steps_take_only_admissible_steps_and_reach_every_frame(longest, steps,
                                                                      n_frames):
    """Steps admissible up to ``longest``: the first ``k`` trials (``length / 2^k ≤
    longest``) are refused, every step taken is admissible, every refused one is not, the
    splits are the refusals and every frame time is reached exactly."""
    from meshopt_toolkit.motion.engine.continuation import GrowingSteps

    length = 1.0 / steps
    k = 0  # the halvings down to an admissible step (exact: powers of two)
    while length / 2**k > longest:
        k += 1
    log = []
    times = np.linspace(0.0, 1.0, n_frames)
    frames, splits = march(np.zeros(1), times, _toy(longest, log),
                           rule=GrowingSteps(length, 12, lambda s: AssertionError(s)))
    np.testing.assert_allclose([F[0] for F in frames], times, atol=1e-12)
    taken = [b - a for a, b, ok in log if ok]
    refused = [b - a for a, b, ok in log if not ok]
    assert splits == len(refused) and all(d <= longest for d in taken)
    assert all(d > longest for d in refused)
    first = []
    march(np.zeros(1), [0.0, 1.0], _toy(longest, first),
          rule=GrowingSteps(length, 12, lambda s: AssertionError(s)))
    assert [ok for _, _, ok in first[:k + 1]] == [False] * k + [True]
    assert first[k][1] == min(1.0, length / 2**k)


def test_a_fallback_restarts_the_steps_and_otherwise_the_rule_refuses():
    """A fallback is offered every refused step with whether the rule is exhausted; where it
    takes over (True) the steps start again at their first length."""
    from meshopt_toolkit.motion.engine.continuation import GrowingSteps, HalvedSteps

    seen, mode = [], ["plain"]

    def advance(Q, s_now, s_try):
        return None if mode[0] == "plain" else Q + (s_try - s_now)

    def fallback(Q, s_now, s_try, exhausted):
        seen.append((s_try, exhausted))
        if exhausted:
            mode[0] = "other"
        return exhausted

    times = [0.0]
    rule = GrowingSteps(0.5, 2, lambda s: AssertionError(s))
    march(np.zeros(1), [0.0, 1.0], advance, rule=rule, fallback=fallback, every_step=True,
          progress=times.append)
    assert seen == [(0.5, False), (0.25, False), (0.125, True)] and times == [0.0, 0.5, 1.0]

    class Refused(Exception):
        pass

    with pytest.raises(Refused, match="at 0.0"):
        march(np.zeros(1), [0.0, 1.0], lambda Q, a, b: None, fallback=lambda *a: False,
              rule=GrowingSteps(0.5, 2, lambda s: Refused(f"at {s}")))
    seen.clear()
    mode[0] = "plain"
    frames, splits = march(np.zeros(1), [0.0, 1.0], advance, fallback=fallback,
                           rule=HalvedSteps(2, "toy"))
    assert seen == [(1.0, False), (0.5, False), (0.25, True)] and splits == 2
    assert frames[-1][0] == 1.0
