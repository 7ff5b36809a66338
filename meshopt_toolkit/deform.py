"""Quality-preserving mesh deformation along complete-metric geodesics (thesis §5.5.3).

Given a mesh and an initial velocity ``V`` — typically nonzero only on boundary vertices,
like a shape derivative supported on the boundary — :func:`deform` follows the geodesic of
the complete metric ``g = I + ∇f∇fᵀ`` with ``γ(0) = Q``, ``γ'(0) = V``. The interior
vertices move automatically (no elasticity extension needed), and the mesh stays admissible
for every time, because f grows at most linearly along the geodesic.

Default penalty: f1 (:class:`~meshopt_toolkit.penalties.HeightPenalty`) with the thesis'
§5.5 parameters ``α = (α1, α2, α3) = (1, 0, 1)`` and ``Qref`` the input mesh: the height
term keeps triangles from thinning, the reference term makes the metric complete, and the
boundary-pair term is off (remark 5.2.10, as in all §5.5 experiments; pass ``alpha`` with
α2 > 0 to guard against boundary self-contact, at a cost). f1 is not scale invariant, so the
mesh and the velocity are deformed at unit size (divided by the mesh's size,
:func:`~meshopt_toolkit.scaling.at_unit_size`) and the frames scaled back: a mesh scaled by
any factor deforms into the frames scaled by it (a penalty object given by the caller is
used at the caller's scale).
"""

from __future__ import annotations

import dataclasses
from time import perf_counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._options import require_at_least
from ._typing import FloatArray
from .conversions import Carried
from .errors import IntegrationError, InvalidMeshError, OptionError, ReadError
from .kernels.admissibility import BoundaryCheck, area_problem
from .riemannian.geodesic_options import GeodesicOptions
from .riemannian.geodesics import GeodesicResult, geodesic
from .kernels.triangles import aspect_ratios
from .mesh import PlanarMesh, TriangleMesh, require_admissible
from .scaling import UnitScale, at_unit_size, size_scale

__all__ = ["DEFAULT_ALPHA", "DeformResult", "deform"]

#: thesis §5.5.2 parameters of f1 (α1, α2, α3)
DEFAULT_ALPHA = (1.0, 0.0, 1.0)


@dataclass
class DeformResult:
    """The deformation path.

    Attributes
    ----------
    mesh : PlanarMesh at the final time
    times : (K,) frame times (0 first, ``time`` last)
    points : (K, N, 2) positions per frame
    aspect_ratio : (K,) mesh aspect ratio ``min 2r/R`` (5.49) per frame
    penalty : the penalty f defining the metric (None for ``metric="euclidean"``)
    geodesic : the underlying :class:`~meshopt_toolkit.riemannian.geodesics.GeodesicResult`
    seconds : wall time
    """

    mesh: PlanarMesh
    times: FloatArray
    points: FloatArray
    aspect_ratio: FloatArray
    penalty: object
    geodesic: GeodesicResult
    seconds: float = 0.0

    def meshes(self) -> list[PlanarMesh]:
        """One :class:`PlanarMesh` per frame (same connectivity and tags)."""
        return [self.mesh.with_points(p) for p in self.points]

    @property
    def frames(self) -> list[PlanarMesh]:
        """The frames as meshes (first = input, last = :attr:`mesh`)."""
        return self.meshes()

    @property
    def status(self) -> str:
        """``"done"``, or ``"warnings"`` when the integration reported a violated invariant."""
        return "warnings" if self.geodesic.warnings else "done"

    def summary(self) -> dict:
        """JSON-ready summary: times, aspect ratio per frame, the integration's counts."""
        g = self.geodesic
        return {
            "status": self.status,
            "frames": int(len(self.points)),
            "times": [float(t) for t in self.times],
            "min_aspect_ratio": float(np.min(self.aspect_ratio)),
            "aspect_ratio": [float(a) for a in self.aspect_ratio],
            "metric": "euclidean" if self.penalty is None else "complete",
            "method": g.method,
            "steps": int(g.n_steps),
            "evaluations": int(g.n_evaluations),
            "max_energy_drift": float(g.max_energy_drift),
            "warnings": list(g.warnings),
            "seconds": float(self.seconds),
        }


