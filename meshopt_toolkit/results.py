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

from dataclasses import dataclass, replace
from typing import Any, Protocol, runtime_checkable

__all__ = ["DoneMotion", "PathFrames", "PathIteration", "Result", "WrappedMotion"]


@runtime_checkable
class Result(Protocol):
    """The result protocol of the public operations (module docstring): read-only
    ``mesh``, ``frames``, ``seconds``, ``status`` and ``summary()``."""

    mesh: Any
    frames: list
    seconds: float
    status: str

    def summary(self) -> dict: ...


@dataclass(frozen=True)
class PathIteration:
    """The record a path solver's ``callback`` gets once per iteration: the iteration
    number, the path energy ``E`` and the gradient norm ``|∇E|``."""

    iteration: int
    energy: float
    gradient_norm: float


class PathFrames:
    """What a morph's result derives from its ``points`` (one array per frame), its
    ``status`` and the other fields of a discrete geodesic's frames (``nit``, ``energy``,
    ``gradient_norm``, ``initial_path``, ``seconds``, ``strain_bound``, ``similarity``, and
    the per-frame ``stats`` of the morph and of the ``linear`` interpolation)."""

    def scaled_up(self, scale, source):
        """This morph of the meshes at unit size, at the user's scale (a
        :class:`~meshopt_toolkit.scaling.UnitScale`): frames, the similarity's centre and
        shift and the user's ``source`` (the rest is scale-free)."""
        return replace(self, points=scale.up(self.points), source=source,
                       similarity=self.similarity.scaled_up(scale))

    def path_summary(self) -> dict:
        """The part of ``summary()`` that every distortion morph has."""
        return {"status": self.status, "converged": self.converged,
                "iterations": int(self.nit), "energy": float(self.energy),
                "gradient_norm": float(self.gradient_norm), "initial_path": self.initial_path,
                "seconds": float(self.seconds),
                "strain_bound": [float(v) for v in self.strain_bound],
                "similarity": self.similarity.as_dict(), "ours": self.stats.as_dict(),
                "linear": self.linear.as_dict()}

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


@dataclass
class WrappedMotion(DoneMotion):
    """A mesh's motion around its solver's result ``motion`` (which has ``seconds`` and
    ``summary()``): what :func:`meshopt_toolkit.move` returns for a mesh in space.

    Attributes
    ----------
    mesh : the moved mesh's type
        The moved mesh (same cells, tags and names), handles bitwise at their targets.
    frames : list of meshes of that type
        The motion (first = input, last = ``mesh``): ``frames`` meshes when asked for,
        else the input and ``mesh``.
    motion : the solver's result
        Its points are those of the vertices in some cell, in order.
    """

    mesh: Any
    frames: list
    motion: Any

    seconds = property(lambda self: self.motion.seconds, doc="Wall time.")

    def summary(self) -> dict:
        return {"status": self.status, **self.motion.summary()}
