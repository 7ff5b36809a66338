"""The discrete geodesic: the K-segment path minimizing the discrete path energy of a
metric, one entry for every metric. Two methods:

- ``"newton-cg"`` (:mod:`.newton_cg`): the complete metric ``I + ∇f∇fᵀ`` of a penalty
  (and straight lines for the Euclidean metric); Newton–CG with the exact Hessian-vector
  product and a Woodbury-inverted Gauss–Newton preconditioner;
- ``"levenberg-marquardt"`` (:mod:`.levenberg_marquardt`): metrics whose path energy is a
  sparse least-squares problem, which they provide through ``path_model``
  (:class:`.levenberg_marquardt.PathModelMetric`; the per-triangle distortion metric
  ``motion.planar.metric.GraphMetric``, the tet metric ``motion.tets.metric.TetGraphMetric``
  and the surface metric ``motion.surface.metric.SurfaceGraphMetric``), each with its
  iteration's rules (:class:`.levenberg_marquardt.IterationRules`).
"""

from __future__ import annotations

import numpy as np

from .._options import check_choice
from .._typing import FloatArray
from ..errors import InvalidMeshError
from ._boundary_value import _as_points, _path_frames
from .geodesic_result import DiscreteGeodesic
from .levenberg_marquardt import levenberg_marquardt
from .metrics import MetricNotImplementedError
from .newton_cg import newton_cg
from .path_options import METHODS, options_for


def _method_of(metric, method: str) -> str:
    """``method`` checked, "auto" resolved by what the metric provides."""
    check_choice(method, METHODS, "discrete-geodesic method", error=ValueError)
    has_model = callable(getattr(metric, "path_model", None))
    if method == "auto":
        return "levenberg-marquardt" if has_model else "newton-cg"
    if method == "levenberg-marquardt" and not has_model:
        raise MetricNotImplementedError(
            f"{type(metric).__name__}.path_model is not implemented: the Levenberg–Marquardt "
            "method needs the metric's least-squares path model; use method='newton-cg'")
    return method


def discrete_geodesic(
    metric,
    Q0: FloatArray,
    Q1: FloatArray,
    segments: int = 16,
    *,
    method: str = "auto",
    path: FloatArray | None = None,
    free: np.ndarray | None = None,
    boundary_edges: np.ndarray | None = None,
    anchor: FloatArray | None = None,
    options=None,
    callback=None,
) -> DiscreteGeodesic:
    """The ``segments``-segment discrete geodesic of ``metric`` from ``Q0`` to ``Q1``.

    Minimizes the path energy ``E = K Σ_k |X(Q_{k+1}) − X(Q_k)|²`` of the frames (``X`` the
    metric's embedding: ``(Q, f(Q))`` for a complete metric, ``(m^½ ⊙ Q, w φ(Q))`` for the
    distortion metric) over the free coordinates; every accepted iterate has all frames
    admissible.

    Parameters
    ----------
    metric : a :class:`~.metrics.Metric`: a complete metric or a penalty (Newton–CG),
        ``EuclideanMetric``/None (straight lines), or a metric with ``path_model``
        (Levenberg–Marquardt)
    Q0, Q1 : (N, d) admissible end frames (``d`` the metric's ``dimension``, 2 where it
        has none: the tet and surface metrics' is 3)
    segments : K ≥ 1
    method : "auto" (Levenberg–Marquardt where the metric has ``path_model``, else
        Newton–CG), "newton-cg" or "levenberg-marquardt"
    path : (K+1, N, d) admissible initial path; its ends are set to ``Q0`` and ``Q1``
        (default: :func:`.initial_path` for Newton–CG, the straight line for
        Levenberg–Marquardt)
    free : (K+1, N) bool, Levenberg–Marquardt only: which vertices of which frame move
        (frame 0 never does; default every vertex of the interior frames). A free vertex
        of the last frame starts at ``Q1``.
    boundary_edges : (E, 2) int, Levenberg–Marquardt only: boundaries kept simple in
        every accepted frame (for tets the boundary faces (F, 3); for a surface its
        contact, a ``motion.surface.morph_contact.PathContact``)
    anchor : Levenberg–Marquardt only: replaces the metric-specific part of ``X(Q0)`` in
        the first segment (for the distortion metric a (T, 3) strain: with one segment,
        the frame that stays close to ``Q0`` while its strain approaches ``anchor``)
    options : the method's settings: :class:`.NewtonCGOptions` or
        :class:`.LevenbergMarquardtOptions`, a mapping of their fields, or None (defaults)
    callback : ``callback(nit, E, gradient_norm)`` at every iteration; returning True stops
        the iteration (status "stopped")

    Returns
    -------
    DiscreteGeodesic
        ``status``: "converged", "max_iter", and "stationary" or "line_search"
        (Newton–CG), "stalled" (Levenberg–Marquardt); a path model's own rules may have
        their own (the surface's: "healthy", "max_iterations").

    Raises
    ------
    NotAdmissibleError
        An end frame or a frame of ``path`` is not admissible.
    MetricNotImplementedError
        ``method="levenberg-marquardt"`` for a metric without ``path_model``.
    """
    dimension = getattr(metric, "dimension", 2)  # the points' columns the metric takes
    Q0 = _as_points(Q0, "Q0", dimension)
    Q1 = _as_points(Q1, "Q1", dimension)
    K = int(segments)
    if K < 1:
        raise ValueError(f"segments must be >= 1, got {segments}")
    if Q0.shape != Q1.shape:
        raise InvalidMeshError(f"Q0 and Q1 have shapes {Q0.shape} and {Q1.shape}")
    method = _method_of(metric, method)
    settings = options_for(method, options)
    if method == "newton-cg":
        if free is not None or boundary_edges is not None or anchor is not None:
            raise ValueError("free, boundary_edges and anchor are settings of the "
                             "Levenberg–Marquardt method")
        return newton_cg(metric, Q0, Q1, K, path, settings, callback)
    if path is None:
        t = np.linspace(0.0, 1.0, K + 1)[:, None, None]
        path = (1.0 - t) * Q0 + t * Q1
    frames = _path_frames(path, Q0, Q1, K)
    if free is None:
        free = np.ones(frames.shape[:2], dtype=bool)
        free[-1] = False
    free = np.array(free, dtype=bool)
    if free.shape != frames.shape[:2]:
        raise InvalidMeshError(f"free must have shape {frames.shape[:2]}, got {free.shape}")
    free[0] = False
    model = metric.path_model(frames, free, boundary_edges, anchor)
    return levenberg_marquardt(model, frames, settings, callback)
