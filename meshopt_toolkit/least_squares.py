"""The damped Gauss–Newton (Levenberg–Marquardt) step every least-squares minimizer of the
package takes: the planar and tet discrete geodesics
(:mod:`.riemannian.levenberg_marquardt`), the tet least squares
(:mod:`.motion.tets.least_squares`) and the surface morph (:mod:`.motion.surface.morph`).

One step of ``min E(x)`` with the gradient ``g`` and a Gauss–Newton matrix ``H`` at ``x``:
the caller's ``solve(λ, attempt)`` gives the step of the damped system ``(H + λD) s = −g``
(None where that matrix is not positive definite); :func:`..descent.backtrack` tries it
along the caller's trial ``lengths`` (the full step by default; a step cap and halvings
where the caller guards a constraint), each trial judged by the caller's ``try_step``
(a decrease, admissibility, no contact); where every trial is refused ``λ`` grows by
``increase`` and the step is solved again, at most ``attempts`` times. After an accepted
trial ``update`` gives the next ``λ``: :func:`gain_ratio_damping` (the decrease achieved
over the model's, :func:`model_decrease`) or :func:`step_length_damping` (whether the full
step was taken). Plain functions of arrays, numpy only.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Generic, TypeVar

from ._typing import FloatArray
from .descent import backtrack

Payload = TypeVar("Payload")

#: what ``try_step`` returns to end the minimization at this trial (neither accepted nor
#: refused: the caller found the minimum, e.g. a trial its energy cannot judge)
STOP = object()


@dataclass
class DampedStep(Generic[Payload]):
    """What :func:`damped_step` did.

    Attributes
    ----------
    outcome : "accepted", "stationary" (the first step's model decrease too small to
        try), "stopped" (``try_step`` returned :data:`STOP`) or "refused" (every trial
        of every attempt)
    damping : the ``λ`` of the next step (after ``update`` where accepted)
    step : the last step solved (None where none was)
    length : the fraction of ``step`` accepted
    payload : what ``try_step`` returned for the accepted trial
    """

    outcome: str
    damping: float
    step: FloatArray | None = None
    length: float = 0.0
    payload: Payload | None = None

    @property
    def accepted(self) -> bool:
        return self.outcome == "accepted"


def model_decrease(g: FloatArray, step: FloatArray, h_step: FloatArray) -> float:
    """The Gauss–Newton model's decrease along ``step``, ``−gᵀs − ½ sᵀHs`` (``h_step`` is
    ``H s``; for ``E = ½|r|²``, ``g = Jᵀr``, ``H = JᵀJ``)."""
    return -float(g @ step) - 0.5 * float(step @ h_step)


def gain_ratio_damping(damping: float, ratio: float, decrease: float = 1.0 / 3.0,
                       floor: float = 1e-12) -> float:
    """Marquardt's rule from the gain ratio (achieved over predicted decrease): ``λ``
    times ``decrease`` above 0.75, kept above 0.25, doubled below; at least ``floor``."""
    factor = decrease if ratio > 0.75 else 1.0 if ratio > 0.25 else 2.0
    return max(damping * factor, floor)


def step_length_damping(damping: float, length: float, floor: float = 1e-8) -> float:
    """``λ / 3`` (at least ``floor``) where the full step was accepted, else ``2λ``."""
    return max(damping / 3.0, floor) if length == 1.0 else damping * 2.0


def damped_step(solve: Callable[[float, int], FloatArray | None],
                try_step: Callable[[FloatArray, float], Payload | None], damping: float, *,
                attempts: int = 1, increase: float = 4.0,
                lengths: Callable[[FloatArray], Iterable[float]] | None = None,
                update: Callable[[float, float, Payload], float] | None = None,
                stationary: Callable[[FloatArray, float], bool] | None = None
                ) -> DampedStep[Payload]:
    """One damped Gauss–Newton step (module docstring).

    Parameters
    ----------
    solve : callable ``(λ, attempt) -> s``
        The step of the system damped by ``λ``; None where it is not positive definite
        (``λ`` then grows, the attempt spent).
    try_step : callable ``(s, t) -> payload``
        The trial ``x + t s`` judged: what it computed where accepted, None where refused,
        :data:`STOP` to end here.
    damping : float
        ``λ`` of the first attempt.
    attempts : int
        Steps solved at most, ``λ`` times ``increase`` after each refused one.
    increase : float
    lengths : callable ``s -> iterable of t``, optional
        The trial fractions of a step, first to last (default: the full step only).
    update : callable ``(λ, t, payload) -> λ``, optional
        The next ``λ`` after an accepted trial (default: kept).
    stationary : callable ``(s, λ) -> bool``, optional
        Asked of the first attempt's step before any trial: True ends the step there
        (the model promises too little).

    Returns
    -------
    DampedStep
    """
    step = None
    for attempt in range(attempts):
        step = solve(damping, attempt)
        if step is None:
            damping *= increase
            continue
        if attempt == 0 and stationary is not None and stationary(step, damping):
            return DampedStep("stationary", damping, step)
        found = backtrack(lambda t, s=step: try_step(s, t),
                          (1.0,) if lengths is None else lengths(step))
        if found is not None:
            length, payload = found
            if payload is STOP:
                return DampedStep("stopped", damping, step)
            if update is not None:
                damping = update(damping, length, payload)
            return DampedStep("accepted", damping, step, length, payload)
        damping *= increase
    return DampedStep("refused", damping, step)

