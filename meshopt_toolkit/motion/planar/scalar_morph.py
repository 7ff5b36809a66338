"""Geodesic morphs: the log map of a complete metric and inversion-free interpolation.

This module is the scalar-metric morph (:func:`geodesic_morph`, :func:`morph_metric`;
``mt.morph(..., metric="complete")``); the manifold computations it is built on live in
:mod:`meshopt_toolkit.riemannian` next to the exponential map:
:mod:`~.riemannian.initial_path`, :mod:`~.riemannian.discrete_geodesic` and
:mod:`~.riemannian.log_map` (re-exported here).

With a complete metric ``g = I + ∇f ∇fᵀ`` (5.17, 5.34) the manifold ``M+(Δ; Qref)`` is
complete, so two admissible meshes of the same connectivity in the same component are
joined by a minimizing geodesic (Hopf–Rinow), and every mesh on it is admissible. Linear
vertex interpolation gives no such guarantee (it inverts triangles of a disc whose
interior is twisted by 225° with a fixed boundary).

The key identity: ``|dQ|²_g = |dQ|² + (df)² = |d(Q, f(Q))|²``, so ``(M+, g)`` is isometric
to the graph of ``f`` in ``R^{2N+1}`` with the Euclidean metric. Three stages:

1. **An admissible initial path** (:func:`initial_path`): straight lines if every node is
   admissible, else the as-rigid-as-possible interpolation
   (:mod:`~meshopt_toolkit.fem.interpolation`) if every node is admissible, otherwise the
   complete-metric gradient flow of ``½|Q − Q1|²`` — the direction
   ``−(P − ∇f (∇f·P)/(1 + |∇f|²))``, ``P = Q − Q1`` slides along the barrier instead of
   crossing it — resampled by arc length in the graph metric.
2. **The discrete geodesic** (:func:`discrete_geodesic`): the ``K``-segment path
   minimizing the path energy

       E(Q_1, …, Q_{K−1}) = K Σ_{k=0}^{K−1} |Q_{k+1} − Q_k|² + (f(Q_{k+1}) − f(Q_k))²

   with fixed end frames. Newton–CG with the exact Hessian-vector product (it needs
   ``∇f`` and ``∇²f·V``), preconditioned by the exact inverse of the Gauss–Newton matrix
   ``2K (L ⊗ I + Fᵀ L F)`` (``L`` the path Laplacian, ``F`` the frame gradients) via the
   Woodbury identity at O(K² N) cost. ``f = +inf`` at inverted meshes is a barrier: the
   backtracking line search never leaves ``M+``. Its length ``√E`` converges to the
   geodesic distance like ``O(1/K²)``. Near the minimizer the frames hold nearly
   degenerate triangles, the quadratic model holds only in a tiny region and Newton
   creeps; the iteration also stops when ``E`` stagnates (status "stationary").
3. **Shooting** (:func:`log_map`): Newton–Krylov on the residual ``exp_{Q0}(V) − Q1``,
   started at the second-order one-sided difference ``V ≈ K(−3Q_0 + 4Q_1 − Q_2)/2`` of
   the discrete geodesic, Jacobian-vector products by directional differences of the
   exponential map, GMRES, step halving when the residual grows.

Stage 2 is robust and cheap against the shooting (``benchmarks/bench_morph.py``) and
converges to the shooting geodesic at second order in ``1/K`` (tested). Stage 3 meets
1e-8·diameter on moderate deformations (tested round trips) but not on the 225° twist,
where the geodesic passes triangles of aspect ratio ~5e-4 and the exponential map is
strongly nonlinear: the integration is accurate and the Jacobian only moderately
ill-conditioned, but a full Newton step raises the residual and only a small fraction of
it lowers it. Newton–Krylov stalls near 1e-2 from the discrete geodesic's velocity (the
frames do not resolve the thin-triangle stretch); an exact forward-mode Jacobian of the
discretized map and multiple shooting from the same start stall as well. Hence
:func:`geodesic_morph` uses the discrete geodesic by default (``method="discrete"``:
every frame admissible, end frames exact) and shooting on request (``"shooting"``,
``"auto"``).

Default metric of the morph: the complete metric of ``√N · f2`` with f2
``QualityPenalty(source, beta=DEFAULT_BETA, reference=source)``, ``DEFAULT_BETA = (1, 1,
0, 1)`` — shape quality and total area (both rigid-motion invariant) plus a weak pull
towards the source; the boundary-pair term β3 is off (it costs a neighbour search per
evaluation and only matters when the boundary moves towards itself: pass
``beta=(…, β3 > 0, …)`` for such morphs). The factor ``√N`` (``normalize=True``) makes
``g = N (I/N + ∇f2∇f2ᵀ)``: displacements count by their mean square over the N vertices,
as f2 (a mean over triangles) counts quality, so the balance between moving and keeping
quality does not drift with refinement. Without it the Euclidean part grows like N and
geodesics of fine meshes approach straight lines: on a 180° rotation of the discs the
plain metric's frames reach min aspect ratios 4e-4, 2e-5 and 1e-6 (146, 541 and 2198
vertices), the normalized one 0.14, 0.10 and 0.34, in fewer Newton iterations.

Known property of the metric: f2's mean quality lets a few triangles flatten cheaply
(a "cap" with a small angle θ costs ~1/θ), so a geodesic may pass through meshes with a
few very thin (never inverted) triangles: on the 225° twist the minimum aspect ratio of
the frames is 3e-4 (146 vertices) with or without the normalization; scaling β does not
change it.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping

import numpy as np

from ..._options import require_at_least
from ..._typing import FloatArray
from ...errors import InvalidMeshError, OptionError
from ...generate import twisted
from ...kernels.triangles import aspect_ratios, min_signed_areas_on_segment, signed_areas
from ...riemannian.discrete_geodesic import discrete_geodesic
from ...riemannian.geodesic_result import DiscreteGeodesic, LogMapResult
from ...riemannian.geodesics import penalty_of
from ...riemannian.initial_path import initial_path, linear_morph
from ...riemannian.log_map import DEFAULT_TOL, SHOOTING_RTOL, LogMapOptions, log_map
from ...riemannian.path_options import NewtonCGOptions
from .scalar_morph_result import MorphResult

logger = logging.getLogger(__name__)

#: default f2 coefficients (β1, β2, β3, β4) of the morph metric (β4 unscaled)
DEFAULT_BETA = (1.0, 1.0, 0.0, 1.0)

#: the morph's shooting: the log map's settings with a smaller exponential-map budget
SHOOTING = LogMapOptions(max_exp=400)

__all__ = [
    "DEFAULT_BETA",
    "DEFAULT_TOL",
    "SHOOTING_RTOL",
    "DiscreteGeodesic",
    "LogMapResult",
    "MorphResult",
    "discrete_geodesic",
    "geodesic_morph",
    "initial_path",
    "linear_morph",
    "log_map",
    "metric_scale",
    "morph_metric",
    "twisted",
]


def _frame_stats(points: FloatArray, triangles) -> tuple[FloatArray, FloatArray]:
    """Min aspect ratio and min signed area of every frame."""
    ar = np.array([aspect_ratios(p, triangles).min() for p in points])
    area = np.array([signed_areas(p, triangles).min() for p in points])
    return ar, area


def _check_pair(source, target):
    from ...mesh import TriangleMesh, require_admissible

    meshes = []
    for m, what in ((source, "source"), (target, "target")):
        if not isinstance(m, TriangleMesh):
            raise InvalidMeshError(f"the {what} must be a mesh, got {type(m).__name__}")
        meshes.append(m)
    s, t = meshes
    if s.n_vertices != t.n_vertices:
        raise InvalidMeshError(
            f"the source has {s.n_vertices} vertices and the target {t.n_vertices}: a morph "
            "needs two meshes of the same connectivity"
        )
    if s.n_triangles != t.n_triangles or not np.array_equal(s.triangles, t.triangles):
        raise InvalidMeshError(
            "the source and the target have different connectivity (triangle lists differ): "
            "a morph moves vertices only"
        )
    s = require_admissible(s, "the morph source")
    t = require_admissible(t, "the morph target")
    if not np.array_equal(s.triangles, t.triangles):
        raise InvalidMeshError("source and target have opposite orientations")
    return s.as_planar(), t  # a PlanarMesh is its own plane view


def metric_scale(mesh, normalize: bool = True) -> float:
    """The factor ``c`` of the default morph metric: ``√N`` if ``normalize`` else 1."""
    return float(np.sqrt(mesh.n_vertices)) if normalize else 1.0


def morph_metric(source, beta=DEFAULT_BETA, *, normalize: bool = True):
    """The default morph metric: the complete metric of ``c · f2(β)`` (module docstring).

    ``f2 = QualityPenalty(source, beta, reference=source)`` and ``c = √N`` when
    ``normalize`` (else 1); since f2 is linear in β, ``c · f2(β) = f2(c β)``.
    """
    from ...riemannian.metrics import CompleteMetric
    from ...penalties import QualityPenalty

    c = metric_scale(source, normalize)
    scaled = tuple(c * float(b) for b in beta)
    return CompleteMetric(QualityPenalty(source, beta=scaled, reference=source))


def _shooting_options(shooting: LogMapOptions | Mapping | None) -> LogMapOptions:
    """The shooting's settings: :data:`SHOOTING`, a mapping of fields on top of it, or an
    instance as given."""
    if shooting is None or isinstance(shooting, Mapping):
        return LogMapOptions.of(SHOOTING, **(shooting or {}))
    return LogMapOptions.of(shooting)


def geodesic_morph(
    source,
    target,
    frames: int = 9,
    *,
    beta=DEFAULT_BETA,
    normalize: bool = True,
    metric=None,
    method: str = "discrete",
    segments: int | None = None,
    discrete_tolerance: float = 1e-9,
    max_iterations: int = 500,
    shooting: LogMapOptions | Mapping | None = None,
    callback=None,
) -> MorphResult:
    """``frames`` meshes along the geodesic from ``source`` to ``target``.

    Parameters
    ----------
    source, target : PlanarMesh (same vertices and triangles, both admissible)
    frames : K ≥ 2 frames, equally spaced in geodesic arc length; frame 0 is the source,
        frame K−1 the target
    beta : (β1, β2, β3, β4) of the default metric: the complete metric of
        ``c · QualityPenalty(source, beta, reference=source)`` (β4 unscaled)
    normalize : ``c = √N`` (default; see the module docstring) or ``c = 1`` (the plain
        complete metric of f2)
    metric : a CompleteMetric to use instead (``beta`` is then ignored)
    method : "discrete" (default: nodes of the discrete geodesic, admissible by
        construction), "shooting" (frames ``exp(t_k V)`` of the shooting geodesic; must
        converge) or "auto" (shooting within ``shooting.max_exp`` exponential maps, the discrete
        frames otherwise). Shooting is exact where it converges, but on the 225° twist
        of the 146-vertex disc Newton–Krylov stalls near a residual of 1e-2 (module
        docstring)
    segments : segments of the discrete geodesic: a multiple of ``frames − 1`` (default
        the smallest multiple ≥ 16); frames are every m-th node
    discrete_tolerance : Newton tolerance of the discrete geodesic
    max_iterations : Newton iterations of the discrete geodesic
    shooting : :class:`~meshopt_toolkit.riemannian.log_map.LogMapOptions` of the shooting
        (or a mapping of its fields on top of :data:`SHOOTING`: ``tolerance`` (default
        1e-8 · diameter), the exponential-map budget ``max_exp``, ...)
    callback : passed to :func:`discrete_geodesic` (``callback(nit, E, gradient_norm)``;
        returning True stops it)

    Returns
    -------
    MorphResult

    Raises
    ------
    InvalidMeshError
        Different vertex counts or connectivity.
    NotAdmissibleError
        A non-admissible input, or no admissible path joins the pair.
    IntegrationError
        ``method="shooting"`` and the shooting does not converge.
    """
    from ...riemannian.geodesics import geodesic
    from ...fem.interpolation import arap_interpolation

    start = time.perf_counter()
    if method not in ("auto", "discrete", "shooting"):
        raise OptionError(f"method must be 'auto', 'discrete' or 'shooting', got {method!r}")
    frames = require_at_least("frames", int(frames), 2)
    src, tgt = _check_pair(source, target)
    Q0, Q1 = src.points, tgt.points
    if metric is None:
        metric = morph_metric(src, beta, normalize=normalize)
        scale = metric_scale(src, normalize)
    else:
        scale = None
    m = int(segments) // (frames - 1) if segments else max(1, -(-16 // (frames - 1)))
    if segments and int(segments) % (frames - 1):
        raise OptionError(f"segments ({segments}) must be a multiple of frames − 1 "
                          f"({frames - 1})")
    K = m * (frames - 1)
    dg = discrete_geodesic(metric, Q0, Q1, K, method="newton-cg",
                           options=NewtonCGOptions(tolerance=discrete_tolerance,
                                                   max_iterations=max_iterations),
                           callback=callback)
    if dg.status not in ("converged", "stationary"):
        logger.warning("geodesic_morph: the discrete geodesic did not converge in %d Newton "
                       "iterations (|∇E| = %.3g); its frames are admissible but not yet a "
                       "minimizer", dg.nit, dg.gradient_norm)
    log = None
    pts = dg.points[::m].copy()
    times = np.linspace(0.0, 1.0, frames)
    used, target_error, length = "discrete", 0.0, dg.length
    if method in ("auto", "shooting"):
        log = log_map(metric, Q0, Q1, discrete=dg,
                      options=_shooting_options(shooting),
                      raise_on_failure=(method == "shooting"))
        if log.success:
            geo = geodesic(metric, Q0, log.velocity, 1.0, times=times, rtol=SHOOTING_RTOL,
                           on_violation="ignore")
            pts = geo.points.copy()
            target_error = float(np.max(np.abs(pts[-1] - Q1)))
            pts[-1] = Q1
            used, length = "shooting", log.path_length
        else:
            logger.info("geodesic_morph: shooting did not converge (%s); using the discrete "
                        "geodesic", log.message)
    pts[0] = Q0
    if np.array_equal(Q0, Q1):  # the geodesic from a mesh to itself stays, bit for bit
        pts[:] = Q0
    pen = penalty_of(metric)
    ar, area = _frame_stats(pts, src.triangles)
    adm = np.array([bool(a > 0) and np.isfinite(pen.value(p)) for a, p in zip(area, pts)])
    lin = linear_morph(Q0, Q1, times)
    lar, larea = _frame_stats(lin, src.triangles)
    rigid = arap_interpolation(Q0, Q1, src.triangles, times)
    rar, rarea = _frame_stats(rigid, src.triangles)
    between = np.array([min_signed_areas_on_segment(pts[k], pts[k + 1], src.triangles).min()
                        for k in range(len(pts) - 1)])
    lmin = float(min_signed_areas_on_segment(Q0, Q1, src.triangles).min())
    return MorphResult(pts, times, src.triangles, used, target_error, ar, area, adm, lar, larea,
                       lmin, float(length), log, dg, time.perf_counter() - start,
                       rar, rarea, between, scale, source=src)
