"""Riemannian descent methods for discretize-then-optimize shape optimization.

Algorithm 2 of the thesis (§6.4.1, SPEC §7): at every iterate the derivative of
``F = j + f2`` is turned into a gradient by the Riesz map of a metric, and a line search
along a retraction picks the step. One iteration (:mod:`meshopt_toolkit.shape.driver`)
runs every method: ``method="steepest"`` is the thesis' steepest descent with Armijo
backtracking (kept for its tables); ``"lbfgs"`` (Riemannian L-BFGS) and ``"cg"``
(nonlinear CG, Hestenes–Stiefel+) use the same metric as inner product, the same
retraction and a Wolfe line search. Variants are named ``"<metric>-<retraction>"``:

=======================  ==================  ==========================================
variant                  gradient metric     retraction
=======================  ==================  ==========================================
euclidean-euclidean      Euclidean (5.2)     Q + s d (6.20), with the travel guard (6.23)
elasticity-euclidean     elasticity (5.3)    Q + s d, travel guard
complete-euclidean       complete (5.34)     Q + s d, travel guard
complete-complete        complete (5.34)     a retraction of the complete metric
=======================  ==================  ==========================================

complete-complete's retraction (:mod:`meshopt_toolkit.riemannian.retractions`) is by
default the second-order one, ``Q + s d + ½ s² A(Q, d)`` with the geodesic acceleration
``A`` (5.35): one Hessian-vector product per iteration instead of a geodesic integration
whose step count grows with the mesh. ``retraction="exp"`` is the thesis'
exponential map (6.19) with the rescaling lemma, integrated as ``exp_options`` say.

The objective is any object with ``value(Q) -> float`` and ``derivative(Q) -> (N, 2)``
(e.g. :class:`~meshopt_toolkit.fem.poisson.PoissonObjective`); the optional penalty is f2
(:class:`~meshopt_toolkit.penalties.QualityPenalty`) with its own ``β^penalty``, the
complete metric uses a second f2 with ``β^metric``.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from ._options import check_choice, require_at_least
from ._typing import FloatArray
from .errors import OptimizationError, OptionError
from .kernels.triangles import aspect_ratios
from .mesh import PlanarMesh, require_admissible
from .mesh.kinds import is_tets
from .shape.options import OptimizeOptions
from .shape.spec import ProblemSpec
from .shape.result import PHASES, IterationRecord, OptimizeResult
from .shape.setup import (  # noqa: F401  (the variants' table and set-up, re-exported)
    DEFAULT_RETRACTION,
    EXP_DEFAULTS,
    RETRACTIONS,
    VARIANT_PARTS,
    VARIANTS,
    _make_metric,
    _make_retraction,
    _retraction_kind,
    _retraction_options,
    area_relative_beta,
    contact_options,
    default_metric_beta,
)
from .shape.problem import max_travel_step
from .scaling import UnitScale, at_unit_size, size_scale

__all__ = [
    "DEFAULT_METHOD",
    "DEFAULT_PENALTY_BETA",
    "DEFAULT_RETRACTION",
    "DEFAULT_VARIANT",
    "EXP_DEFAULTS",
    "METHODS",
    "PHASES",
    "RETRACTIONS",
    "THESIS_PENALTY_SETS",
    "VARIANTS",
    "VARIANT_PARTS",
    "IterationRecord",
    "Objective",
    "OptimizeOptions",
    "OptimizeResult",
    "ProblemSpec",
    "default_metric_beta",
    "max_travel_step",
    "optimize",
    "thesis_penalty_beta",
]

logger = logging.getLogger(__name__)

#: the default variant: the elasticity metric extends the boundary's motion into the
#: interior, so its L-BFGS iteration count hardly grows with the mesh (thesis set 2 with
#: β4 fixed: 75 / 110 / 152 / 163 iterations on the 146 / 541 / 2198 / 13,586-vertex
#: discs, min AR kept ≥ 0.88× the initial one); complete-euclidean moves the boundary
#: vertices first and on the 13,586-vertex disc squeezes its boundary triangles to min AR
#: 7e-4 and stops (step too small) far from the minimizer (``bench_optimize.py --defaults``)
DEFAULT_VARIANT = "elasticity-euclidean"

#: optimization methods; the default was chosen from ``benchmarks/bench_optimize.py``
METHODS = ("lbfgs", "cg", "steepest")
DEFAULT_METHOD = "lbfgs"



@runtime_checkable
class Objective(Protocol):
    """What :func:`optimize` needs from a shape functional j(Q).

    - ``value(Q) -> float`` for ``Q`` of shape ``(N, 2)``;
    - ``derivative(Q) -> (N, 2)`` — the Euclidean derivative: ``dF(Q)[V] = Σ derivative(Q) * V``
      (the metric turns it into a gradient);
    - optionally ``value_and_derivative(Q) -> (float, (N, 2))`` sharing work between the two.

    Raise :class:`~meshopt_toolkit.errors.NotAdmissibleError` for configurations the
    objective cannot evaluate, and check the derivative with
    :func:`meshopt_toolkit.diagnostics.check_gradient` before optimizing.
    :class:`~meshopt_toolkit.fem.poisson.PoissonObjective` is the reference implementation.
    """

    def value(self, Q: FloatArray) -> float: ...

    def derivative(self, Q: FloatArray) -> FloatArray: ...


#: a converged ``scale="auto"`` run with an exact constraint (the area, a body's
#: barycenter) is restarted from its last iterate at most this many times, f2's anchor
#: moved there and j's weight multiplied by ``ANCHOR_GROWTH``, until a restart lowers j by
#: at most ``RESTART_GAIN · tolerance`` relative; without a constraint many objectives
#: fall without bound as the domain shrinks or grows, and the restarts would only drive
#: the mesh to the quality floor
#: (:func:`_follow_anchor`; ``benchmarks/bench_shape2d.py``: the hole under stresses (2, 1)
#: reaches the closed-form axis ratio 2 and a body in Stokes flow drags less than the
#: best ellipse)
ANCHOR_RESTARTS = 5
ANCHOR_GROWTH = 2.0
RESTART_GAIN = 10.0


#: β^penalty parameter sets of thesis table 6.3, with β4 given per vertex (β4/N_V)
THESIS_PENALTY_SETS = {
    1: (1.0, 0.5, 0.0, 0.1),
    2: (0.1, 0.01, 0.0, 0.001),
    3: (0.015, 0.005, 0.0, 0.0005),
}


def thesis_penalty_beta(parameter_set: int, n_vertices: int) -> tuple[float, float, float, float]:
    """β^penalty of thesis table 6.3 with β4 unscaled (table value × N_V)."""
    b1, b2, b3, b4_per_vertex = THESIS_PENALTY_SETS[parameter_set]
    return (b1, b2, b3, b4_per_vertex * n_vertices)


#: the default β^penalty of ``meshopt optimize`` and ``apply_coord_shape_optimization``: thesis
#: parameter set 2 at the thesis' mesh size (146 vertices: β4 = 0.001·146), with β4 kept
#: fixed on other meshes. f2's anchor term (β4/2N)‖Q − Q_ref‖² is then a mean over the
#: vertices (a discrete L² norm of the displacement) and means the same on every
#: resolution; set 2's β4 = 0.001·N makes it a sum, so on fine meshes moving the interior
#: costs N times more than squeezing the boundary layer of triangles, and the optimum
#: does exactly that. Measured (complete-euclidean, L-BFGS, default rhs), min AR
#: initial → final: disc_2198 0.682 → 0.340 (set 2) vs 0.768 (this); elasticity-euclidean
#: on disc_13586 0.687 → 0.776 (this), j = −0.0936 as on the coarser discs. β3 = 0.01 is
#: the contact barrier (:func:`~meshopt_toolkit.shape.setup.contact_options`): it is zero
#: unless a boundary vertex comes within ⅔ of the shortest boundary edge of a boundary
#: edge it does not belong to, so it never acts on the discs, and it keeps holes and
#: re-entrant notches of users' domains from closing (without it, straight-line trials
#: cross an unmeshed hole or notch with every area positive and are all rejected).
DEFAULT_PENALTY_BETA = (0.1, 0.01, 0.01, 0.146)


def optimize(
    mesh: PlanarMesh,
    objective: Objective | None = None,
    *,
    problem: ProblemSpec | None = None,
    variant: str = DEFAULT_VARIANT,
    method: str = DEFAULT_METHOD,
    penalty: Sequence[float] | None = DEFAULT_PENALTY_BETA,
    metric_beta: Sequence[float] | None = None,
    fixed: np.ndarray | None = None,
    max_iterations: int = 1000,
    options: OptimizeOptions | Mapping | None = None,
    callback: Callable[[IterationRecord], bool | None] | None = None,
    progress: Callable[[float], None] | None = None,
) -> OptimizeResult:
    """Minimize ``F(Q) = j(Q) + f2(Q; Q0)`` over admissible meshes by a Riemannian
    descent method: L-BFGS, nonlinear CG or steepest descent (thesis algorithm 2, §6.4.1).

    Every trial configuration outside M+ (a non-positive area, a boundary touching
    itself, an objective refusing it) counts as ``F = +∞`` and is rejected by the line
    search; every iterate is admissible.

    Parameters
    ----------
    mesh : PlanarMesh or TetMesh
        Initial mesh; also the reference Q_ref of the penalty. Must be admissible. A tet
        mesh is optimized with the tet kind's admissibility, metric and distortion penalty
        (:mod:`meshopt_toolkit.shape.tets`; ``penalty``'s β1 is that penalty's weight).
    objective : object with ``value(Q)`` and ``derivative(Q)`` (shape (N, 2)); None:
        ``problem``'s objective (:meth:`ProblemSpec.make_objective`: Poisson, elasticity
        compliance or Stokes dissipation).
    problem : :class:`~meshopt_toolkit.shape.spec.ProblemSpec`, optional
        The user's problem by physical group: fixed and moving boundary parts (added to
        ``fixed``), PDE, boundary conditions and objective (when ``objective`` is None),
        the area and the moving body's barycenter kept exactly (``keep_area``,
        ``keep_barycenter``, lbfgs and cg), the weight of j (``scale``;
        ``F = w j + f2``, the result's ``j`` is unweighed). ``scale="auto"`` weighs j to
        the mesh, rejects trial steps whose worst triangle falls below half its initial
        aspect ratio and restarts a run that finds no step with a smaller weight
        (:data:`~meshopt_toolkit.shape.spec.AUTO_GRADIENT_NORM`, ``QUALITY_GUARD``);
        with an exact constraint (``keep_area``, ``keep_barycenter``) a converged run is
        restarted with f2's anchor at its last iterate and a larger weight
        (:data:`ANCHOR_RESTARTS`), so that f2 does not hold the shape back.
    variant : one of :data:`VARIANTS`
    method : one of :data:`METHODS`: ``"lbfgs"`` (Riemannian L-BFGS with the metric as
        inner product and a Wolfe line search), ``"cg"`` (Hestenes–Stiefel+), or
        ``"steepest"`` (the thesis' Armijo steepest descent).
    penalty : (β1, β2, β3, β4) of the penalty f2 added to j (β4 unscaled: f2 divides it
        by 2N; β2 is weighed so that the area term pushes the boundary as on the unit
        disc, :func:`~meshopt_toolkit.shape.setup.area_relative_beta`); None or all zero
        = unpenalized. The default
        :data:`DEFAULT_PENALTY_BETA` is that of ``meshopt optimize`` and the filter.
    metric_beta : β^metric of the complete metric (default :func:`default_metric_beta`).
    fixed : vertex indices (or boolean mask) that do not move.
    max_iterations : maximum number of iterations.
    options : :class:`~meshopt_toolkit.shape.options.OptimizeOptions` (or a mapping of
        its fields): stopping rules (``tolerance``, ``gtol``), line search (``sigma``,
        ``tau``, ``c2``, ``segment_fraction``, ``min_step``), L-BFGS ``memory`` and
        ``lbfgs_preconditioner``, ``metric_options``, ``retraction`` and ``exp_options``.
    callback : called as ``callback(record)`` after each iteration with its
        :class:`IterationRecord` (``record.points``: the iterate's positions); returning
        True stops (status ``"stopped"``).
    progress : called as ``progress(fraction)`` after each iteration, the fraction of
        ``max_iterations`` done (an upper bound: most runs stop earlier).

    Returns
    -------
    OptimizeResult
        The mesh is optimized at unit size (divided by its own size, the objective read
        at the user's scale: :func:`~meshopt_toolkit.scaling.at_unit_size`) and ``x``,
        ``mesh`` and the callback's ``record.points`` scaled back: a mesh scaled by any
        factor, with an objective of the scaled mesh, optimizes to the result scaled by
        it; the history's numbers are those of the unit-size problem.

    Raises
    ------
    OptionError
        An unknown variant, method, retraction or option, an option out of range, a
        retraction or ``exp_options`` given to a variant that moves along straight lines,
        ``max_iterations < 0``.
    OptimizationError
        A direction that is not a descent direction (a wrong derivative), or every vertex
        fixed.
    """
    check_choice(variant, VARIANTS, "variant", error=OptionError)
    check_choice(method, METHODS, "method", error=OptionError)
    require_at_least("max_iterations", max_iterations, 0)
    o = OptimizeOptions.of(options)
    exp_options = o.exp_options
    retraction = _retraction_kind(variant, o.retraction, exp_options)
    mesh = (mesh.require_admissible() if is_tets(mesh)
            else require_admissible(mesh, "shape optimization"))
    spec = ProblemSpec() if problem is None else problem
    if objective is None:
        objective = spec.make_objective(mesh)
    # at unit size (the mesh divided by its size, the objective read at the user's scale)
    # and back: the same optimization at every scale
    scale = size_scale(mesh, columns=3 if is_tets(mesh) else 2)
    run = dict(spec=spec, variant=variant, method=method, penalty=penalty,
               metric_beta=metric_beta, fixed=fixed, max_iterations=max_iterations,
               options=o, retraction=retraction,
               step=_iteration_hook(callback, progress, max_iterations, scale))
    return at_unit_size(
        lambda unit: _optimize(unit, objective if scale.is_identity
                               else _UserScaleObjective(objective, scale, mesh.points),
                               **run),
        scale, (mesh,), lambda result, sc: _scaled_up(result, sc, mesh))


def _optimize(mesh: PlanarMesh, objective, *, spec: ProblemSpec, variant: str, method: str,
              penalty, metric_beta, fixed, max_iterations: int, options: OptimizeOptions,
              retraction, step) -> OptimizeResult:
    """:func:`optimize` of an admissible mesh with checked options."""
    from .shape.preconditioners import make_preconditioner
    from .shape.driver import run_descent
    from .shape.problem import ShapeProblem
    from .shape.spec import GUARD_FACTOR, GUARD_TRIES, QUALITY_GUARD, ScaledObjective

    o, exp_options = options, options.exp_options
    tets = is_tets(mesh)
    N = mesh.n_vertices
    free = None
    stay = spec.fixed_mask(mesh)
    if fixed is not None or stay is not None:
        free = np.ones(N, bool) if stay is None else ~stay
        if fixed is not None:
            free[np.asarray(fixed)] = False
        if not free.any():
            raise OptimizationError("every vertex is fixed: nothing to optimize")
    if (spec.keep_area or spec.keep_barycenter) and method == "steepest":
        raise OptionError("keep_area and keep_barycenter need method 'lbfgs' or 'cg'")
    auto = spec.scale == "auto"
    f2, anchored = None, None
    if tets:
        from .shape.tets import tet_setup

        f2, metric, Problem, floor = tet_setup(mesh, variant, penalty, o.lbfgs_preconditioner)
        cells, boundary, norm_metric = mesh.tets, mesh.boundary_faces, metric
    else:
        if penalty is not None and any(b != 0 for b in penalty):
            from .penalties import QualityPenalty

            contact = contact_options(mesh) if penalty[2] > 0 else {}
            beta = area_relative_beta(penalty, mesh)
            f2 = QualityPenalty(mesh, beta=beta, **contact)

            def anchored(start: PlanarMesh):
                """The same f2 with its anchor ``Q_ref`` (β4) at ``start``."""
                return QualityPenalty(start, beta=beta, **contact)
        metric = _make_metric(variant, mesh, metric_beta, dict(o.metric_options or {}))
        cells, boundary, norm_metric = mesh.triangles, mesh.boundary_edges, None
        Problem = ShapeProblem
        floor = QUALITY_GUARD * aspect_ratios(mesh.points, cells).min() if auto else None
    retract = (None if retraction is None
               else _make_retraction(retraction, metric, exp_options, free))
    constraint = spec.constraint(mesh, lambda Q, P: metric.riesz(Q, P, free=free), free)
    weight = spec.weight(lambda: _gradient_norm(mesh, objective, free, spec, norm_metric))
    start = time.perf_counter()

    def descend(start, penalty_f2, iterations: int, done: int = 0, w: float | None = None):
        w = weight if w is None else w
        weighed = objective if w == 1.0 else ScaledObjective(objective, w)
        problem = Problem(weighed, penalty_f2, metric, cells, boundary, free, constraint,
                          quality_floor=floor)
        h0 = None if tets else make_preconditioner(
            o.lbfgs_preconditioner, metric_kind=VARIANT_PARTS[variant][0], method=method,
            mesh=start, penalty=penalty_f2, free=free)
        hook = step if step is None or not done else (
            lambda record, Q: step(dataclasses.replace(record, iteration=record.iteration + done),
                                   Q))
        out = run_descent(start, problem, method=method, variant=variant, retraction=retract,
                          max_iterations=iterations, options=o, callback=hook, h0=h0)
        return _unweighed(out, objective, w)

    attempts = []
    for attempt in range(1 + (GUARD_TRIES if auto else 0)):
        result = descend(mesh, f2, max_iterations)
        attempts.append(result)
        if not auto or result.status != "step_too_small":
            break
        logger.info("no step at weight %.3g (%s): restarting with %.3g", weight, result.message,
                    weight / GUARD_FACTOR)
        weight /= GUARD_FACTOR
    if result.status == "step_too_small":  # no weight went on to the end: the least j of all
        result = min(attempts, key=lambda r: r.j)
    if auto and anchored is not None and constraint is not None:  # planar f2 only
        result = _follow_anchor(
            result, lambda start, n, done, k: descend(start, anchored(start), n, done,
                                                      weight * ANCHOR_GROWTH ** k),
            mesh, max_iterations, o.tolerance)
    result.seconds = time.perf_counter() - start
    result.initial = mesh
    return result


def _follow_anchor(result: OptimizeResult, descend, mesh: PlanarMesh, max_iterations: int,
                   tolerance: float | None) -> OptimizeResult:
    """Restart a converged run from its last iterate with f2's anchor ``Q_ref`` moved there
    and the weight ``w`` of j multiplied by :data:`ANCHOR_GROWTH`, at most
    :data:`ANCHOR_RESTARTS` times, until a restart lowers j by at most
    ``RESTART_GAIN · tolerance`` relative (None: every restart).

    The anchor term ``β4/(2N)‖Q − Q_ref‖²`` and the quality terms of f2 steady each run,
    but at a fixed ``Q_ref = Q0`` and weight they also hold the moving boundary back: the
    minimizer of ``w j + f2`` is not that of j (a hole under the stresses ``(2, 1)`` stops
    at the axis ratio 1.8 instead of 2). Restarted from its own minimizer (a proximal
    point iteration) the anchor adds nothing at a fixed point, and the growing weight
    leaves f2 the part of a barrier: the worst triangle stays above the quality floor
    of the initial mesh. ``descend(start, iterations, done, k)`` runs restart ``k``; the
    histories are joined (the objective column jumps at each restart: F changes with
    the anchor and the weight); a restart that does not converge within the iterations
    left is dropped (one stopped by the callback is kept), though the callback has seen
    its iterations."""
    for k in range(1, ANCHOR_RESTARTS + 1):
        left = max_iterations - result.nit
        if result.status != "converged" or left <= 0:
            break
        again = descend(mesh.with_points(result.x), left, result.nit, k)
        if again.status not in ("converged", "stopped"):
            break
        gain = (result.j - again.j) / max(abs(result.j), 1e-300)
        for r in again.history[1:]:
            r.iteration += result.nit
        again.history = result.history + again.history[1:]
        again.nit = len(again.history) - 1
        again.rejected_pairs += result.rejected_pairs
        result = again
        if tolerance is not None and gain <= RESTART_GAIN * tolerance:
            break
    return result


def _iteration_hook(callback, progress, max_iterations: int, scale: UnitScale):
    """The drivers' ``(record, Q)`` hook that calls ``progress(fraction)`` and
    ``callback(record)`` with the iterate's positions (at the user's scale) in
    ``record.points``."""
    if callback is None and progress is None:
        return None

    def hook(record: IterationRecord, Q: FloatArray) -> bool:
        if progress is not None:
            progress(min(1.0, record.iteration / max(int(max_iterations), 1)))
        return callback is not None and bool(callback(dataclasses.replace(
            record, points=scale.up(Q))))

    return hook


class _UserScaleObjective:
    """The user's objective ``j`` read at unit size: ``U ↦ j(s U)``, derivative
    ``s j'(s U)`` (``s`` the scale's factor; the vertices still at the user's ``rest``
    bitwise, :meth:`~meshopt_toolkit.scaling.UnitScale.points_up`)."""

    def __init__(self, objective, scale: UnitScale, rest: FloatArray):
        self.objective, self.scale, self.rest = objective, scale, rest

    def value(self, U: FloatArray) -> float:
        return self.objective.value(self.scale.points_up(U, self.rest))

    def derivative(self, U: FloatArray) -> FloatArray:
        return self.scale.up(self.objective.derivative(self.scale.points_up(U, self.rest)))


def _scaled_up(result: OptimizeResult, scale: UnitScale, mesh: PlanarMesh) -> OptimizeResult:
    """An optimization of the mesh at unit size at the user's scale: the optimized points
    (the vertices it leaves alone bitwise) and the initial mesh; the history's numbers are
    those of the unit-size problem (its ``j`` the user's)."""
    x = scale.points_up(result.x, mesh.points)
    result.x, result.mesh, result.initial = x, mesh.with_points(x), mesh
    return result


def _unweighed(result: OptimizeResult, objective, weight: float) -> OptimizeResult:
    """``j`` of the result and its history without the weight ``w`` of ``F = w j + f2``
    (``objective`` and ``penalty`` stay those of the weighed problem)."""
    result.objective_weight = weight
    if weight == 1.0:
        return result
    result.j = float(objective.value(result.x))
    for r in result.history:
        r.j = r.j / weight
    return result


def _gradient_norm(mesh, objective, free, spec: ProblemSpec, metric=None) -> float:
    """``‖grad j‖`` at the initial mesh in ``metric`` (None: the elasticity metric),
    projected onto the tangent space of ``spec``'s constraints."""
    from .riemannian.metrics import ElasticityMetric

    Q = mesh.points
    P = np.asarray(objective.derivative(Q), dtype=float)
    if free is not None:
        P = np.where(free[:, None], P, 0.0)
    metric = ElasticityMetric(mesh) if metric is None else metric
    g = metric.riesz(Q, P, free=free)
    constraint = spec.constraint(mesh, lambda X, V: metric.riesz(X, V, free=free), free)
    if constraint is not None:
        g = constraint.project(Q, g)
    return math.sqrt(max(float(np.sum(P * g)), 0.0))
