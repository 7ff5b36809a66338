"""The result record of the scalar-metric morph (:class:`MorphResult`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..._typing import FloatArray
from ...mesh import PlanarMesh
from ...riemannian.geodesic_result import DiscreteGeodesic, LogMapResult
from ...scaling import UnitScale


# ---------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------


@dataclass
class MorphResult:
    """Frames of a geodesic morph and their diagnostics.

    Attributes
    ----------
    points : (K, N, 2) frame positions, ``points[0]`` the source, ``points[-1]`` the target
    times : (K,) curve parameter of each frame in [0, 1]
    triangles : (T, 3) the shared connectivity
    method : "shooting" (frames on the exact geodesic ``exp(tV)``) or "discrete"
    target_error : max-norm distance of the geodesic's end from the target before the last
        frame is set to the target (0 for "discrete": its end frame is the target)
    min_aspect_ratio : (K,) ``min 2r/R`` per frame
    min_area : (K,) smallest signed area per frame
    admissible : (K,) every signed area > 0 and the penalty finite
    linear_min_aspect_ratio, linear_min_area : (K,) the same for linear interpolation
        ``(1 − t) Q0 + t Q1`` at the same times (negative area = inverted)
    linear_min_area_dense : smallest signed area of linear interpolation over the whole
        segment from source to target, exact (:func:`~.geometry.min_signed_areas_on_segment`;
        the linear path may invert between frames)
    length : geodesic length (``|V|_g`` for shooting, polygon length for discrete)
    log : the LogMapResult of the shooting (None when not attempted)
    discrete : the DiscreteGeodesic used
    seconds : wall time
    rigid_min_aspect_ratio, rigid_min_area : (K,) the same for the as-rigid-as-possible
        interpolation (:func:`~.interpolation.arap_interpolation`) at the same times: no
        guarantee of admissibility, but often far from degenerate where the geodesic of
        ``g = I + ∇f∇fᵀ`` squeezes triangles (the metric only resists motion along ∇f)
    metric_scale : the factor c of the default metric ``c · f2`` (None for a given metric)
    between_frames_min_area : (K − 1,) exact smallest signed area along the straight
        segment between consecutive frames (:func:`~.geometry.min_signed_areas_on_segment`):
        all positive means that linear in-betweening of the frames never inverts either
    unit_scale : the size the ends were divided by (:func:`~meshopt_toolkit.scaling.size_scale`):
        every area above is one of the unit-size problem (times ``unit_scale.factor**2``
        at the user's scale, a number that may leave the floating-point range)
    """

    points: FloatArray
    times: FloatArray
    triangles: np.ndarray
    method: str
    target_error: float
    min_aspect_ratio: FloatArray
    min_area: FloatArray
    admissible: np.ndarray
    linear_min_aspect_ratio: FloatArray
    linear_min_area: FloatArray
    linear_min_area_dense: float
    length: float
    log: LogMapResult | None = None
    discrete: DiscreteGeodesic | None = None
    seconds: float = 0.0
    rigid_min_aspect_ratio: FloatArray | None = None
    rigid_min_area: FloatArray | None = None
    between_frames_min_area: FloatArray | None = None
    metric_scale: float | None = None
    #: the source mesh: the frames carry its tags
    source: PlanarMesh | None = None
    unit_scale: UnitScale = field(default_factory=UnitScale)

    @property
    def n_frames(self) -> int:
        return len(self.points)

    def scaled_up(self, scale: UnitScale, source: PlanarMesh) -> MorphResult:
        """This morph of the meshes at unit size, at the user's scale: frames, the target
        error and the user's ``source``; the areas stay the unit problem's, with ``scale``
        as :attr:`unit_scale` (an area of a mesh near 1e300 is past the float range), the
        rest is scale-free or the unit problem's (``length``)."""
        return replace(self, points=scale.up(self.points), source=source,
                       target_error=float(scale.up(self.target_error)), unit_scale=scale)

    @property
    def frames(self) -> list:
        """The frames as meshes with the source's tags (first = source, last = target)."""
        return self.meshes(like=self.source)

    @property
    def mesh(self):
        """The last frame (the target's points, the source's tags)."""
        return self.frames[-1]

    @property
    def status(self) -> str:
        """The discrete geodesic's status, or ``"converged"`` for converged shooting."""
        if self.method == "shooting" or self.discrete is None:
            return "converged"
        return self.discrete.status

    def meshes(self, like=None) -> list:
        """The frames as PlanarMesh objects (tags of ``like`` kept when given)."""
        if like is not None:
            base = like.as_planar()
            return [base.with_points(p) for p in self.points]
        return [PlanarMesh(p, self.triangles) for p in self.points]

    def summary(self) -> dict:
        """JSON-able summary (frames, target_error, min_aspect_ratio, admissible, ...)."""
        return {
            "frames": int(self.n_frames),
            "method": self.method,
            "target_error": float(self.target_error),
            "min_aspect_ratio": float(np.min(self.min_aspect_ratio)),
            "min_aspect_ratio_per_frame": [float(x) for x in self.min_aspect_ratio],
            "admissible": bool(np.all(self.admissible)),
            "linear_min_area": float(self.linear_min_area_dense),
            "linear_min_aspect_ratio": float(np.min(self.linear_min_aspect_ratio)),
            "linear_inverts": bool(self.linear_min_area_dense <= 0),
            "rigid_min_aspect_ratio": (None if self.rigid_min_aspect_ratio is None
                                       else float(np.min(self.rigid_min_aspect_ratio))),
            "rigid_inverts": (None if self.rigid_min_area is None
                              else bool(np.min(self.rigid_min_area) <= 0)),
            "inversion_free_between_frames": (
                None if self.between_frames_min_area is None
                else bool(np.min(self.between_frames_min_area) > 0)),
            "metric_scale": self.metric_scale,
            "length": float(self.length),
            "shooting_residual": None if self.log is None else float(self.log.residual),
            "shooting_iterations": None if self.log is None else int(self.log.iterations),
            "discrete_iterations": None if self.discrete is None else int(self.discrete.nit),
            "discrete_converged": None if self.discrete is None else bool(self.discrete.converged),
            "discrete_status": None if self.discrete is None else self.discrete.status,
            "status": self.status,
            "seconds": float(self.seconds),
            "unit_scale": self.unit_scale.factor,
        }


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------


