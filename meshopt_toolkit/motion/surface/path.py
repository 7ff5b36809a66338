"""The discrete path energy of the surface metric (:mod:`.metric`) as the path model of
:func:`~meshopt_toolkit.riemannian.discrete_geodesic.discrete_geodesic`
(:meth:`.metric.SurfaceGraphMetric.path_model`), with the surface morph's rules of the
Levenberg–Marquardt iteration (:class:`SurfaceRules`, an
:class:`~meshopt_toolkit.riemannian.levenberg_marquardt.IterationRules`).

The frames ``Q_0 … Q_K`` (both ends fixed) have the energy

    E = ½ Σ_k |X(Q_{k+1}) − X(Q_k)|² (+ the frames' contact barriers)

(angle differences wrapped into [−π, π)); the unknowns are every coordinate of the
interior frames. A frame is admissible where no triangle is degenerate and no triangle
folds (:class:`.folds.FoldTest` against the source) that the target does not fold.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray
from ...descent import halvings
from ...errors import NotAdmissibleError
from ...kernels.surface import aspect_ratios
from ...least_squares import model_decrease, step_length_damping
from ...riemannian.geodesic_result import DiscreteGeodesic
from ...riemannian.path_options import LevenbergMarquardtOptions
from .bending import dihedral_angles, wrap
from .folds import FoldTest
from .path_system import PathSystem

__all__ = ["SurfacePathProblem", "SurfacePath", "SurfacePathOptions", "SurfaceRules"]

#: the default tolerance of the surface morph's stopping tests (:class:`SurfacePathOptions`)
RTOL = 5e-2
#: conjugate-gradient iterations per Levenberg–Marquardt step at most, and the count above
#: which the kept per-frame factors are refactorized at the next iterate
CG_ITERATIONS, CG_REFACTORIZE = 30, 15
#: a frame whose worst relative quality is within this fraction of the worse end's is as
#: healthy as it (the rounding of the aspect ratios of a moved triangle)
HEALTHY_RTOL = 1e-12


@dataclass(frozen=True)
class SurfacePathOptions(LevenbergMarquardtOptions):
    """:class:`~meshopt_toolkit.riemannian.path_options.LevenbergMarquardtOptions` of the
    surface path model: ``max_iterations`` and ``rtol`` (stop where the Gauss–Newton model
    of the next step predicts, or a step achieved, a decrease below ``rtol·E``), and
    ``stop_when_healthy`` (stop where every interior frame's worst relative quality is at
    least the worse end's, the start included). ``gtol``, ``cg_rtol``, ``newton``,
    ``lambda_decrease`` and ``factors`` do not apply."""

    max_iterations: int = 10
    rtol: float = RTOL
    stop_when_healthy: bool = False


class SurfacePathProblem:
    """The path energy's pieces of a surface metric's frames ending at ``target``: the
    embedding, the segments' residuals, the Jacobians, admissibility and health."""

    def __init__(self, metric, target: FloatArray) -> None:
        self.metric, self.target = metric, target
        V0, F = metric.reference, metric.triangles
        self.membrane, self.shell = metric.membrane, metric.shell
        self.sqrt_c, self.sqrt_m = metric.sqrt_c, metric.sqrt_m
        self.weight = metric.weight
        self.folds = FoldTest(V0, F)
        self._memo: dict = {}
        #: triangles folded at the target itself: not asked of the frames
        self.allowed = self.fold_mask(target)
        self.triangles, self.rest_quality = F, aspect_ratios(V0, F)
        #: the worse end's worst relative quality (the source's is 1): no path does better
        self.floor = min(1.0, self.worst(target))

    def _once(self, kind: str, Q: FloatArray, make: Callable):
        """``make(Q)`` once per frame (by its values: a frame copied into the discrete
        geodesic's array is the same frame; frames are never changed in place, so the
        array held is the frame's values)."""
        key = (kind, Q.shape, hash(Q.tobytes()))
        hit = self._memo.get(key)
        if hit is None or not (hit[0] is Q or np.array_equal(hit[0], Q)):
            if len(self._memo) >= 96:
                self._memo.clear()
            hit = self._memo[key] = (Q, make(Q))
        return hit[1]

    def fold_mask(self, Q: FloatArray) -> np.ndarray:
        """The folded triangles of ``Q`` against the source (:class:`FoldTest`)."""
        return self._once("folds", Q, self.folds.mask)

    def worst(self, Q: FloatArray) -> float:
        """The worst relative quality of ``Q``."""
        return self._once("worst", Q, lambda Q: float(self.relative_quality(Q).min())
                          if len(self.triangles) else 1.0)

    def relative_quality(self, Q: FloatArray) -> FloatArray:
        """Per triangle the aspect ratio over its value in the source (T,)."""
        return aspect_ratios(Q, self.triangles) / self.rest_quality

    def healthy(self, path) -> bool:
        """Every interior frame's worst relative quality at least the worse end's: the
        path's worst frame is then the worse end, the best any path can have (to
        ``HEALTHY_RTOL``)."""
        return all(self.worst(Q) >= self.floor * (1.0 - HEALTHY_RTOL) for Q in path[1:-1])

    def embed(self, Q: FloatArray):
        """``(m^½ Q, w φ, θ)``; None where a triangle is degenerate."""
        return self._once("embed", Q, self._embed)

    def _embed(self, Q: FloatArray):
        phi = self.membrane.values(Q)
        if not np.all(np.isfinite(phi)):
            return None
        return (self.sqrt_m * Q.ravel(), self.weight * phi.ravel(),
                dihedral_angles(Q, self.shell.diamonds))

    def admissible(self, Q: FloatArray) -> bool:
        return not np.any(self.fold_mask(Q) & ~self.allowed)

    def segment(self, X0, X1) -> FloatArray:
        """The residual of one segment, ``X(Q_{k+1}) − X(Q_k)``."""
        return np.concatenate([X1[0] - X0[0], X1[1] - X0[1],
                               self.sqrt_c * wrap(X1[2] - X0[2])])

    def residuals(self, path) -> list:
        """The segments' residuals of the frames ``path``."""
        X = [self.embed(Q) for Q in path]
        return [self.segment(X[k], X[k + 1]) for k in range(len(path) - 1)]

    def jacobian(self, Q: FloatArray) -> sp.csr_matrix:
        """``∂X/∂Q`` (3N + 3T + E) × 3N (:meth:`.SurfaceGraphMetric.jacobian`)."""
        return self.metric.jacobian(Q)


class SurfacePath:
    """The path model of the surface metric: the frames (K+1, N, 3), every coordinate of
    the interior frames unknown, with ``contact`` (a
    :class:`.morph_contact.PathContact` on a clean start, or None) the frames' barriers
    in the energy, every step capped by CCD and taken only on a clean path."""

    def __init__(self, metric, frames: FloatArray, contact=None) -> None:
        self.frames = np.array(frames, dtype=float)
        self.problem = metric.path_problem(self.frames[-1])
        self.contact = contact
        self.n_unknowns = (len(self.frames) - 2) * self.frames[0].size

    def iteration_rules(self, frames: FloatArray, options) -> SurfaceRules:
        return SurfaceRules(self.problem, list(frames), options, self.contact)


class SurfaceRules:
    """The surface morph's Levenberg–Marquardt rules (:mod:`.morph`): the energy ``½|r|²``
    plus the frames' barriers (their stiffness set at each iterate); each step a
    :func:`...least_squares.damped_step` from ``λ = 1e-4``, 4 attempts at most, ``λ`` ×10
    per refused attempt, 8 trials halving from the CCD cap, then
    :func:`...least_squares.step_length_damping`; the step systems solved by
    :class:`.path_system.PathSystem` with kept factors, refactorized after a slow solve.
    It stops where the path is healthy (``stop_when_healthy``, the start included, then
    after each step), where a barely damped step's model decrease is below ``rtol·E``
    (status "converged"), where a step lowered ``E`` by at most ``rtol·E`` ("converged"),
    where no trial is accepted ("stalled"), or where the callback returns True ("stopped",
    called after each step with the steps taken, ``E`` and ``|∇E|``)."""

    def __init__(self, problem: SurfacePathProblem, path: list, options, contact) -> None:
        self.problem, self.path, self.contact = problem, path, contact
        self.rtol = options.rtol
        self.healthy = getattr(options, "stop_when_healthy", False)
        self.steps, self.gnorm, self.initial_energy = 0, 0.0, 0.0
        self.system, self.history = None, []

    def _energy(self, X, path):
        K = len(path) - 1
        r = [self.problem.segment(X[k], X[k + 1]) for k in range(K)]
        barrier = 0.0 if self.contact is None else self.contact.energy(path)
        return 0.5 * float(sum(v @ v for v in r)) + barrier, r

    def start(self) -> str | None:
        problem, path = self.problem, self.path
        if len(path) < 3:
            return "converged"
        if not all(problem.embed(Q) is not None and problem.admissible(Q) for Q in path[1:-1]):
            raise NotAdmissibleError("the initial path has a degenerate or folded triangle")
        if self.healthy and problem.healthy(path):
            self.initial_energy = None  # returned unevaluated
            return "healthy"
        self.X = [problem.embed(Q) for Q in path]
        self.E, self.r = self._energy(self.X, path)
        self.initial_energy, self.n = self.E, path[0].size
        self.system = PathSystem(len(path) - 1)
        self.damping = 1e-4
        self.fresh = True  # factorize the preconditioner's blocks (again)
        return None

    def before_step(self, callback) -> str | None:
        problem, path, r, contact = self.problem, self.path, self.r, self.contact
        K = len(path) - 1
        self.D = D = [problem.jacobian(path[j]) for j in range(1, K)]
        g = np.concatenate([D[j - 1].T @ (r[j - 1] - r[j]) for j in range(1, K)])
        self.barriers = None
        if contact is not None:
            if contact.set_stiffness(path, g):  # κ set or raised: the energy with it
                self.E, self.r = self._energy(self.X, path)
            g = g + contact.gradient(path)
            self.barriers = contact.hessians(path)
        self.g, self.gnorm = g, float(np.linalg.norm(g))
        self.history.append((self.E, self.gnorm))
        return None

    def solve(self, damping: float, attempt: int) -> FloatArray:
        system = self.system
        system.update(self.D, damping, self.fresh or attempt > 0, self.barriers)
        step = -system.solve(self.g, max_iterations=CG_ITERATIONS)
        # the kept factors serve while conjugate gradients converge quickly with them
        self.fresh = system.iterations > CG_REFACTORIZE
        return step

    def try_step(self, step: FloatArray, alpha: float):
        problem, path, X, n = self.problem, self.path, self.X, self.n
        K = len(path) - 1
        trial = [path[0]] + [path[j] + alpha * step[(j - 1) * n:j * n].reshape(-1, 3)
                             for j in range(1, K)] + [path[K]]
        Xt = [X[0]] + [problem.embed(Q) for Q in trial[1:-1]] + [X[K]]
        if any(x is None for x in Xt):
            return None
        E_trial, r_trial = self._energy(Xt, trial)
        if E_trial < self.E and all(problem.admissible(Q) for Q in trial[1:-1]) and (
                self.contact is None or self.contact.clean(trial)):
            return trial, Xt, E_trial, r_trial
        return None

    def stationary(self, step: FloatArray, damping: float) -> bool:
        # a barely damped step whose Gauss–Newton model promises under rtol·E
        return damping <= 1e-3 and model_decrease(
            self.g, step, self.system.product(step, 0.0)) <= self.rtol * self.E

    def step_arguments(self) -> dict:
        path, contact = self.path, self.contact
        return dict(attempts=4, increase=10.0, stationary=self.stationary,
                    lengths=lambda step: halvings(
                        1.0 if contact is None else contact.cap(path, step), count=8),
                    update=lambda damping, alpha, _: step_length_damping(damping, alpha))

    def after_step(self, found, callback) -> str | None:
        if not found.accepted:  # the model stationary, or every trial refused
            return "converged" if found.outcome == "stationary" else "stalled"
        self.steps += 1
        trial, Xt, E_trial, r_trial = found.payload
        decrease = self.E - E_trial
        self.path, self.X, self.E, self.r = trial, Xt, E_trial, r_trial
        if callback is not None and callback(self.steps, self.E, self.gnorm):
            return "stopped"
        if self.healthy and self.problem.healthy(self.path):
            return "healthy"
        if decrease <= self.rtol * self.E:
            return "converged"
        return None

    def result(self, status: str | None) -> DiscreteGeodesic:
        status = "max_iterations" if status is None else status
        r = self.problem.residuals(self.path)
        return DiscreteGeodesic(
            np.array(self.path), np.full(len(self.path), np.nan),
            0.5 * float(sum(v @ v for v in r)), float(sum(np.linalg.norm(v) for v in r)),
            self.steps, self.gnorm, status == "converged", 0, status, self.history,
            self.initial_energy, 0 if self.system is None else self.system.factorizations)
