"""Riemannian descent methods for discretize-then-optimize shape optimization.

Algorithm 2 of the thesis (§6.4.1, SPEC §7): at every iterate the derivative of
``F = j + f2`` is turned into a gradient by the Riesz map of a metric, and a line search
along a retraction picks the step. ``method="steepest"`` is the thesis' steepest descent
with Armijo backtracking (kept for its tables); ``"lbfgs"`` (Riemannian L-BFGS) and
``"cg"`` (nonlinear CG, Hestenes–Stiefel+) use the same metric as inner product, the same
retraction and a Wolfe line search (:mod:`meshopt_toolkit.shape`). Variants are
named ``"<metric>-<retraction>"``:

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
whose step count grows with the mesh (issue 16). ``retraction="exp"`` is the thesis'
exponential map (6.19) with the rescaling lemma, integrated as ``exp_options`` say.

The objective is any object with ``value(Q) -> float`` and ``derivative(Q) -> (N, 2)``
(e.g. :class:`~meshopt_toolkit.fem.poisson.PoissonObjective`); the optional penalty is f2
(:class:`~meshopt_toolkit.penalties.QualityPenalty`) with its own ``β^penalty``, the
complete metric uses a second f2 with ``β^metric``.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from ._linalg import dot as _dot
from ._typing import FloatArray
from .errors import OptimizationError
from .kernels.triangles import heights, quality_summary, signed_areas
from .mesh import PlanarMesh, require_admissible
from .shape.result import PHASES, IterationRecord, OptimizeResult, PhaseTimer

__all__ = [
    "DEFAULT_METHOD",
    "DEFAULT_PENALTY_BETA",
    "DEFAULT_RETRACTION",
    "DEFAULT_VARIANT",
    "EXP_DEFAULTS",
    "METHODS",
    "PHASES",
    "RETRACTIONS",
    "SIZE_RANGE",
    "THESIS_PENALTY_SETS",
    "VARIANTS",
    "VARIANT_PARTS",
    "IterationRecord",
    "Objective",
    "OptimizeResult",
    "default_metric_beta",
    "max_travel_step",
    "optimize",
    "thesis_penalty_beta",
]

logger = logging.getLogger(__name__)

#: variant -> (gradient metric, retraction along a curve of the complete metric?), the
#: table above (False: the straight line ``Q + s d``)
VARIANT_PARTS: dict[str, tuple[str, bool]] = {
    "euclidean-euclidean": ("euclidean", False),
    "elasticity-euclidean": ("elasticity", False),
    "complete-euclidean": ("complete", False),
    "complete-complete": ("complete", True),
}
VARIANTS = tuple(VARIANT_PARTS)

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

#: meshes whose bounding box diagonal lies outside this range are refused: the penalty
#: and the metrics are not scale-invariant (β2/Σ A and the β4 term scale like L⁻² and L²),
#: so the problem changes with the unit of length; on disc_146 (diagonal 2.8) scaled to a
#: diagonal of 3e-3 the complete metric's Riesz map already cancels to a non-descent
#: direction, and a diagonal of 100 with the default rhs ends with min AR ~1e-12
SIZE_RANGE = (1e-2, 1e2)

#: complete-complete's retractions: second order (the default) or the exponential map
RETRACTIONS = ("second-order", "exp")
DEFAULT_RETRACTION = "second-order"

#: default ``exp_options`` of ``retraction="exp"``: the geodesic's
#: line-search mode (:data:`meshopt_toolkit.riemannian.geodesics.LINE_SEARCH_OPTIONS`;
#: Bogacki–Shampine 3(2) at rtol 5e-2 with energy projection, positions only). Every trial
#: point is still a point of an (approximate) geodesic, admissible and checked exactly; pass
#: ``exp_options={"method": "auto"}`` (with ``retraction="exp"``) for the 1e-6-accurate map.
EXP_DEFAULTS = {"method": "line-search"}


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


def default_metric_beta(n_vertices: int) -> tuple[float, float, float, float]:
    """β^metric of thesis §6.4.3, (10, 1, 0, 1.46) for 146 vertices, i.e. β4 = 0.01·N."""
    return (10.0, 1.0, 0.0, 0.01 * n_vertices)


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


#: the default β^penalty of ``meshopt optimize`` and ``compute_shape_optimization``: thesis
#: parameter set 2 at the thesis' mesh size (146 vertices: β4 = 0.001·146), with β4 kept
#: fixed on other meshes. f2's anchor term (β4/2N)‖Q − Q_ref‖² is then a mean over the
#: vertices (a discrete L² norm of the displacement) and means the same on every
#: resolution; set 2's β4 = 0.001·N makes it a sum, so on fine meshes moving the interior
#: costs N times more than squeezing the boundary layer of triangles, and the optimum
#: does exactly that. Measured (complete-euclidean, L-BFGS, default rhs), min AR
#: initial → final: disc_2198 0.682 → 0.340 (set 2) vs 0.768 (this); elasticity-euclidean
#: on disc_13586 0.687 → 0.776 (this), j = −0.0936 as on the coarser discs.
DEFAULT_PENALTY_BETA = (0.1, 0.01, 0.0, 0.146)


def max_travel_step(Q: FloatArray, triangles: np.ndarray, d: FloatArray) -> float:
    """Largest step allowed by the node-travel safeguard (6.23).

    A trial step ``s`` is refused when ``s |d_i| ≥ ½ h_l`` for a vertex ``i`` at local
    position ``l`` of any triangle, ``h_l`` that triangle's height from ``i``. Returns
    ``min ½ h_l / |d_i|`` (inf when ``d`` vanishes).
    """
    h = heights(Q, triangles)  # (T, 3), height from local vertex l onto the opposite edge
    speed = np.linalg.norm(d, axis=1)[triangles]  # (T, 3)
    with np.errstate(divide="ignore"):
        limit = np.where(speed > 0, 0.5 * h / speed, np.inf)
    return float(limit.min())


def _retraction_options(exp_options: dict | None):
    """The complete-complete retraction's
    :class:`~meshopt_toolkit.riemannian.geodesics.GeodesicOptions`: ``exp_options`` on top
    of :data:`EXP_DEFAULTS`; an ``"options"`` entry (a ``GeodesicOptions``) replaces the
    defaults, the other entries override its fields."""
    from .riemannian.geodesic_options import GeodesicOptions

    user = dict(exp_options or {})
    base = user.pop("options", None)
    return GeodesicOptions.of(GeodesicOptions.of(EXP_DEFAULTS) if base is None else base, **user)


def _retraction_kind(variant: str, retraction: str, exp_options: dict | None) -> str | None:
    """The retraction asked for, checked against the variant (None: the straight line;
    the default retraction names no request, so it passes with every variant)."""
    if retraction not in RETRACTIONS:
        raise OptimizationError(f"unknown retraction {retraction!r}; choose one of "
                                f"{', '.join(RETRACTIONS)}")
    if not VARIANT_PARTS[variant][1]:
        if retraction != DEFAULT_RETRACTION or exp_options is not None:
            raise OptimizationError(f"{variant} moves along straight lines; a retraction and "
                                    "exp_options apply to complete-complete only")
        return None
    if retraction != "exp" and exp_options is not None:
        raise OptimizationError("exp_options apply to retraction='exp' only")
    return retraction


def _make_retraction(kind: str, metric, exp_options: dict | None, free):
    from .riemannian.retractions import ExponentialRetraction, SecondOrderRetraction

    if kind == "exp":
        return ExponentialRetraction(metric, _retraction_options(exp_options), free)
    return SecondOrderRetraction(metric, free)


def _make_metric(variant: str, mesh: PlanarMesh, metric_beta, metric_options: dict):
    from .riemannian.metrics import CompleteMetric, ElasticityMetric, EuclideanMetric

    kind = VARIANT_PARTS[variant][0]
    if kind == "euclidean":
        return EuclideanMetric()
    if kind == "elasticity":
        return ElasticityMetric(mesh, **metric_options)
    from .penalties import QualityPenalty

    beta = default_metric_beta(mesh.n_vertices) if metric_beta is None else tuple(metric_beta)
    return CompleteMetric(QualityPenalty(mesh, beta=beta, **metric_options))


def optimize(
    mesh: PlanarMesh,
    objective: Objective,
    *,
    variant: str = DEFAULT_VARIANT,
    method: str = DEFAULT_METHOD,
    penalty_beta: Sequence[float] | None = None,
    metric_beta: Sequence[float] | None = None,
    fixed: np.ndarray | None = None,
    max_iter: int = 1000,
    tol: float | None = 1e-6,
    gtol: float | None = 1e-5,
    ftol: float | None = 1e-6,
    memory: int = 10,
    sigma: float = 1e-4,
    tau: float = 0.5,
    c2: float | None = None,
    segment_fraction: float = 0.5,
    min_step: float = 1e-6,
    metric_options: dict | None = None,
    retraction: str = DEFAULT_RETRACTION,
    exp_options: dict | None = None,
    callback: Callable[[IterationRecord, FloatArray], bool | None] | None = None,
    lbfgs_preconditioner: str = "auto",
) -> OptimizeResult:
    """Minimize ``F(Q) = j(Q) + f2(Q; Q0)`` over admissible meshes by a Riemannian
    descent method: L-BFGS, nonlinear CG or steepest descent (thesis algorithm 2, §6.4.1).

    Every trial configuration outside M+ (a non-positive area, a boundary touching
    itself, an objective refusing it) counts as ``F = +∞`` and is rejected by the line
    search; every iterate is admissible.

    Parameters
    ----------
    mesh : PlanarMesh
        Initial mesh; also the reference Q_ref of the penalty. Must be admissible.
    objective : object with ``value(Q)`` and ``derivative(Q)`` (shape (N, 2))
    variant : one of :data:`VARIANTS`
    method : one of :data:`METHODS`: ``"lbfgs"`` (Riemannian L-BFGS with the metric as
        inner product and a Wolfe line search), ``"cg"`` (Hestenes–Stiefel+), or
        ``"steepest"`` (the thesis' Armijo steepest descent).
    penalty_beta : (β1, β2, β3, β4) of the penalty f2 added to j (β4 unscaled: f2
        divides it by 2N); None or all zero = unpenalized.
    metric_beta : β^metric of the complete metric (default :func:`default_metric_beta`).
    fixed : vertex indices (or boolean mask) that do not move.
    max_iter : maximum number of iterations.
    tol : steepest descent only: tolerance of the stopping rule (6.26)
        ``max_{m=1..5} F_{n−m} − F_n < tol``; None disables it (fixed iteration count, as
        for the unpenalized runs).
    gtol : stop when the Riemannian gradient norm ``‖grad F‖_g`` falls to ``gtol`` times
        its first value (every method); None disables it.
    ftol : lbfgs/cg only: stop when ``max_{m=1..5} F_{n−m} − F_n ≤ ftol · max(|F_n|, 1)``
        (the relative version of (6.26)); None disables it.
    memory : number of L-BFGS curvature pairs kept.
    sigma, tau : Armijo parameters (6.21) (``sigma`` is ``c1`` of the Wolfe search) and
        the backtracking factor of steepest descent.
    c2 : Wolfe curvature constant (default 0.9 for lbfgs, 0.1 for cg).
    segment_fraction : lbfgs/cg with the straight-line retraction: trial steps go at most
        this fraction of the way to the first degenerate triangle along ``Q + t d``.
    min_step : a run fails (``step_too_small``) when a trial step drops below this.
    metric_options : extra keyword arguments of the metric (e.g. elasticity ``E``, ``nu``).
    retraction : complete-complete only: ``"second-order"`` (default) or ``"exp"`` (the
        exponential map), see :data:`RETRACTIONS`.
    exp_options : settings of ``retraction="exp"`` (fields of
        :class:`~meshopt_toolkit.riemannian.geodesics.GeodesicOptions`, or
        ``{"options": GeodesicOptions(...)}``), on top of :data:`EXP_DEFAULTS`.
    callback : called as ``callback(record, Q)`` after each iteration; returning True stops.
    lbfgs_preconditioner : the L-BFGS initial inverse Hessian ``H_0 = γ B⁻¹``
        (:mod:`meshopt_toolkit.shape.preconditioners`): ``"none"`` (``B`` = the metric,
        the Riemannian two-loop with ``H_0 = γ id``), ``"penalty"`` (``B`` ≈ the Hessian
        of the penalty f2, refactorized every 5 iterations), ``"elasticity"`` (``B`` =
        the elasticity matrix), or ``"auto"`` (default): ``"penalty"`` for the complete-*
        variants with a penalty (β1 > 0), else ``"none"``. Table 6.4 set 2: complete-
        complete L-BFGS 56 → 21 iterations (steepest descent 233), 247 → 50 on the
        2198-vertex disc.

    Returns
    -------
    OptimizeResult

    Raises
    ------
    OptimizationError
        A direction that is not a descent direction (a wrong derivative), an unknown
        variant, method or retraction, a retraction or ``exp_options`` given to a variant
        that moves along straight lines, or a mesh whose size is outside
        :data:`SIZE_RANGE`.
    """
    from .shape.preconditioners import make_preconditioner
    from .shape.problem import ShapeProblem

    if variant not in VARIANTS:
        raise OptimizationError(f"unknown variant {variant!r}; choose one of {', '.join(VARIANTS)}")
    if method not in METHODS:
        raise OptimizationError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    retraction = _retraction_kind(variant, retraction, exp_options)
    mesh = require_admissible(mesh, "shape optimization")
    _check_size(mesh.points)
    tri = mesh.triangles
    N = mesh.n_vertices
    free = None
    if fixed is not None:
        fixed = np.asarray(fixed)
        free = np.ones(N, bool)
        free[fixed] = False
        if not free.any():
            raise OptimizationError("every vertex is fixed: nothing to optimize")
    penalty = None
    if penalty_beta is not None and any(b != 0 for b in penalty_beta):
        from .penalties import QualityPenalty

        penalty = QualityPenalty(mesh, beta=tuple(penalty_beta))
    metric = _make_metric(variant, mesh, metric_beta, dict(metric_options or {}))
    retract = (None if retraction is None
               else _make_retraction(retraction, metric, exp_options, free))
    problem = ShapeProblem(objective, penalty, metric, tri, mesh.boundary_edges, free)
    h0 = make_preconditioner(lbfgs_preconditioner, metric_kind=VARIANT_PARTS[variant][0],
                             method=method, mesh=mesh, penalty=penalty, free=free)
    if method != "steepest":
        from .shape.driver import run_descent

        return run_descent(
            mesh, problem, method=method, variant=variant, retraction=retract,
            max_iter=max_iter,
            gtol=gtol, ftol=ftol, memory=memory, c1=sigma, c2=c2,
            segment_fraction=segment_fraction, min_step=min_step, callback=callback,
            h0=h0,
        )

    def penalty_value(Q):
        return 0.0 if penalty is None else float(penalty.value(Q))

    start = time.perf_counter()
    Q = np.array(mesh.points, dtype=float)
    timer = PhaseTimer()
    t0 = time.perf_counter()
    J = float(objective.value(Q))
    t0 = timer.add("state", t0)
    fpen = penalty_value(Q)
    F = J + fpen
    q = quality_summary(Q, tri)
    history = [
        IterationRecord(0, J, fpen, F, q.mean_shape_quality, q.min_aspect_ratio, 0.0, 0, math.nan,
                        dict(timer.seconds))
    ]
    s_prev = slope_prev = dnorm0 = None
    status = "max_iterations"
    message = f"reached the maximum of {max_iter} iterations without converging"
    for n in range(1, max_iter + 1):
        timer = PhaseTimer()
        t0 = time.perf_counter()
        dJ = objective.derivative(Q)
        t0 = timer.add("derivative", t0)
        P = dJ if penalty is None else dJ + penalty.gradient(Q)
        t0 = timer.add("penalty_derivative", t0)
        d = -metric.riesz(Q, P, free=free)  # restricted to the free vertices if any
        slope = _dot(P, d)  # dF(Q)[d]
        dnorm = float(metric.norm(Q, d))
        t0 = timer.add("gradient", t0)
        if dnorm0 is None:
            dnorm0 = dnorm
        if not slope < 0:
            if slope == 0 or dnorm == 0:
                status, message = "converged", "the gradient vanishes"
                break
            raise OptimizationError(
                f"iteration {n}: the search direction is not a descent direction "
                f"(dF[d] = {slope:.3e}); the derivative or the metric is wrong"
            )
        if gtol is not None and dnorm <= gtol * dnorm0:
            status = "converged"
            message = f"‖grad F‖ fell to {dnorm / dnorm0:.2e} of its first value (gtol {gtol:g})"
            break
        s = None if s_prev is None else s_prev * slope_prev / slope
        if s is None or s * dnorm < 1e-4:
            s = 1.0 / dnorm
        trial_steps = s * tau ** np.arange(max(1, math.ceil(math.log(min_step / s) / math.log(tau)) + 1))
        trial_steps = trial_steps[trial_steps >= min_step]
        # complete-complete: one retraction call gives every trial (None = not admissible)
        geo_points: list | None = None
        if retract is not None and len(trial_steps):
            t_r = time.perf_counter()
            # rescaling lemma: R_Q(s_k d) = R_Q((s_k / s) · s d) for the exponential map;
            # the second-order retraction has the same property
            geo_points = retract(Q, s * d, trial_steps / s)[0]
            timer.add("retraction", t_r)
        s_max = np.inf if retract is not None else max_travel_step(Q, tri, d)
        accepted = None
        backtracks = rejected = 0
        t_b = time.perf_counter()
        state_in_backtracking = 0.0
        for k, s_k in enumerate(trial_steps):
            if s_k >= s_max:
                backtracks += 1
                continue
            Qt = geo_points[k] if retract is not None else Q + s_k * d
            if Qt is None or np.any(signed_areas(Qt, tri) <= 0):
                backtracks += 1
                rejected += 1
                continue
            t_s = time.perf_counter()
            Ft, Jt = problem.values(Qt)  # +inf outside M+ (e.g. a boundary touching itself)
            state_in_backtracking += time.perf_counter() - t_s
            if not np.isfinite(Ft):
                backtracks += 1
                rejected += 1
                continue
            if Ft <= F + sigma * s_k * slope:
                accepted = (s_k, Qt, Jt, Ft)
                break
            backtracks += 1
        timer.seconds["backtracking"] += time.perf_counter() - t_b - state_in_backtracking
        timer.seconds["state"] += state_in_backtracking
        if accepted is None:
            status = "step_too_small"
            message = f"iteration {n}: no step ≥ {min_step:g} satisfies the Armijo condition"
            break
        s_k, Q, J, F = accepted
        s_prev, slope_prev = s_k, slope
        q = quality_summary(Q, tri)
        record = IterationRecord(
            n, J, F - J, F, q.mean_shape_quality, q.min_aspect_ratio, s_k, backtracks,
            dnorm, dict(timer.seconds), relative_gradient_norm=dnorm / dnorm0,
            rejected_trials=rejected,
        )
        history.append(record)
        logger.debug("iter %d: F=%.6g j=%.6g Λ=%.4f step=%.3g", n, F, J, q.mean_shape_quality, s_k)
        if callback is not None and callback(record, Q):
            status, message = "stopped", f"stopped by the callback at iteration {n}"
            break
        if tol is not None and n >= 5:
            past = np.array([h.objective for h in history[n - 5 : n]])
            if np.max(past - F) < tol:
                status = "converged"
                message = f"F changed less than {tol:g} over the last 5 iterations (6.26)"
                break
    final = mesh.with_points(Q)
    return OptimizeResult(
        mesh=final,
        x=Q,
        fun=F,
        j=J,
        nit=len(history) - 1,
        status=status,
        success=status in ("converged", "stopped"),
        message=message,
        history=history,
        seconds=time.perf_counter() - start,
        variant=variant,
    )


def _check_size(points: FloatArray) -> None:
    """Refuse a mesh whose bounding-box diagonal is outside :data:`SIZE_RANGE`."""
    size = float(np.linalg.norm(np.ptp(points, axis=0)))
    lo, hi = SIZE_RANGE
    if not lo <= size <= hi:
        raise OptimizationError(
            f"the mesh is {size:.3g} across (bounding-box diagonal); shape optimization "
            f"needs a size between {lo:g} and {hi:g} because the penalty and the metrics "
            f"are not scale-invariant: rescale the mesh (e.g. to unit size) first"
        )