def _penalty(mesh: PlanarMesh, penalty, alpha):
    from .penalties import HeightPenalty, QualityPenalty

    if penalty is not None and alpha is not None:
        raise OptionError("give at most one of penalty and alpha")
    if penalty is not None and not _is_beta(penalty):
        return penalty
    try:
        if penalty is not None:
            return QualityPenalty(mesh, beta=tuple(float(b) for b in penalty))
        return HeightPenalty(mesh, alpha=DEFAULT_ALPHA if alpha is None else alpha)
    except ValueError as exc:
        raise InvalidMeshError(str(exc)) from None


def _is_beta(penalty) -> bool:
    """Whether ``penalty`` is f2's four numbers rather than a penalty object."""
    return not hasattr(penalty, "value") and np.ndim(penalty) == 1


def deform(
    mesh: TriangleMesh,
    displacement,
    time: float = 1.0,
    frames: int | None = None,
    *,
    penalty=None,
    alpha=None,
    metric: str = "complete",
    options: GeodesicOptions | None = None,
    progress=None,
) -> DeformResult:
    """Deform ``mesh`` along the geodesic with initial velocity ``displacement``.

    Parameters
    ----------
    mesh : PlanarMesh (admissible), or a planar ``meshio.Mesh``
        A meshio mesh is deformed as a PlanarMesh and comes back as a ``CarriedResult``
        whose meshes are meshio meshes with all its cells and data, only the points moved
        (:class:`~meshopt_toolkit.conversions.Carried`).
    displacement : (N, 2) array_like
        Initial velocity ``V``; at ``time = 1`` a Euclidean path would have moved every
        vertex by exactly this amount.
    time : final time ``T``
    frames : number K ≥ 2 of equally spaced frames on [0, T] (default: just 0 and T)
    penalty : (β1, β2, β3, β4) of f2 (5.22, β4 unscaled), or a penalty object
        (value/gradient/hvp/gradient_and_curvature); or
    alpha : (α1, α2, α3) for f1 (5.16);
        default f1 with ``α = (1, 0, 1)`` (thesis §5.5), ``Qref`` = the input mesh
    metric : "complete" (default) or "euclidean" (straight lines ``Q + tV``, for
        comparison; may invert triangles, which ``aspect_ratio`` then shows as ≤ 0)
    options : :class:`~meshopt_toolkit.riemannian.geodesic_options.GeodesicOptions`
        (method, ``rtol``, ``atol``, ``on_violation``, …) of the integration; frames are
        always step ends (``dense=False``)
    progress : callable ``fraction -> None``, optional
        Called per integration step with the fraction of ``[0, T]`` done.

    Returns
    -------
    DeformResult
        Its frames at the user's scale; ``penalty`` and ``geodesic`` are those of the
        unit-size problem.

    Raises
    ------
    NotAdmissibleError
        The input mesh is not admissible.
    InvalidMeshError
        The displacement does not have shape (N, 2) or is not finite.
    OptionError
        ``frames < 2``, an unknown ``metric``, or both penalty and alpha.
    IntegrationError
        The geodesic cannot be integrated (never an inverted mesh).
    """
    if (carried := Carried.of(mesh)) is not None:  # a library object: deformed as ours
        return carried.result(deform(carried.mesh, displacement, time, frames, penalty=penalty,
                                     alpha=alpha, metric=metric, options=options,
                                     progress=progress))
    start = perf_counter()
    require_at_least("frames", frames, 2)
    if metric not in ("complete", "euclidean"):
        raise OptionError(f"metric must be 'complete' or 'euclidean', got {metric!r}")
    m = require_admissible(mesh, "deform")
    V = np.asarray(displacement, dtype=float)
    if V.shape != m.points.shape:
        raise InvalidMeshError(
            f"displacement has shape {V.shape}, the mesh has {m.points.shape} points"
        )
    if not np.isfinite(V).all():
        raise InvalidMeshError("displacement has non-finite entries")
    if frames is None:
        times = np.array([0.0, float(time)])
    else:
        times = np.linspace(0.0, float(time), int(frames))
    # at unit size (the mesh and the velocity divided by the mesh's size) and back: the
    # same deformation at every scale; a penalty object is the user's, at the user's scale
    scale = (UnitScale() if penalty is not None and not _is_beta(penalty)
             else size_scale(m))
    return at_unit_size(
        lambda unit, velocity: _deform(unit, velocity, times, penalty, alpha, metric, options,
                                       progress, start),
        scale, (m, V), lambda result, sc: _scaled_up(result, sc, m))


