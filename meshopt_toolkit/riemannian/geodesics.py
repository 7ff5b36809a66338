"""Geodesics and the exponential map of the complete metric ``g = I + ∇f ∇fᵀ`` (SPEC §5).

The geodesic equation (5.35) of a complete metric is the explicit ODE

    Q'' = − ∇f(Q) · (Q'ᵀ ∇²f(Q) Q') / (1 + |∇f(Q)|²).

Derivation: the Euler–Lagrange equation of ``½ Vᵀ g(Q) V`` reads
``d/dt (g V) = ½ ∂_Q(Vᵀ g V) = (∇f·V) ∇²f V``. With ``d/dt g = (∇²f V)∇fᵀ + ∇f (∇²f V)ᵀ``
the left side is ``g V' + (∇²f V)(∇f·V) + ∇f (Vᵀ∇²f V)``, so ``g V' = −∇f (Vᵀ∇²f V)`` and
Sherman–Morrison, ``g⁻¹ ∇f = ∇f / (1 + |∇f|²)``, gives the formula. Along a geodesic the
energy ``e = |Q'|² + (∇f·Q')²`` is constant and ``|f(γ(t)) − f(γ(0))| ≤ √e·|t|``, so f — and
with it the inverse heights or areas — grows at most linearly: a geodesic never leaves M+.

Methods (``method=``):

``"auto"`` / ``"dop853"``
    Own adaptive stepping (:func:`~meshopt_toolkit.ode.runge_kutta`) with
    Hairer's 8th-order DOP853 pair (12 penalty calls per step; coefficient table from
    scipy), steps landing exactly on the requested times, stages outside M+ rejected.
    Default tolerance ``rtol = 1e-6``, ``atol = 1e-6 · scale`` (scale = ``max(max|Q|,
    max|V|·t)``): about 1e-7·max|V| from a tight solution on the benchmark disc
    (``benchmarks/bench_geodesics.py``) with fewer penalty calls than dopri5 at equal
    accuracy. ``rtol = atol = 1e-5`` is plenty for a line-search retraction.
``"dopri5"``
    The same stepping with our Dormand–Prince 5(4) pair (6 calls per step), default
    ``rtol = 1e-7``; cheaper per step, better at loose tolerances.
``"bs3"``
    The same stepping with the Bogacki–Shampine 3(2) pair (3 calls per step), default
    ``rtol = 1e-5``.
``"line-search"``
    The retraction of a line search (complete-complete optimization,
    :data:`meshopt_toolkit.optimize.EXP_DEFAULTS`): Bogacki–Shampine 3(2) at
    ``rtol = atol/scale = 5e-2``, the velocity projected back onto the initial energy after
    every step (instead of rejecting steps that change it; this keeps the bound on the
    growth of f, so the discrete path cannot run into a degenerate mesh), a step with an
    inadmissible stage retried at half its size, and positions only (``monitor=False``:
    no f evaluations at the outputs, no invariant checks). Every output is still
    admissible (areas at every stage and output, the boundary exactly at every step end
    and output) and the map agrees with ``exp`` to O(t³) for small t (the first step's
    local error), so it is a retraction. It is *not* an accurate exponential map for
    large t: the geodesics of an optimization step bounce off nearly degenerate triangles,
    where local errors grow fast; on the bundled discs its γ(1) is 0.1–0.3·max|V| away
    from a tight solution (dop853 at 1e-6 is 1e-5–1e-6 away), with 25–60 penalty calls
    instead of 200–1500 (``benchmarks/bench_geodesics.py``). Optimization results are as
    good (thesis §6.4 runs: F monotone, admissible iterates, same final F and Λ within
    the run-to-run spread).
``"stormer-verlet"``
    The thesis' algorithm 1 with ``steps`` uniform steps (default 1024): the reference.
    Its fixed points use the thesis' tolerance 1e-8 and at most 10 iterations
    (``fixed_point_tolerance``, ``fixed_point_max_iterations``); when the contraction is
    slow (stiff penalty, large velocity) it raises "use more steps".
``"scipy"``
    ``scipy.integrate.solve_ivp`` with DOP853 on the same right-hand side, default
    ``rtol = 1e-10``: an independent check (it sees a stage outside M+ only as NaN).

For a Euclidean metric (``EuclideanMetric`` or ``None``) the geodesic is ``Q + tV``.

Guards (``on_violation="warn" | "raise" | "ignore"``): the relative energy drift
``|e(t) − e(0)|/e(0)`` must stay below ``energy_tol`` (default ``max(1e-3, 1e4·rtol)``
for the adaptive methods — the energy error can be 10–1000× the relative position error,
as ``(∇f·V)²`` amplifies errors in V by ``|∇f|``, so the adaptive steppers also reject a
step changing e by more than ``10·rtol·e(0)``; 1e-2 for Störmer–Verlet, whose energy
error is O(Δt²)), and
``|f(γ(t)) − f(γ(0))| ≤ √(max e)·t·(1 + energy_tol) + 1e-10·(1 + |f(γ(0))|)`` is checked at
every output time. A step with a stage outside M+ is rejected and retried smaller; an
integration that cannot proceed raises :class:`~meshopt_toolkit.errors.IntegrationError`.
A complete-metric result never contains an inverted mesh.

Admissibility: every right-hand-side evaluation needs positive areas (a stage outside
M+ rejects the step); the boundary (SPEC §1: no boundary self-intersection) is checked
exactly at every accepted step end and every output, not at intermediate stages
(:class:`~meshopt_toolkit.riemannian.field.BoundaryGuard`, which proves most configurations
simple with a displacement certificate instead of the full test).

Rescaling lemma: ``γ_{Q, τV}(1) = γ_{Q, V}(τ)``, so one call of :func:`geodesic` with
``times=[1, τ, τ², …]`` serves every backtracking trial of a line search; with the default
dense output those times cost no extra steps (the line-search mode's Hermite outputs no
penalty call at all with ``monitor=False``; DOP853's continuous extension 3 calls in a
step that holds outputs).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray
from ..errors import IntegrationError
from ..kernels.triangles import signed_areas
from ..ode import IntegrationOutput, energy, runge_kutta, stormer_verlet
from .field import GeodesicField
from .geodesic_options import GeodesicOptions
from .geodesic_result import GeodesicResult, GeodesicWarning, _assemble  # noqa: F401 (re-exported)

__all__ = [
    "GeodesicOptions",
    "GeodesicResult",
    "GeodesicWarning",
    "exp_map",
    "geodesic",
    "geodesic_acceleration",
    "penalty_of",
    "triangles_of",
]


#: default relative tolerance of each adaptive integrator (atol = rtol · scale)
DEFAULT_RTOL = {"dop853": 1e-6, "dopri5": 1e-7, "bs3": 1e-5, "line-search": 5e-2,
                "scipy": 1e-10}

#: how ``method="line-search"`` drives :func:`~meshopt_toolkit.ode.runge_kutta`
#: (with the Bogacki–Shampine pair): the velocity is projected back onto the initial
#: energy after every step instead of rejecting steps that change it, and a step with an
#: inadmissible stage is retried at half its size
LINE_SEARCH_OPTIONS = {"project_energy": True, "energy_rtol": np.inf, "exit_shrink": 0.5}

#: first step of ``method="line-search"`` as a fraction of the interval: its geodesics take
#: about ten steps, and starting there saves the trial evaluation and the cautious first
#: steps of the general heuristic (fewer penalty calls on the bundled discs)
LINE_SEARCH_FIRST_STEP = 0.1


def penalty_of(metric):
    """The penalty ``f`` behind a complete metric, or None for the Euclidean metric.

    Accepts a ``CompleteMetric`` (anything with a ``.penalty``), a penalty itself (anything
    with ``gradient_and_curvature``), ``EuclideanMetric`` or ``None``.

    Raises
    ------
    IntegrationError
        The metric has no geodesics implemented here (e.g. the elasticity metric).
    """
    if metric is None:
        return None
    if hasattr(metric, "gradient_and_curvature"):
        return metric
    pen = getattr(metric, "penalty", None)
    if pen is not None:
        return pen
    if getattr(metric, "is_flat", False):
        return None
    raise IntegrationError(
        f"{type(metric).__name__}.exp is not implemented: geodesics are available for the "
        "Euclidean and complete metrics only"
    )


def triangles_of(penalty) -> np.ndarray | None:
    """The ``(T, 3)`` connectivity behind a penalty (its ``mesh.triangles`` or its
    ``triangles``), or None when it declares none."""
    mesh = getattr(penalty, "mesh", None)
    if mesh is not None and hasattr(mesh, "triangles"):
        return mesh.triangles
    tri = getattr(penalty, "triangles", None)
    return None if tri is None else np.asarray(tri)


_triangles_of = triangles_of  # the former private name


def geodesic_acceleration(metric, Q: FloatArray, V: FloatArray) -> FloatArray:
    """Right-hand side of (5.35): ``Q'' = −∇f (Vᵀ∇²f V)/(1 + |∇f|²)``, shape (N, 2)."""
    pen = penalty_of(metric)
    if pen is None:
        return np.zeros_like(np.asarray(V, dtype=float))
    return GeodesicField(pen).acceleration(np.asarray(Q, float), np.asarray(V, float))[0]


def _default_atol(Q: FloatArray, V: FloatArray, t_end: float, rtol: float,
                  atol: float | None) -> float:
    """``atol`` as given, else ``rtol`` times the scale ``max(max|Q|, max|V|·t_end)``."""
    if atol is not None:
        return atol
    return rtol * max(float(np.max(np.abs(Q))), float(np.max(np.abs(V))) * t_end, 1e-300)


def _scipy_dop853(fld: GeodesicField, Q0, V0, t_out, rtol, atol) -> IntegrationOutput:
    from scipy.integrate import solve_ivp

    shape = np.shape(Q0)
    n = int(np.prod(shape))
    e0 = energy(fld.gradient(Q0), V0)

    def rhs(_t, y):
        q = y[:n].reshape(shape)
        v = y[n:].reshape(shape)
        if not fld.admissible(q):
            return np.full_like(y, np.nan)
        a, _ = fld.acceleration(q, v)
        return np.concatenate([v.ravel(), a.ravel()])

    y0 = np.concatenate([np.ravel(Q0), np.ravel(V0)])
    sol = solve_ivp(rhs, (0.0, float(t_out[-1])), y0, method="DOP853", t_eval=t_out,
                    rtol=rtol, atol=atol)
    if not sol.success or not np.isfinite(sol.y).all():
        raise IntegrationError(f"scipy DOP853 failed: {sol.message}")
    pts = sol.y[:n].T.reshape((-1,) + shape)
    vel = sol.y[n:].T.reshape((-1,) + shape)
    en = np.array([energy(fld.gradient(p), v) for p, v in zip(pts, vel)])
    for p in pts:
        if not fld.admissible(p):
            raise IntegrationError("scipy DOP853 produced an inverted mesh; tighten rtol/atol")
    drift = float(np.max(np.abs(en - e0)) / e0) if e0 > 0 else 0.0
    return IntegrationOutput(pts, vel, en, int(sol.nfev), 0, 0, drift)


def geodesic(
    metric,
    Q: FloatArray,
    V: FloatArray,
    time: float = 1.0,
    *,
    times=None,
    options: GeodesicOptions | None = None,
    free=None,
    progress=None,
    **settings,
) -> GeodesicResult:
    """The geodesic ``γ`` with ``γ(0) = Q``, ``γ'(0) = V``, sampled from ONE integration.

    Parameters
    ----------
    metric : CompleteMetric, penalty, EuclideanMetric or None
        A complete metric ``g = I + ∇f∇fᵀ`` (5.17, 5.34) or the penalty ``f`` itself.
    Q : (N, 2) admissible initial positions
    V : (N, 2) initial velocity (a tangent vector)
    time : final time (may be negative: γ_V(−t) = γ_{−V}(t))
    times : (K,) array_like, optional
        Output times between 0 and ``time`` (any order; returned in the given order).
        Default ``[time]``. Include 0 to get the initial state as well.
    options : GeodesicOptions, optional
        How to integrate: method, tolerances, invariant checks, dense output, first step,
        Störmer–Verlet settings (default ``GeodesicOptions()``).
    **settings
        Fields of :class:`GeodesicOptions` overriding ``options`` (e.g.
        ``method="bs3", rtol=1e-4``); an unknown name is a TypeError.
    free : (N,) bool mask or vertex indices, optional
        Free vertices: the geodesic of the metric restricted to tangent vectors vanishing
        on the fixed vertices (see :class:`~meshopt_toolkit.riemannian.field.GeodesicField`);
        ``V`` must vanish there, and fixed vertices do not move.
    progress : callable, optional
        Adaptive methods: ``progress(fraction)`` after each accepted step, the fraction
        of ``[0, time]`` integrated (for a progress bar).

    Returns
    -------
    GeodesicResult

    Raises
    ------
    IntegrationError
        The integration cannot proceed without leaving M+, a Störmer–Verlet fixed point
        fails ("use more steps"), the initial mesh is not admissible, or (with
        ``on_violation="raise"``) an invariant is violated. When an adaptive integration
        stops early, the exception carries ``partial``: a :class:`GeodesicResult` over the
        requested times reached (ascending), or None if none was.
    """
    opts = GeodesicOptions.of(options, **settings)
    method, rtol, atol, energy_tol = opts.method, opts.rtol, opts.atol, opts.energy_tol
    monitor, h0 = opts.monitor, opts.h0
    Q = np.asarray(Q, dtype=float)
    V = np.asarray(V, dtype=float)
    if Q.shape != V.shape or Q.ndim != 2 or Q.shape[1] != 2:
        raise IntegrationError(f"Q and V must both have shape (N, 2), got {Q.shape} and {V.shape}")
    if not np.isfinite(V).all():
        raise IntegrationError("the initial velocity has non-finite entries")
    time = float(time)
    req = np.atleast_1d(np.asarray([time] if times is None else times, dtype=float))
    if req.ndim != 1 or req.size == 0:
        raise IntegrationError("times must be a non-empty 1D sequence")
    if time < 0:
        if np.any(req > 0) or np.any(req < time):
            raise IntegrationError(f"times must lie in [{time}, 0]")
        try:
            res = geodesic(metric, Q, -V, -time, times=-req, options=opts, free=free,
                           progress=progress)
        except IntegrationError as exc:
            part = getattr(exc, "partial", None)
            if part is not None:
                part.times = -part.times
                part.velocities = -part.velocities
            raise
        res.times = req
        res.velocities = -res.velocities
        return res
    if np.any(req < 0) or np.any(req > time * (1 + 1e-12)):
        raise IntegrationError(f"times must lie in [0, {time}]")
    pen = penalty_of(metric)
    K = req.size

    if pen is None:  # Euclidean: straight lines
        pts = Q[None] + req[:, None, None] * V[None]
        return GeodesicResult(
            times=req, points=pts, velocities=np.broadcast_to(V, pts.shape).copy(),
            energy=np.full(K, float(np.vdot(V, V))), penalty=np.full(K, np.nan),
            admissible=np.array([_all_positive(p, metric) for p in pts]),
            method="euclidean",
        )

    method_used = "dop853" if method == "auto" else method
    line_search = method_used == "line-search"
    if monitor is None:
        monitor = not line_search
    free = free_vertex_mask(free, len(Q))
    if free is not None:
        if free.shape != (len(Q),):
            raise IntegrationError(f"free must be an (N,) mask, got shape {free.shape}")
        if np.any(V[~free]):
            raise IntegrationError("the initial velocity must vanish on the fixed vertices")
    fld = GeodesicField(pen, triangles_of(pen), free=free)
    if not fld.admissible(Q):
        raise IntegrationError("the initial mesh is not admissible (a signed area is <= 0)")
    if monitor:
        f0 = fld.value(Q)
        if not np.isfinite(f0):
            raise IntegrationError("the penalty is not finite at the initial mesh")
    else:
        problem = fld.boundary_problem(Q)
        if problem is not None:
            raise IntegrationError(f"the initial mesh is not admissible: {problem}")
        f0 = np.nan
    positive = np.unique(req[req > 0])
    if method_used in DEFAULT_RTOL and rtol is None:
        rtol = DEFAULT_RTOL[method_used]
    if positive.size == 0 or not np.any(V):
        out = None
    elif method_used in ("dop853", "dopri5", "bs3", "line-search"):
        extra = LINE_SEARCH_OPTIONS if line_search else {}
        if line_search and h0 is None:
            h0 = LINE_SEARCH_FIRST_STEP * positive[-1]
        out = runge_kutta(fld, Q, V, positive, pair="bs3" if line_search else method_used,
                          rtol=rtol, atol=_default_atol(Q, V, positive[-1], rtol, atol),
                          dense=opts.dense, h0=h0, partial=True, progress=progress,
                          control={"max_steps": opts.max_steps, **extra})
    elif method_used == "stormer-verlet":
        out = stormer_verlet(fld, Q, V, positive,
                             steps=1024 if opts.steps is None else int(opts.steps),
                             tolerance=opts.fixed_point_tolerance,
                             max_iterations=opts.fixed_point_max_iterations)
    else:
        out = _scipy_dop853(fld, Q, V, positive, rtol,
                            _default_atol(Q, V, positive[-1], rtol, atol))

    if out is not None and out.failure:
        reached = positive[: out.n_reached]
        keep = np.flatnonzero((req == 0) | np.isin(req, reached))
        exc = IntegrationError(out.failure)
        exc.partial = None
        if keep.size:
            sub = np.sort(req[keep])
            exc.partial = _assemble(fld, Q, V, f0, sub, positive, out, method_used, monitor,
                                    rtol, energy_tol, "ignore")
        raise exc
    return _assemble(fld, Q, V, f0, req, positive, out, method_used, monitor, rtol,
                     energy_tol, opts.on_violation)


def free_vertex_mask(free, n: int) -> np.ndarray | None:
    """``free`` (an (n,) bool mask, vertex indices or None) as a bool mask; None stays None."""
    if free is None:
        return None
    free = np.asarray(free)
    if free.dtype != bool:
        mask = np.zeros(n, dtype=bool)
        mask[free] = True
        free = mask
    return free


def _all_positive(points, metric) -> bool:
    tri = getattr(getattr(metric, "mesh", None), "triangles", None)
    if tri is None:
        return True
    return bool(signed_areas(points, tri).min() > 0)


def exp_map(
    metric,
    Q: FloatArray,
    V: FloatArray,
    time: float = 1.0,
    method: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    **kwargs,
) -> FloatArray:
    """Exponential map ``exp_Q(time·V) = γ_{Q,V}(time)`` of ``metric``, shape (N, 2).

    For a Euclidean metric this is ``Q + time·V`` (no integration, no admissibility check: the
    caller guards Euclidean retractions). For a complete metric the geodesic (5.35) is
    integrated (see :func:`geodesic` for ``method``, tolerances and guards; extra keyword
    arguments are passed on), and the result is always admissible.

    Examples
    --------
    >>> exp_map(None, [[0.0, 0.0]], [[1.0, 2.0]], time=0.5).tolist()
    [[0.5, 1.0]]
    """
    Q = np.asarray(Q, dtype=float)
    V = np.asarray(V, dtype=float)
    if penalty_of(metric) is None:
        if Q.shape != V.shape:
            raise IntegrationError(f"Q and V must have the same shape, got {Q.shape} and {V.shape}")
        return Q + float(time) * V
    given = {k: v for k, v in (("method", method), ("rtol", rtol), ("atol", atol)) if v is not None}
    return geodesic(metric, Q, V, time, **given, **kwargs).points[-1]
