"""What every operation returns: the :class:`Result` protocol, and the one convention of
its callbacks.

``mt.move``, ``mt.morph``, ``mt.deform`` and ``mt.optimize`` return results with

- ``mesh``: the final mesh (same connectivity and tags as the input);
- ``frames``: the path as a list of meshes (first = input, last = ``mesh``; an
  optimization keeps its initial and its final mesh);
- ``summary()``: a JSON-ready dict (:mod:`meshopt_toolkit.strict_json` writes it);
- ``seconds``: wall time;
- ``status``: a word, ``"converged"`` when the operation met its tolerance.

Callbacks: ``progress(fraction)`` with ``fraction`` in [0, 1], for a progress bar, and
``callback(record) -> bool | None`` once per iteration, returning True to stop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

__all__ = ["DoneMotion", "PathFrames", "PathIteration", "Result", "WrappedMotion"]


@runtime_checkable
class Result(Protocol):
    """The result protocol of the public operations (module docstring)."""

    @property
    def mesh(self) -> Any: ...

    @property
    def frames(self) -> list: ...

    @property
    def seconds(self) -> float: ...

    @property
    def status(self) -> str: ...

    def summary(self) -> dict: ...


@dataclass(frozen=True)
class PathIteration:
    """The record a path solver's ``callback`` gets once per iteration: the iteration
    number, the path energy ``E`` and the gradient norm ``|∇E|``."""

    iteration: int
    energy: float
    gradient_norm: float


class PathFrames:
    """What a morph's result derives from its ``points`` (one array per frame) and its
    ``status``."""

    @property
    def converged(self) -> bool:
        return self.status == "converged"

    @property
    def n_frames(self) -> int:
        return len(self.points)


class DoneMotion:
    """A motion's result: the solvers raise where they cannot reach the targets, so a
    returned one is done."""

    @property
    def status(self) -> str:
        """``"done"``: a returned motion always reached its targets (else it raises)."""
        return "done"


class WrappedMotion(DoneMotion):
    """A mesh's motion around its solver's result ``motion`` (which has ``seconds`` and
    ``summary()``)."""

    seconds = property(lambda self: self.motion.seconds, doc="Wall time.")

    def summary(self) -> dict:
        return {"status": self.status, **self.motion.summary()}
