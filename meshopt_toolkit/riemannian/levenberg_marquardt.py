"""The Levenberg–Marquardt method of the discrete geodesic, for metrics whose path energy
is a sparse nonlinear least-squares problem ``E = |r|²`` in the free coordinates of the
frames (the per-triangle distortion metric: :mod:`meshopt_toolkit.motion.planar.path`).

The metric provides the problem through :class:`PathModelMetric` (``path_model``): the
residuals, the normal equations of a step (gradient, step matrix, Levenberg–Marquardt's
scaling) and the admissibility of frames (:class:`LeastSquaresPath`), and the solver of
the damped step systems (:class:`StepSolver`). Each step is the package's one damped
Gauss–Newton step (:func:`..least_squares.damped_step`): the full step only, the damping
quadrupled per refused attempt and updated by Marquardt's gain ratio
(:func:`..least_squares.gain_ratio_damping`). A trial with an inadmissible frame is
rejected like a trial that raises the energy.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .._typing import FloatArray
from ..errors import NotAdmissibleError
from ..least_squares import STOP, damped_step, gain_ratio_damping, model_decrease
from .geodesic_result import DiscreteGeodesic
from .path_options import ENERGY_RESOLUTION, UNDAMPED, LevenbergMarquardtOptions


class StepMatrix(Protocol):
    """The matrix of a step (``JᵀJ``, or the Hessian of ``½E``), never assembled."""

    def damped(self, shift: FloatArray) -> StepMatrix:
        """The matrix plus ``diag(shift)``."""

    def __matmul__(self, x: FloatArray) -> FloatArray: ...


class StepSolver(Protocol):
    """Solves the damped step systems (kept across iterations, and across calls through
    ``LevenbergMarquardtOptions.factors``)."""

    def solve(self, A: StepMatrix, b: FloatArray, rtol: float) -> FloatArray:
        """``A⁻¹ b`` to the relative residual ``rtol``; FloatingPointError where ``A`` is
        not positive definite."""


class LeastSquaresPath(Protocol):
    """The discrete path energy of K segments as ``E = |r|²``: ``r`` is K equal blocks,
    block ``k`` being ``√K (X(Q_{k+1}) − X(Q_k))`` for the metric's isometric embedding
    ``X`` (so ``Σ_k |r_k| / √K`` is the polygon's length). The unknowns are the free
    coordinates; ``frames`` (K+1, N, 2) holds the fixed ones."""

    frames: FloatArray
    n_unknowns: int

    def unknowns(self, frames: FloatArray) -> FloatArray: ...

    def with_unknowns(self, x: FloatArray) -> FloatArray: ...

    def evaluate(self, frames: FloatArray, jacobian: bool):
        """The residual vector (and, with ``jacobian``, its sparse Jacobian)."""

    def normal_equations(self, frames: FloatArray, newton: bool = False
                         ) -> tuple[FloatArray, FloatArray, StepMatrix, FloatArray]:
        """``r``, the gradient ``Jᵀr`` (half ``∇E``), the step matrix (``JᵀJ``, or the
        Hessian of ``½E`` with ``newton``) and the diagonal of ``JᵀJ``."""

    def admissible(self, frames: FloatArray) -> bool: ...

    def step_solver(self, kept: StepSolver | None = None) -> StepSolver:
        """A solver for this path's step systems (``kept``, checked to fit, or a new one)."""


class PathModelMetric(Protocol):
    """A metric whose discrete geodesics Levenberg–Marquardt computes (optional capability
    of :class:`~meshopt_toolkit.riemannian.metrics.Metric`); the points' columns are its
    ``dimension`` where it has one (3 for tets), else 2."""

    def path_model(self, frames: FloatArray, free: np.ndarray, boundary_edges=None,
                   anchor: FloatArray | None = None) -> LeastSquaresPath:
        """The path energy of ``frames`` (K+1, N, d) in the coordinates ``free`` (K+1, N)
        marks (frame 0 never moves), with the boundaries ``boundary_edges`` kept simple;
        ``anchor`` replaces the embedding's metric-specific part at ``Q_0``."""


def _length(r: FloatArray, K: int) -> float:
    """``Σ_k |X(Q_{k+1}) − X(Q_k)|`` from the residual (see :class:`LeastSquaresPath`)."""
    return float(np.sum(np.linalg.norm(r.reshape(K, -1), axis=1)) / np.sqrt(K))


def _result(frames: FloatArray, r: FloatArray, E: float, gnorm: float, it: int, status: str,
            history: list) -> DiscreteGeodesic:
    K = frames.shape[0] - 1
    return DiscreteGeodesic(frames, np.full(K + 1, np.nan), E, _length(r, K), it, gnorm,
                            status == "converged", 0, status, history)


def levenberg_marquardt(path: LeastSquaresPath, frames: FloatArray,
                        options: LevenbergMarquardtOptions, callback=None) -> DiscreteGeodesic:
    """Minimize the path energy of ``path`` from ``frames`` over its unknowns; see
    :func:`.discrete_geodesic.discrete_geodesic` and :class:`.LevenbergMarquardtOptions`."""
    gtol, rtol, max_iterations = options.gtol, options.rtol, options.max_iterations
    cg_rtol, newton, lambda_decrease = options.cg_rtol, options.newton, options.lambda_decrease
    if not path.admissible(frames):
        raise NotAdmissibleError("the initial path is not admissible")
    if path.n_unknowns == 0:
        r, _ = path.evaluate(frames, jacobian=False)
        return _result(frames, r, float(r @ r), 0.0, 0, "converged", [])
    r, g, H, d = path.normal_equations(frames, newton)
    E = float(r @ r)
    lam = 1e-3
    blocks = path.step_solver(options.factors)
    status = "max_iter"
    history = []
    it = 0
    for it in range(1, max_iterations + 1):
        gnorm = 2.0 * float(np.linalg.norm(g))
        history.append((E, gnorm))
        if callback is not None and callback(it - 1, E, gnorm):
            status = "stopped"  # the callback returned True
            it -= 1
            break
        if it == 1:
            g0 = gnorm
        if gnorm <= max(gtol * max(1.0, np.sqrt(E)), rtol * g0):
            status = "converged"
            it -= 1
            break
        x = path.unknowns(frames)
        # whether an admissible trial's model decrease exceeded E's rounding (None: no
        # admissible trial was evaluated)
        resolvable: bool | None = None
        judged = None  # the normal equations at a step judged by its gradient
        tried = lam  # the damping of the step being tried

        def solve(damping: float, attempt: int):
            nonlocal tried
            tried = damping
            try:
                return blocks.solve(H.damped(damping * (d + 1e-12 * d.max())), -g, cg_rtol)
            except FloatingPointError:  # not positive definite (Newton): damp more
                return None

        def try_step(step: FloatArray, t: float):
            nonlocal resolvable, judged
            trial = path.with_unknowns(x + step)
            if not path.admissible(trial):
                return None
            r_t, _ = path.evaluate(trial, jacobian=False)
            E_t = float(r_t @ r_t)
            predicted = 2.0 * model_decrease(g, step, H @ step)  # of E = |r|²
            resolvable = bool(resolvable or predicted > ENERGY_RESOLUTION * E)
            if tried <= UNDAMPED and predicted <= ENERGY_RESOLUTION * E:
                # E cannot judge the model's own step (its change is rounding): the
                # gradient, computed to full precision, does; where it does not fall
                # either, the minimum to machine precision
                judged = path.normal_equations(trial, newton)
                return (trial, None) if 2.0 * float(np.linalg.norm(judged[1])) < gnorm else STOP
            if np.isfinite(E_t) and E_t < E:
                return trial, (E - E_t) / max(predicted, 1e-300)
            return None

        found = damped_step(solve, try_step, lam, attempts=30, increase=4.0,
                            update=lambda lam, t, out: lam if out[1] is None else
                            gain_ratio_damping(lam, out[1], lambda_decrease))
        lam = found.damping
        if found.outcome == "stopped":
            status = "converged"
            it -= 1
            break
        if not found.accepted:
            # no step lowers E, and the admissible ones promised no more than E's
            # floating-point resolution: the minimum to machine precision (a tight gtol
            # cannot be met there)
            status = "converged" if resolvable is False else "stalled"
            break
        frames = found.payload[0]
        path.frames = frames
        r, g, H, d = path.normal_equations(frames, newton) if judged is None else judged
        E = float(r @ r)
    gnorm = 2.0 * float(np.linalg.norm(g))
    if status == "max_iter" and gnorm <= gtol * max(1.0, np.sqrt(E)):
        status = "converged"
    return _result(frames, r, E, gnorm, it, status, history)
