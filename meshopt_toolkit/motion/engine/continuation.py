"""The one continuation loop of the motions (:func:`march`): frames along the handle path,
each reached by steps of its parameter, a step that cannot be made admissible shortened.
Every cell kind configures it with its own ``advance`` (planar:
:mod:`..planar.continuation`; tets: :mod:`..tets.move`, :mod:`..tets.morph`; surfaces:
:mod:`..surface.move`, with the step rule :class:`GrowingSteps` and a ``fallback``).

How long a step is, is a :class:`StepRule`: :class:`HalvedSteps` (the default: each step
tries the rest of the way to the next frame, halved where refused) or
:class:`GrowingSteps` (steps of a given length, halved where refused and doubled back
after two taken in a row).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from ..._typing import FloatArray
from ..._options import require_at_least, require_positive
from ...errors import MeshoptError

class NoAdmissiblePathError(MeshoptError):
    """No admissible motion was found within the effort allowed."""


def check_frames_and_weight(frames: int, weight: float) -> None:
    """Refuse a path of fewer than two frames or a metric weight that is not positive
    (:class:`~meshopt_toolkit.errors.OptionError`)."""
    require_at_least("frames", frames, 2)
    require_positive("weight", weight)


def frame_times(steps: int, frames: int | None) -> tuple[FloatArray, np.ndarray]:
    """The times on ``[0, 1]`` a motion's continuation reaches (``steps`` steps, more
    where more ``frames`` are asked for) and the indices among them of the ``frames``
    returned (the two ends when ``frames`` is None)."""
    n_steps = max(int(steps), (frames or 2) - 1)
    times = np.linspace(0.0, 1.0, n_steps + 1)
    return times, np.round(np.linspace(0, n_steps, int(frames or 2))).astype(int)


class StepRule(Protocol):
    """How :func:`march` chooses the steps of the path parameter ``s``."""

    #: how many times a step was shortened
    splits: int

    def trial(self, s_now: float, s_goal: float) -> float:
        """The parameter the next step tries, in ``(s_now, s_goal]``; raises a
        :class:`~meshopt_toolkit.errors.MeshoptError` where the step is too short."""

    def refused(self, s_now: float) -> None:
        """The step tried was refused: the next one shorter, or raise where none may be."""

    def exhausted(self) -> bool:
        """Whether a refusal now would raise (no shorter step allowed)."""

    def taken(self) -> None:
        """The step tried was taken."""

    def restart(self) -> None:
        """The next step is a first one again (after a ``fallback`` of :func:`march`)."""


class HalvedSteps:
    """Each step tries the rest of the way to the next frame, halved where it is refused, at
    most ``max_splits`` times in a row (:class:`NoAdmissiblePathError`, naming ``what`` was
    not found); a step shorter than 1e-12 of the time is refused as well."""

    def __init__(self, max_splits: int, what: str) -> None:
        self.max_splits, self.what = int(max_splits), what
        self.splits, self.ds, self.tries = 0, None, 0

    def trial(self, s_now: float, s_goal: float) -> float:
        if self.ds is None:
            self.ds = s_goal - s_now
        s_try = s_goal if self.ds == s_goal - s_now else s_now + self.ds
        if s_try - s_now <= 1e-12 * max(1.0, s_goal):  # steps too short to go on
            raise NoAdmissiblePathError(f"no admissible {self.what} beyond s = {s_now:.6g} "
                                        "(the steps shrink towards it)")
        return s_try

    def refused(self, s_now: float) -> None:
        self.ds *= 0.5
        self.splits += 1
        self.tries += 1
        if self.tries > self.max_splits:
            raise NoAdmissiblePathError(
                f"no admissible {self.what} at s = {s_now + self.ds:.4g} (the step was "
                f"halved {self.max_splits} times)")

    def exhausted(self) -> bool:
        return self.tries >= self.max_splits

    def taken(self) -> None:
        self.ds, self.tries = None, 0

    restart = taken


class GrowingSteps:
    """Steps of ``length`` (the last one to the frame's time; a step within 1e-12 of it
    goes there), halved where refused, at least ``length · 2^-max_halvings`` (below,
    ``refusal(s_now)`` is raised); a halved step doubles again, up to ``length``, after two
    taken in a row."""

    def __init__(self, length: float, max_halvings: int,
                 refusal: Callable[[float], Exception]) -> None:
        self.length, self.shortest = length, length / 2.0**max_halvings
        self.refusal = refusal
        self.splits, self.dt, self.halvings, self.in_row = 0, length, 0, 0

    def trial(self, s_now: float, s_goal: float) -> float:
        return s_now + self.dt if s_goal - (s_now + self.dt) > 1e-12 else s_goal

    def refused(self, s_now: float) -> None:
        self.halvings += 1
        if self.exhausted():
            raise self.refusal(s_now)
        self.dt /= 2.0
        self.splits += 1

    def exhausted(self) -> bool:
        return self.dt / 2.0 < self.shortest

    def taken(self) -> None:
        self.in_row, self.halvings = (self.in_row + 1 if self.halvings == 0 else 1), 0
        if self.in_row >= 2 and self.dt < self.length:  # grows back after two taken
            self.dt, self.in_row = min(2.0 * self.dt, self.length), 0

    def restart(self) -> None:
        self.dt, self.halvings = self.length, 0


def march(start: FloatArray, times: FloatArray,
          advance: Callable[[FloatArray, float, float], FloatArray | None], *,
          max_splits: int | None = None, rule: StepRule | None = None,
          fallback: Callable[[FloatArray, float, float, bool], bool] | None = None,
          every_step: bool = False, progress: Callable[[float], None] | None = None,
          what: str = "position of the mesh for the handles") -> tuple[list[FloatArray], int]:
    """The one continuation loop of the motions: frames at ``times`` (increasing, from
    ``times[0]``), each reached by steps of the path parameter ``s``.

    A step from ``s_now`` tries the ``rule``'s ``s_try`` through ``advance(Q, s_now,
    s_try)``: the positions at ``s_try`` (the prediction checked admissible and relaxed),
    or None where no prediction is admissible; then the rule shortens the step, or raises
    where it may not. A refused step is first offered to ``fallback(Q, s_now, s_try,
    exhausted)`` (``exhausted``: the rule allows no shorter step): True where it changed how
    ``advance`` steps, and the step is tried again from the rule's first length.

    Parameters
    ----------
    max_splits, what
        The default rule, ``HalvedSteps(max_splits, what)``.
    rule : StepRule, optional
    fallback : callable, optional
    every_step : bool
        Every accepted step is a frame (else only those at ``times``).
    progress : callable ``s -> None``, optional
        Called after each accepted step.

    Returns
    -------
    frames : list of arrays, ``frames[0]`` a copy of ``start``
    splits : int
        How many times a step was shortened.
    """
    rule = HalvedSteps(max_splits, what) if rule is None else rule
    Q = np.array(start, float)
    s_now = float(times[0])
    frames = [Q.copy()]
    for s_goal in times[1:]:
        while s_now < s_goal:
            s_try = rule.trial(s_now, s_goal)
            moved = advance(Q, s_now, s_try)
            if moved is None:
                if fallback is not None and fallback(Q, s_now, s_try, rule.exhausted()):
                    rule.restart()
                else:
                    rule.refused(s_now)
                continue
            rule.taken()
            Q, s_now = moved, s_try
            if every_step:
                frames.append(Q.copy())
            if progress is not None:
                progress(s_now)
        if not every_step:
            frames.append(Q.copy())
    return frames, rule.splits
