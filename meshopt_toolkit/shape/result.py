"""What an optimization run returns: the per-iteration history and the result
(:func:`meshopt_toolkit.optimize.optimize` and the quasi-Newton driver both fill them)."""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from .._typing import FloatArray
from ..mesh import PlanarMesh

#: the phases timed per iteration (the columns of thesis tables 6.2, 6.5, 6.6)
PHASES = ("state", "derivative", "penalty_derivative", "gradient", "backtracking", "retraction")

@dataclass
class IterationRecord:
    """One row of the optimization history.

    ``objective`` is F = j + f (penalty), ``mean_shape_quality`` is Λ (6.25),
    ``min_aspect_ratio`` is AR (5.49) (on tets: the mean and the worst mean ratio); ``seconds`` maps each phase of :data:`PHASES` to
    its wall time in this iteration. Row 0 describes the initial mesh (step 0).
    """

    iteration: int
    j: float
    penalty: float
    objective: float
    mean_shape_quality: float
    min_aspect_ratio: float
    step: float
    backtracks: int
    gradient_norm: float
    seconds: dict = field(default_factory=dict)
    #: "steepest", "lbfgs" or "cg"
    method: str = "steepest"
    #: ‖grad F‖ at the start of the iteration over its first value (NaN in row 0)
    relative_gradient_norm: float = math.nan
    #: whether the accepted step satisfied the Wolfe conditions (None: Armijo-only search)
    wolfe: bool | None = None
    #: L-BFGS: the curvature pair of this step was rejected (s·ŷ not positive enough)
    pair_rejected: bool = False
    #: line-search trials outside M+ (f = +∞), rejected
    rejected_trials: int = 0
    #: the iterate's positions, in the record a callback gets (None in the history)
    points: FloatArray | None = field(default=None, repr=False, compare=False)

    def as_row(self) -> dict:
        """Flat dict (phase times as ``time_<phase>`` columns) for CSV/JSON."""
        row = {k: v for k, v in asdict(self).items() if k not in ("seconds", "points")}
        for phase in PHASES:
            row[f"time_{phase}"] = float(self.seconds.get(phase, 0.0))
        return row


@dataclass
class OptimizeResult:
    """Outcome of :func:`optimize` (scipy's field names where they fit).

    Attributes
    ----------
    mesh : PlanarMesh
        The final (admissible) mesh.
    x : (N, 2) array
        Its node positions.
    fun : float
        Final F = j + f.
    j : float
        Final shape functional.
    nit : int
        Iterations performed.
    status : str
        ``"converged"`` (gradient norm, objective change or (6.26)), ``"stopped"`` (by the
        callback), ``"max_iterations"`` or ``"step_too_small"``.
    success : bool
        True for ``"converged"`` and ``"stopped"``; reaching max iterations is a failure.
    message : str
    history : list of IterationRecord
    seconds : float
        Total wall time.
    variant : str
    """

    mesh: PlanarMesh
    x: FloatArray
    fun: float
    j: float
    nit: int
    status: str
    success: bool
    message: str
    history: list[IterationRecord]
    seconds: float
    variant: str
    method: str = "steepest"
    rejected_pairs: int = 0
    #: ``w`` of ``F = w j + f2`` (:class:`~meshopt_toolkit.shape.spec.ProblemSpec` ``scale``);
    #: ``j`` and the history's ``j`` are unweighed
    objective_weight: float = 1.0
    #: the initial mesh
    initial: PlanarMesh | None = None

    @property
    def frames(self) -> list[PlanarMesh]:
        """The initial and the final mesh (an optimization keeps no other iterate)."""
        return [self.mesh] if self.initial is None else [self.initial, self.mesh]

    def history_columns(self) -> dict[str, np.ndarray]:
        """The history as named columns (arrays), one entry per record."""
        rows = [r.as_row() for r in self.history]
        return {k: np.array([r[k] for r in rows]) for k in rows[0]}

    def phase_totals(self, iterations: int | None = None) -> dict[str, float]:
        """Wall time per phase summed over the first ``iterations`` iterations (all if None)."""
        recs = self.history[1 : None if iterations is None else iterations + 1]
        return {p: float(sum(r.seconds.get(p, 0.0) for r in recs)) for p in PHASES}

    def summary(self) -> dict:
        """JSON-ready summary of the run."""
        last = self.history[-1]
        return {
            "status": self.status,
            "success": self.success,
            "message": self.message,
            "variant": self.variant,
            "method": self.method,
            "iterations": self.nit,
            "rejected_curvature_pairs": self.rejected_pairs,
            "rejected_trials": int(sum(r.rejected_trials for r in self.history)),
            "j": self.j,
            "objective_weight": self.objective_weight,
            "penalty": last.penalty,
            "objective": self.fun,
            **self._quality(last),
            "seconds": self.seconds,
        }

    def _quality(self, last: IterationRecord) -> dict:
        """The final quality and size: Λ and AR of triangles, mean ratios of tets (the
        history's two quality columns hold the tets' mean and worst mean ratio)."""
        from ..mesh.kinds import is_tets

        if is_tets(self.mesh):
            return {"mean_mean_ratio": last.mean_shape_quality,
                    "min_mean_ratio": last.min_aspect_ratio,
                    "n_vertices": self.mesh.n_vertices, "n_tets": self.mesh.n_tets}
        return {"mean_shape_quality": last.mean_shape_quality,
                "min_aspect_ratio": last.min_aspect_ratio,
                "n_vertices": self.mesh.n_vertices, "n_triangles": self.mesh.n_triangles}


class PhaseTimer:
    """Wall time per phase of :data:`PHASES` in one iteration."""

    def __init__(self) -> None:
        self.seconds = dict.fromkeys(PHASES, 0.0)

    def add(self, phase: str, t0: float) -> float:
        now = time.perf_counter()
        self.seconds[phase] += now - t0
        return now