def _deform(m: PlanarMesh, V: FloatArray, times: FloatArray, penalty, alpha, metric: str,
            options, progress, start: float) -> DeformResult:
    """:func:`deform` of an admissible mesh and a checked velocity."""
    pen = met = None if metric == "euclidean" else _penalty(m, penalty, alpha)
    # frames are few: land on each (exact velocities and energies in the result)
    opts = dataclasses.replace(options or GeodesicOptions(), dense=False)
    res = geodesic(met, m.points, V, float(times[-1]), times=times, options=opts,
                   progress=progress)
    if pen is not None:  # the complete metric promises admissible frames: judged exactly
        check = BoundaryCheck(m.boundary_edges, m.boundary_vertices)
        for k, p in enumerate(res.points):
            if problem := area_problem(p, m._triangle_columns) or check.test(p):
                raise IntegrationError(f"deform: frame {k} is not admissible: {problem}")
    ar = np.array([float(aspect_ratios(p, m.triangles).min()) for p in res.points])
    return DeformResult(
        mesh=m.with_points(res.points[-1]), times=times, points=res.points,
        aspect_ratio=ar, penalty=pen, geodesic=res, seconds=perf_counter() - start,
    )


def _scaled_up(result: DeformResult, scale: UnitScale, mesh: PlanarMesh) -> DeformResult:
    """A deformation of the mesh at unit size at the user's scale: the frames (the
    vertices it leaves alone bitwise, the first the user's mesh)."""
    points = scale.points_up(result.points, mesh.points)
    points[0] = mesh.points
    return dataclasses.replace(result, mesh=mesh.with_points(points[-1]), points=points)


def load_displacement(spec, mesh: PlanarMesh, plane=None) -> FloatArray:
    """Read an initial velocity for ``mesh`` from a file.

    ``spec`` is a ``.npy`` or ``.csv`` (N, 2) array (an (N, 3) array with z = 0 is
    accepted), or a mesh file with the same connectivity (V = its points − ``mesh``'s).
    ``plane(points, source)``, when given, maps that file's points into ``mesh``'s plane
    coordinates (:meth:`~meshopt_toolkit.io.workpiece.Workpiece.plane_coordinates`).

    Raises
    ------
    ReadError
        The file is missing or unreadable.
    InvalidMeshError
        Wrong shape, or a mesh with another connectivity.
    """
    from .io import load

    path = Path(spec)
    if not path.is_file():
        raise ReadError(f"{spec}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise ReadError(f"{spec}: not a readable .npy array ({exc})") from None
    elif suffix in (".csv", ".txt"):
        try:
            arr = np.loadtxt(path, delimiter=",", ndmin=2, dtype=float)
        except ValueError as exc:
            raise ReadError(f"{spec}: not a numeric CSV array ({exc})") from None
    else:
        other = load(path)
        if other.n_vertices != mesh.n_vertices or not np.array_equal(other.triangles, mesh.triangles):
            raise InvalidMeshError(
                f"{spec}: the displacement mesh must have the same connectivity as the input "
                f"({other.n_vertices} vs {mesh.n_vertices} vertices, "
                f"{other.n_triangles} vs {mesh.n_triangles} triangles)"
            )
        if plane is not None:
            arr = plane(other.points, str(spec)) - mesh.points
        elif not other.in_xy_plane:
            raise InvalidMeshError(f"{spec}: the displacement mesh is not in the plane z = 0")
        else:
            arr = np.asarray(other.points)[:, :2] - mesh.points
    arr = np.asarray(arr, dtype=float)
    if arr.ndim == 2 and arr.shape[1] == 3 and not np.any(arr[:, 2]):
        arr = arr[:, :2]
    if arr.shape != mesh.points.shape:
        raise InvalidMeshError(
            f"{spec}: displacement has shape {arr.shape}, the mesh has {mesh.points.shape} points"
        )
    return arr
