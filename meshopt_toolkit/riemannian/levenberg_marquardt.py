"""The Levenberg–Marquardt method of the discrete geodesic, for metrics whose path energy
is a sparse nonlinear least-squares problem ``E = |r|²`` in the free coordinates of the
frames (the per-triangle distortion metric: :mod:`meshopt_toolkit.motion.planar.path`).

The metric provides the problem through :class:`PathModelMetric` (``path_model``): the
residuals, the normal equations of a step (gradient, step matrix, Levenberg–Marquardt's
scaling) and the admissibility of frames (:class:`LeastSquaresPath`), and the solver of
the damped step systems (:class:`StepSolver`). Each step is the package's one damped
Gauss–Newton step (:func:`..least_squares.damped_step`), configured, with the stop rules,
by the path model's :class:`IterationRules` (``iteration_rules``; the surface morph's:
:mod:`meshopt_toolkit.motion.surface.path`), else by :class:`LeastSquaresRules`: the full
step only, the damping quadrupled per refused attempt and updated by Marquardt's gain
ratio (:func:`..least_squares.gain_ratio_damping`). A trial with an inadmissible frame is
rejected like a trial that raises the energy.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .._typing import FloatArray
from ..errors import NotAdmissibleError, OptionError
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
                   anchor: FloatArray | None = None):
        """The path energy of ``frames`` (K+1, N, d) in the coordinates ``free`` (K+1, N)
        marks (frame 0 never moves), with the boundaries ``boundary_edges`` kept simple;
        ``anchor`` replaces the embedding's metric-specific part at ``Q_0``. A
        :class:`LeastSquaresPath`, or a model with ``iteration_rules(frames, options)``
        (:class:`IterationRules`: the surface metric's)."""


def require_interior_frames(free: np.ndarray, anchor: FloatArray | None, model: str) -> None:
    """Refuse, for a path ``model`` that moves every vertex of the interior frames, a
    ``free`` mask (K+1, N) that says otherwise or an ``anchor`` (:class:`OptionError`)."""
    inner = np.zeros_like(free, dtype=bool)
    inner[1:-1] = True
    if anchor is not None or not np.array_equal(free, inner):
        raise OptionError(f"the {model} path model moves every vertex of the interior "
                          "frames and takes no anchor")


def _length(r: FloatArray, K: int) -> float:
    """``Σ_k |X(Q_{k+1}) − X(Q_k)|`` from the residual (see :class:`LeastSquaresPath`)."""
    return float(np.sum(np.linalg.norm(r.reshape(K, -1), axis=1)) / np.sqrt(K))


def _result(frames: FloatArray, r: FloatArray, E: float, gnorm: float, it: int, status: str,
            history: list) -> DiscreteGeodesic:
    K = frames.shape[0] - 1
    return DiscreteGeodesic(frames, np.full(K + 1, np.nan), E, _length(r, K), it, gnorm,
                            status == "converged", 0, status, history)


class IterationRules(Protocol):
    """One path model's rules of the Levenberg–Marquardt iteration: its energy at the
    iterate, the damped step's configuration (:func:`..least_squares.damped_step`'s
    arguments) and its stop rules. A path model provides them through
    ``iteration_rules(frames, options)``; the sum of squares ``E = |r|²`` of
    :class:`LeastSquaresPath` has :class:`LeastSquaresRules`."""

    damping: float  # λ of the next step

    def start(self) -> str | None:
        """The status where the start itself ends the iteration, else None."""

    def before_step(self, callback) -> str | None:
        """The gradient and step matrix at the iterate, and the tests before a step."""

    def solve(self, damping: float, attempt: int) -> FloatArray | None: ...

    def try_step(self, step: FloatArray, t: float): ...

    def step_arguments(self) -> dict:
        """The keyword arguments of :func:`..least_squares.damped_step`."""

    def after_step(self, found, callback) -> str | None:
        """The iterate after ``found`` and the tests after a step."""

    def result(self, status: str | None) -> DiscreteGeodesic:
        """The result (``status`` None: the iterations ran out)."""


class LeastSquaresRules:
    """The rules of :class:`LeastSquaresPath`: stop at ``|∇E| ≤ max(gtol·max(1, √E),
    rtol·|∇E₀|)``; the full step only, λ from 1e-3, quadrupled per refused attempt (30 at
    most) and updated by Marquardt's gain ratio; a barely damped step whose predicted
    decrease is below E's resolution judged by its gradient."""

    def __init__(self, path: LeastSquaresPath, frames: FloatArray,
                 options: LevenbergMarquardtOptions) -> None:
        self.path, self.frames, self.options = path, frames, options
        self.newton = options.newton
        self.it, self.history, self.done = 0, [], None

    def start(self) -> str | None:
        path, frames = self.path, self.frames
        if not path.admissible(frames):
            raise NotAdmissibleError("the initial path is not admissible")
        if path.n_unknowns == 0:
            r, _ = path.evaluate(frames, jacobian=False)
            self.done = _result(frames, r, float(r @ r), 0.0, 0, "converged", [])
            return "converged"
        self.r, self.g, self.H, self.d = path.normal_equations(frames, self.newton)
        self.E = float(self.r @ self.r)
        self.damping = 1e-3
        self.blocks = path.step_solver(self.options.factors)
        return None

    def before_step(self, callback) -> str | None:
        self.it += 1
        E, options = self.E, self.options
        self.gnorm = gnorm = 2.0 * float(np.linalg.norm(self.g))
        self.history.append((E, gnorm))
        if callback is not None and callback(self.it - 1, E, gnorm):
            self.it -= 1
            return "stopped"  # the callback returned True
        if self.it == 1:
            self.g0 = gnorm
        if gnorm <= max(options.gtol * max(1.0, np.sqrt(E)), options.rtol * self.g0):
            self.it -= 1
            return "converged"
        self.x = self.path.unknowns(self.frames)
        # whether an admissible trial's model decrease exceeded E's rounding (None: no
        # admissible trial was evaluated)
        self.resolvable: bool | None = None
        self.judged = None  # the normal equations at a step judged by its gradient
        self.tried = self.damping  # the damping of the step being tried
        return None

    def solve(self, damping: float, attempt: int):
        self.tried = damping
        d = self.d
        try:
            return self.blocks.solve(self.H.damped(damping * (d + 1e-12 * d.max())), -self.g,
                                     self.options.cg_rtol)
        except FloatingPointError:  # not positive definite (Newton): damp more
            return None

    def try_step(self, step: FloatArray, t: float):
        path, E, g = self.path, self.E, self.g
        trial = path.with_unknowns(self.x + step)
        if not path.admissible(trial):
            return None
        r_t, _ = path.evaluate(trial, jacobian=False)
        E_t = float(r_t @ r_t)
        predicted = 2.0 * model_decrease(g, step, self.H @ step)  # of E = |r|²
        self.resolvable = bool(self.resolvable or predicted > ENERGY_RESOLUTION * E)
        if self.tried <= UNDAMPED and predicted <= ENERGY_RESOLUTION * E:
            # E cannot judge the model's own step (its change is rounding): the
            # gradient, computed to full precision, does; where it does not fall
            # either, the minimum to machine precision
            self.judged = path.normal_equations(trial, self.newton)
            return (trial, None) if 2.0 * float(np.linalg.norm(self.judged[1])) < self.gnorm \
                else STOP
        if np.isfinite(E_t) and E_t < E:
            return trial, (E - E_t) / max(predicted, 1e-300)
        return None

    def step_arguments(self) -> dict:
        decrease = self.options.lambda_decrease
        return dict(attempts=30, increase=4.0,
                    update=lambda lam, t, out: lam if out[1] is None else
                    gain_ratio_damping(lam, out[1], decrease))

    def after_step(self, found, callback) -> str | None:
        if found.outcome == "stopped":
            self.it -= 1
            return "converged"
        if not found.accepted:
            # no step lowers E, and the admissible ones promised no more than E's
            # floating-point resolution: the minimum to machine precision (a tight gtol
            # cannot be met there)
            return "converged" if self.resolvable is False else "stalled"
        self.frames = found.payload[0]
        self.path.frames = self.frames
        self.r, self.g, self.H, self.d = (self.path.normal_equations(self.frames, self.newton)
                                          if self.judged is None else self.judged)
        self.E = float(self.r @ self.r)
        return None

    def result(self, status: str | None) -> DiscreteGeodesic:
        if self.done is not None:
            return self.done
        status = "max_iter" if status is None else status
        gnorm = 2.0 * float(np.linalg.norm(self.g))
        if status == "max_iter" and gnorm <= self.options.gtol * max(1.0, np.sqrt(self.E)):
            status = "converged"
        return _result(self.frames, self.r, self.E, gnorm, self.it, status, self.history)


def levenberg_marquardt(path: LeastSquaresPath, frames: FloatArray,
                        options: LevenbergMarquardtOptions, callback=None) -> DiscreteGeodesic:
    """Minimize the path energy of ``path`` from ``frames`` over its unknowns; see
    :func:`.discrete_geodesic.discrete_geodesic` and :class:`.LevenbergMarquardtOptions`.
    The path model's ``iteration_rules(frames, options)`` (:class:`IterationRules`) where
    it has them, else :class:`LeastSquaresRules`, configure each damped step and say when
    to stop."""
    own = getattr(path, "iteration_rules", None)
    rules = own(frames, options) if callable(own) else LeastSquaresRules(path, frames, options)
    status = rules.start()
    for _ in range(options.max_iterations if status is None else 0):
        status = rules.before_step(callback)
        if status is None:
            found = damped_step(rules.solve, rules.try_step, rules.damping,
                                **rules.step_arguments())
            rules.damping = found.damping
            status = rules.after_step(found, callback)
        if status is not None:
            break
    return rules.result(status)
