"""``mt.move`` on triangle surfaces in 3D: :func:`move_surface` on a :class:`SurfaceMesh`,
the moved mesh keeping its triangles, tags and names (``mt.move`` gives a
``trimesh.Trimesh`` or ``pymeshlab.Mesh`` here as a SurfaceMesh).

A surface has no boundary to keep when it is closed: the handles are exactly the vertices
given, every other vertex is free.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...errors import InvalidMeshError
from ...mesh.kinds import is_surface
from ...results import WrappedMotion
from ...scaling import unit_scale
from ..engine.handles import SolvedVertices, check_handles, distinct_handles
from ..engine.pinned_cells import surface_targets_problem
from .move import SurfaceMoveOptions, move_surface

__all__ = ["SurfaceMeshMoveResult", "move_surface_mesh"]


@dataclass
class SurfaceMeshMoveResult(WrappedMotion):
    """What :func:`meshopt_toolkit.move` returns for a surface: a
    :class:`~meshopt_toolkit.results.WrappedMotion` of
    :class:`~meshopt_toolkit.mesh.SurfaceMesh` frames around a
    :class:`~.move.SurfaceMoveResult` (worst relative quality, folds, bound)."""


def move_surface_mesh(mesh, handles, targets, *, frames: int | None = None, steps: int = 4,
                      weight: float = 1.0, relax_iterations: int = 15, max_splits: int = 8,
                      quality_rounds: int | None = None,
                      progress: Callable[[float], None] | None = None,
                      contact: bool = True) -> SurfaceMeshMoveResult:
    """:func:`move_surface` on a :class:`SurfaceMesh` (what ``mt.move`` calls for one).

    ``steps``, ``weight`` and ``contact`` are those of :func:`move_surface`, ``max_splits``
    its ``max_halvings``; ``relax_iterations`` and ``quality_rounds`` (options of the
    planar and tet solvers) are not used. With ``frames = K`` at least ``K − 1`` increments are taken and
    the K frames are those whose path fractions are nearest to ``0, 1/(K−1), …, 1``.
    The motion is solved at unit size (the surface divided by the power of two nearest
    its size, :mod:`..scaling`) and scaled back: a surface scaled by ``2**k`` moves to
    the result scaled by ``2**k``.

    Raises
    ------
    InvalidMeshError
        Bad handles or targets, a degenerate triangle; targets that make a triangle
        whose corners are all handles degenerate, or turn a closed surface whose
        vertices are all handles inside out (a mirror image).
    NotAdmissibleError
        No fold-free increment of the handles' path; or, where the path runs into the
        surface, handles that pulled along it cannot reach their targets
        (:mod:`.handle_pull`).
    """
    del relax_iterations, quality_rounds  # options of the other solvers
    if not is_surface(mesh):
        raise InvalidMeshError(f"cannot move a {type(mesh).__name__} as a surface")
    surface = mesh
    if progress is not None:
        progress(0.0)
    h, tg = distinct_handles(*check_handles(handles, targets, len(surface.points)))
    # vertices in no triangle are left out of the solve (no mass) and stay put
    solved = SolvedVertices(surface.points, surface.triangles, h, tg)
    n_steps = max(int(steps), (frames or 2) - 1)
    # solved at unit size (an exact power of two): the same motion at every scale
    scale = unit_scale(solved.points, columns=3)
    if problem := surface_targets_problem(
            scale.down(solved.points), solved.cells, solved.handles,
            scale.down(solved.targets), surface.is_closed and surface.is_oriented):
        raise InvalidMeshError(problem)
    res = move_surface(scale.down(solved.points), solved.cells, solved.handles,
                       scale.down(solved.targets), steps=n_steps, contact=contact,
                       options=SurfaceMoveOptions(weight=weight, max_halvings=max_splits)
                       ).scaled_up(scale)
    res.points[solved.handles] = solved.targets  # bitwise, subnormal targets included

    moved = surface.with_points(solved.full(res.points))
    if frames is not None:
        times = np.asarray(res.times)
        pick = [int(np.argmin(np.abs(times - s))) for s in np.linspace(0, 1, int(frames))]
        out = [surface.with_points(solved.full(res.frames[i])) for i in pick[:-1]]
        out.append(moved)
    else:
        out = [mesh, moved]
    if progress is not None:
        progress(1.0)
    return SurfaceMeshMoveResult(mesh=moved, frames=out, motion=res)
