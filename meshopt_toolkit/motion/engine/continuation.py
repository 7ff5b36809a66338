"""The one continuation loop of the motions (:func:`march`): frames along the handle path,
each reached by steps of its parameter, a step that cannot be made admissible halved.
Every cell kind configures it with its own ``advance`` (planar:
:mod:`..planar.continuation`; tets: :mod:`..tets.move`, :mod:`..tets.morph`).
"""

from __future__ import annotations

from collections.abc import Callable

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


def march(start: FloatArray, times: FloatArray,
          advance: Callable[[FloatArray, float, float], FloatArray | None], *,
          max_splits: int, progress: Callable[[float], None] | None = None,
          what: str = "position of the mesh for the handles") -> tuple[list[FloatArray], int]:
    """The one continuation loop of the motions: frames at ``times`` (increasing, from
    ``times[0]``), each reached by steps of the path parameter ``s``.

    A step from ``s_now`` tries ``s_try``, the next frame's time first, through
    ``advance(Q, s_now, s_try)``: the positions at ``s_try`` (the prediction checked
    admissible and relaxed), or None where no prediction is admissible; then the step is
    halved, at most ``max_splits`` times in a row (:class:`NoAdmissiblePathError`, naming
    ``what`` was not found); a step shorter than 1e-12 of the time is refused as well.
    ``progress(s)`` after each accepted step.

    Returns
    -------
    frames : list of arrays, ``frames[0]`` a copy of ``start``
    splits : int
        How many times a step was halved.
    """
    Q = np.array(start, float)
    s_now = float(times[0])
    frames, splits = [Q.copy()], 0
    for s_goal in times[1:]:
        while s_now < s_goal:
            ds, moved = s_goal - s_now, None
            for _ in range(max_splits + 1):
                s_try = s_goal if ds == s_goal - s_now else s_now + ds
                if s_try - s_now <= 1e-12 * max(1.0, s_goal):  # steps too short to go on
                    raise NoAdmissiblePathError(
                        f"no admissible {what} beyond s = {s_now:.6g} (the steps shrink "
                        "towards it)")
                moved = advance(Q, s_now, s_try)
                if moved is not None:
                    break
                ds *= 0.5
                splits += 1
            else:
                raise NoAdmissiblePathError(
                    f"no admissible {what} at s = {s_now + ds:.4g} (the step was halved "
                    f"{max_splits} times)")
            Q, s_now = moved, s_try
            if progress is not None:
                progress(s_now)
        frames.append(Q.copy())
    return frames, splits
