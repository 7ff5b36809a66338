"""``mt.morph`` on triangle surfaces in 3D: :func:`.morph.morph_surface` between
two :class:`SurfaceMesh` poses with the same triangles, the frames with the source's
triangles, tags and names (``mt.morph`` gives ``trimesh.Trimesh`` and ``pymeshlab.Mesh``
poses here as SurfaceMeshes)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ...errors import InvalidMeshError
from ...mesh import SurfaceMesh
from ...mesh.kinds import is_surface
from ...results import PathIteration
from ...scaling import unit_scale
from ..engine.handles import SelfIntersectionGuard
from .morph import BENDING, WEIGHT, SurfaceMorph, morph_surface

__all__ = ["SurfaceMeshMorph", "morph_surface_mesh"]


@dataclass
class SurfaceMeshMorph:
    """What :func:`meshopt_toolkit.morph` returns for surfaces (the
    :class:`~meshopt_toolkit.results.Result` protocol).

    Attributes
    ----------
    mesh : SurfaceMesh, the target pose (the last frame)
    frames : list of SurfaceMesh, the source first and the target last
    morph : SurfaceMorph, the solver's result (points, per-frame measures)
    """

    mesh: SurfaceMesh
    frames: list[SurfaceMesh]
    morph: SurfaceMorph

    seconds = property(lambda self: self.morph.seconds, doc="Wall time.")
    status = property(lambda self: self.morph.status,
                      doc='"healthy", "converged", "max_iterations", "stalled", "stopped", '
                          '"similarity" or "identical".')
    n_frames = property(lambda self: len(self.frames), doc="Number of frames.")

    def summary(self) -> dict:
        return self.morph.summary()


def morph_surface_mesh(source, target, frames: int = 9, *, weight: float = WEIGHT,
                       bending: float = BENDING, max_iterations: int = 10,
                       stop_when_healthy: bool = True,
                       callback: Callable[[PathIteration], bool | None] | None = None,
                       progress: Callable[[float], None] | None = None,
                       contact: bool = True) -> SurfaceMeshMorph:
    """:func:`morph_surface` between two poses given as :class:`SurfaceMesh` (the same
    triangles); ``stop_when_healthy`` and ``contact`` as there. Every frame returned is
    checked exactly for self-intersections where neither end has one (with contact too:
    the exact check is the last guard of every frame).

    Raises
    ------
    InvalidMeshError
        Meshes that are not both surfaces, a different number of points or other
        triangles, a
        degenerate triangle.
    NotAdmissibleError
        No fold-free start path.
    SelfIntersectionError
        A frame that intersects itself, where neither end does (exact; no frame is
        returned); with contact, no clean start path.
    """
    if not (is_surface(source) and is_surface(target)):
        raise InvalidMeshError(f"cannot morph a {type(source).__name__} into a "
                               f"{type(target).__name__} as surfaces")
    s, t = source, target
    if len(s.points) != len(t.points) or not np.array_equal(s.triangles, t.triangles):
        raise InvalidMeshError(
            "source and target have different connectivity: "
            + (f"{len(s.points)} points and {len(s.triangles)} triangles against "
               f"{len(t.points)} and {len(t.triangles)}"
               if (len(s.points), len(s.triangles)) != (len(t.points), len(t.triangles))
               else "other triangles"))
    guard = SelfIntersectionGuard.of_morph(s, t)  # ends through themselves: not checked
    if progress is not None:
        progress(0.0)
    hook = callback
    if progress is not None:
        def hook(record: PathIteration):
            progress(min(1.0, record.iteration / max(int(max_iterations), 1)))
            return callback(record) if callback is not None else None
    # at unit size (an exact power of two, both poses alike) and back: the same morph at
    # every scale
    scale = unit_scale(s.points, t.points, columns=3)
    res = morph_surface(scale.down(s.points), scale.down(t.points), s.triangles, frames,
                        weight=weight, bending=bending, max_iterations=max_iterations,
                        stop_when_healthy=stop_when_healthy, callback=hook,
                        contact=contact)
    res = replace(res, points=scale.up(res.points))

    guard.check(res.points, motion="the morph", last=False)

    out = [s.with_points(P) for P in res.points]
    if progress is not None:
        progress(1.0)
    return SurfaceMeshMorph(mesh=out[-1], frames=out, morph=res)
