"""``mt.morph``: the morph between two meshes, one call whatever the metric.

The metric is chosen in one place, :data:`MORPH_METRICS`: ``"distortion"`` (the
per-triangle distortion metric ``M + w² JᵀJ``, :func:`~.motion.planar.morph.distortion_morph`:
frames as healthy as their ends) or ``"complete"`` (the complete metric of ``√N·f2``,
:func:`~.motion.planar.scalar_morph.geodesic_morph`: frames only non-inverted). The command
line's ``--metric scalar`` is the complete metric (:data:`METRIC_ALIASES`).

When a morph stops is :data:`STOP_RULES`: ``"healthy"`` stops a surface's morph as soon as
every interior frame is as healthy as the worse end (its default, ``"auto"``),
``"converged"`` runs the energy tests alone; planar and tet morphs have only the latter.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ._options import check_choice, require_at_least
from .conversions import Carried
from .errors import InvalidMeshError, OptionError
from .results import PathIteration
from .scaling import UnitScale, at_unit_size, size_scale

__all__ = ["CompleteMorph", "IN_SPACE", "METRIC_ALIASES", "MORPH_METRICS", "STOP_RULES", "morph"]

#: other names of the morph metrics
METRIC_ALIASES = {"scalar": "complete"}

#: default iterations of each metric's discrete geodesic (Levenberg–Marquardt for the
#: distortion metric, Newton–CG for the complete one, which usually stops earlier:
#: stationary energy)
DEFAULT_MAX_ITER = {"distortion": 200, "complete": 500}

#: when a morph stops: "auto" (each kind's default: "healthy" for surfaces in 3D,
#: "converged" for the others), "healthy" (surfaces in 3D: as soon as every interior frame's
#: worst relative quality is at least the worse end's, else on the energy tests) or
#: "converged" (the energy tests alone: a minimizer of the path energy)
STOP_RULES = ("auto", "healthy", "converged")


@dataclass(frozen=True)
class CompleteMorph:
    """The morph in the complete metric of ``√N·f2`` (thesis §5.4) with its options:
    ``mt.morph(..., metric=CompleteMorph(beta=...))``; ``metric="complete"`` is
    ``CompleteMorph()``.

    Attributes
    ----------
    beta : (β1, β2, β3, β4), optional
        The f2 coefficients (default :data:`~.motion.planar.scalar_morph.DEFAULT_BETA`).
    normalize : bool
        The metric of ``√N·f2`` (default) or of f2.
    method : str
        ``"discrete"``, ``"shooting"`` or ``"auto"``.
    """

    beta: tuple | None = None
    normalize: bool = True
    method: str = "discrete"


@dataclass(frozen=True)
class _Settings:
    weight: float
    complete: CompleteMorph
    max_iterations: int
    callback: Callable | None
    stop: str = "auto"
    contact: bool = True


def _no_healthy_stop(o: _Settings, what: str) -> None:
    if o.stop == "healthy":
        raise OptionError(f"stop='healthy' applies to surfaces in 3D only; {what} stop on "
                          "their energy tests alone (stop='converged', their default)")


def _distortion(source, target, frames: int, o: _Settings):
    """The distortion morph of planar or tet meshes, which stop on their energy tests."""
    if _kind_in_space(source) == "tetrahedra":
        from .motion.tets.morph import morph_tets as solve

        _no_healthy_stop(o, "tet morphs")
    else:
        from .motion.planar.morph import distortion_morph as solve

        _no_healthy_stop(o, "planar morphs")
    return solve(source, target, frames, weight=o.weight, max_iterations=o.max_iterations,
                 callback=o.callback)


def _complete(source, target, frames: int, o: _Settings):
    from .motion.planar.scalar_morph import DEFAULT_BETA, geodesic_morph

    if o.weight != 1.0:
        raise OptionError("weight applies to metric='distortion' only")
    _no_healthy_stop(o, "planar morphs")
    c = o.complete
    return geodesic_morph(source, target, frames,
                          beta=DEFAULT_BETA if c.beta is None else tuple(c.beta),
                          normalize=c.normalize, method=c.method, max_iterations=o.max_iterations,
                          callback=o.callback)


#: the morph of each metric
MORPH_METRICS = {"distortion": _distortion, "complete": _complete}


def _surfaces(source, target, frames: int, o: _Settings):
    from .motion.surface.mesh_morph import morph_surface_mesh

    hook = o.callback
    return morph_surface_mesh(source, target, frames, weight=o.weight,
                              max_iterations=o.max_iterations,
                              stop_when_healthy=o.stop != "converged", contact=o.contact,
                              callback=None if hook is None else (
                                  lambda r: hook(r.iteration, r.energy, r.gradient_norm)))


#: meshes in space, each morphed with its own distortion metric (tets:
#: :mod:`~.motion.tets.morph`, surfaces: :mod:`~.motion.surface.morph`), and its default
#: iterations of the discrete geodesic
IN_SPACE = {"tetrahedra": (_distortion, 200), "surfaces": (_surfaces, 10)}


def _kind_in_space(source) -> str | None:
    from .mesh.kinds import SURFACE, TETS, class_kind

    return {TETS: "tetrahedra", SURFACE: "surfaces"}.get(class_kind(source))


def morph(
    source,
    target,
    frames: int = 9,
    *,
    metric: str | CompleteMorph = "distortion",
    weight: float = 1.0,
    contact: bool = True,
    max_iterations: int | None = None,
    stop: str = "auto",
    callback: Callable[[PathIteration], bool | None] | None = None,
    progress: Callable[[float], None] | None = None,
):
    """Morph ``source`` into ``target`` (same vertices and triangles) along a geodesic.

    Parameters
    ----------
    source, target : PlanarMesh, TetMesh, SurfaceMesh, or meshio, trimesh or pymeshlab meshes
        Admissible meshes with the same connectivity, both of one type; tets and surfaces
        are morphed with their distortion metric (:data:`IN_SPACE`). Library objects are
        morphed as our meshes (:class:`~meshopt_toolkit.conversions.Carried`) and the
        frames come back of their type, each with everything the source carries but its
        points (uv, colours, attributes, point and cell data, …).
    frames : int
        Number of frames (≥ 2), both ends included.
    metric : ``"distortion"`` (default), ``"complete"`` (alias ``"scalar"``) or a
        :class:`CompleteMorph` (the complete metric with other options than its defaults:
        ``CompleteMorph(beta=..., normalize=..., method=...)``)
    weight : float
        Distortion metric: ``w`` of ``M + w² JᵀJ``.
    contact : bool
        Surfaces in 3D (default True): where both poses are free of self-intersections, no
        frame, nor the motion between two frames, passes through the surface (an IPC
        barrier in the path energy, every step capped by continuous collision detection;
        :mod:`~.motion.surface.morph_contact`). Planar and tet meshes need none: an
        admissible frame cannot overlap itself.
    max_iterations : int, optional
        Iterations of the discrete geodesic (default :data:`DEFAULT_MAX_ITER`, in space
        :data:`IN_SPACE`).
    stop : ``"auto"`` (default), ``"healthy"`` or ``"converged"`` (:data:`STOP_RULES`)
        Surfaces in 3D: ``"healthy"`` (their default) stops as soon as every interior
        frame's worst relative quality is at least the worse end's (then no frame can be
        better; the path energy is not minimized further), ``"converged"`` runs the energy
        tests alone (a lower path energy, more iterations). Planar and tet morphs stop on
        their energy tests only: ``"healthy"`` is refused for them.
    callback : callable ``PathIteration -> bool | None``, optional
        Called once per iteration; returning True stops the iteration (status
        ``"stopped"``; the frames are admissible, not yet a minimizer).
    progress : callable ``fraction -> None``, optional
        Iterations done over ``max_iterations`` (an upper bound: most morphs stop earlier).

    Returns
    -------
    DistortionMorph, MorphResult, TetMorphResult, SurfaceMeshMorph or CarriedResult
        All with ``mesh``, ``frames`` (meshes with the source's tags), ``summary()``,
        ``seconds`` and ``status`` (:class:`~meshopt_toolkit.results.Result`).

    Raises
    ------
    OptionError
        ``frames < 2``, an unknown metric, method or stop rule, ``weight`` with the complete
        metric, ``stop="healthy"`` for a planar or tet morph.
    InvalidMeshError, NotAdmissibleError
        Different connectivity, ends of different types, a non-admissible end.
    """
    carried, other = Carried.of(source), Carried.of(target)
    if carried is not None or other is not None:  # library objects: morphed as ours
        if carried is None or other is None or type(source) is not type(target):
            raise InvalidMeshError(f"cannot morph a {type(source).__name__} into a "
                                   f"{type(target).__name__}: give both of one type")
        return carried.result(morph(
            carried.mesh, other.mesh, frames, metric=metric, weight=weight, contact=contact,
            max_iterations=max_iterations, stop=stop, callback=callback, progress=progress))
    if isinstance(metric, CompleteMorph):
        name, complete = "complete", metric
    else:
        name, complete = METRIC_ALIASES.get(metric, metric), CompleteMorph()
    run = MORPH_METRICS.get(name)
    if run is None:
        raise OptionError(f"unknown morph metric {metric!r}; choose one of "
                          f"{', '.join(MORPH_METRICS)}")
    space = _kind_in_space(source)
    if space is not None:
        if name != "distortion":
            raise OptionError(f"{space} in 3D are morphed with metric='distortion' only, "
                              f"not {metric!r}")
        run, default_iterations = IN_SPACE[space]
    else:
        default_iterations = DEFAULT_MAX_ITER[name]
    require_at_least("frames", frames, 2)
    check_choice(stop, STOP_RULES, "stop rule", error=OptionError)
    n_iter = default_iterations if max_iterations is None else int(max_iterations)
    require_at_least("max_iterations", n_iter, 1)

    def step(nit: int, energy: float, gradient_norm: float) -> bool:
        if progress is not None:
            progress(min(1.0, nit / n_iter))
        if callback is not None:
            return bool(callback(PathIteration(int(nit), float(energy), float(gradient_norm))))
        return False

    hook = step if callback is not None or progress is not None else None
    settings = _Settings(float(weight), complete, n_iter, hook, stop, bool(contact))
    # at unit size (both ends divided by their size) and back: the same morph at every
    # scale
    return at_unit_size(lambda s, t: run(s, t, int(frames), settings),
                        size_scale(source, target, columns=2 if space is None else 3),
                        (source, target), lambda r, scale: _scaled_up(r, scale, source, target))


def _scaled_up(result, scale: UnitScale, source, target):
    """A morph of the ends at unit size at the user's scale: the frames (the vertices it
    leaves alone bitwise, the ends the user's) and every length of the result."""
    surface = getattr(result, "morph", None)  # a surface's morph: its solver's inside
    unit = np.asarray(result.points if surface is None else surface.points)
    ends = [np.asarray(m.points)[:, :unit.shape[-1]] for m in (source, target)]
    points = scale.points_up(unit, ends[0])
    points[0], points[-1] = ends
    if surface is None:
        return replace(result.scaled_up(scale, source), points=points)
    frames = [source.with_points(p) for p in points]
    return replace(result, mesh=frames[-1], frames=frames,
                   morph=replace(surface, points=points))
