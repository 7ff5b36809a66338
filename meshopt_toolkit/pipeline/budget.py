"""The size budget: triangles of the current mesh estimated after each step.

A pipeline of three ``meshing_uniform_refinement`` steps of 8 iterations would make
``4**24`` times the input's triangles; it must be refused, not run until memory runs out.
Each step estimates the current mesh after it from the mesh before it
(:meth:`Filter.plan <meshopt_toolkit.pipeline.filter.Filter.plan>` for meshopt filters,
:func:`estimate_meshlab` for MeshLab ones); ``--dry-run`` chains the estimates from the
input, and at run time the estimate is checked before each step from the real mesh and
the real count after it. The default budget is
:data:`~meshopt_toolkit.pipeline.limits.DEFAULT_MAX_TRIANGLES` (``--max-triangles``).

MeshLab estimates are conservative upper bounds for the filters that grow meshes
(subdivision ×4 per iteration whatever the threshold, Catmull–Clark/Doo–Sabin ×2·4ⁿ,
isotropic remeshing ``2 · area / (√3/4 · L²)``, reconstructions from their resolution or
cell size); other filters are assumed not to grow the mesh and are measured after the
step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import FilterError
from ..kernels.surface import pad3
from ..mesh.kinds import is_tets

__all__ = ["MeshStats", "stats_of", "stats_of_arrays", "estimate_meshlab", "check_budget"]


@dataclass(frozen=True)
class MeshStats:
    """What the estimates need of the current mesh.

    Attributes
    ----------
    n_triangles : int or float
        Triangle count (a float once an estimate exceeds int range).
    area : float
        Total (unsigned) area.
    diagonal : float
        Bounding-box diagonal (MeshLab's reference for percentages).
    """

    n_triangles: float
    area: float = 0.0
    diagonal: float = 0.0

    def times(self, factor: float) -> MeshStats:
        return replace(self, n_triangles=self.n_triangles * factor)


def stats_of_arrays(points, triangles) -> MeshStats:
    """:class:`MeshStats` of ``(N, 2|3)`` points and ``(T, 3)`` triangles."""
    P = np.asarray(points, dtype=np.float64)
    T = np.asarray(triangles)
    if P.size == 0 or T.size == 0:
        return MeshStats(int(len(T)))
    P = pad3(P)
    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    with np.errstate(all="ignore"):
        area = 0.5 * float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
        diag = float(np.linalg.norm(P.max(0) - P.min(0)))
    return MeshStats(int(len(T)), area if math.isfinite(area) else 0.0,
                     diag if math.isfinite(diag) else 0.0)


def stats_of(mesh) -> MeshStats:
    """:class:`MeshStats` of a :class:`~meshopt_toolkit.mesh.TriangleMesh`; of a
    :class:`~meshopt_toolkit.mesh.TetMesh`, its tetrahedra counted as the budget's cells
    and its boundary's area."""
    if is_tets(mesh):
        return replace(stats_of_arrays(mesh.points, mesh.boundary_faces),
                       n_triangles=int(len(mesh.tets)))
    return stats_of_arrays(mesh.points, mesh.triangles)


def _param(name: str, vals: dict, key: str) -> Any:
    """The value of ``key`` for MeshLab filter ``name`` (given, else pymeshlab's default)."""
    if key in vals:
        return vals[key]
    from . import meshlab

    for p in meshlab.parameter_list(name):
        if p["name"] == key:
            text = p["default"].strip()
            if text.endswith("%"):
                return text
            try:
                return float(text)
            except ValueError:
                return None
    return None


def _length(value: Any, diagonal: float) -> float | None:
    """An absolute length from a MeshLab length value (number, "5%", {"abs"}/{"percent"})."""
    if isinstance(value, dict):
        if "abs" in value:
            return float(value["abs"])
        if "percent" in value:
            return float(value["percent"]) * diagonal / 100.0
        return None
    if isinstance(value, str) and value.strip().endswith("%"):
        return float(value.strip()[:-1]) * diagonal / 100.0
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    return None


def _by_length(stats: MeshStats, length: float | None, per_cell: float) -> MeshStats:
    """Triangles of a surface of ``stats.area`` tiled by cells of side ``length``."""
    if length is None:
        return stats
    if length <= 0.0:
        return replace(stats, n_triangles=math.inf)
    cells = stats.area / (math.sqrt(3.0) / 4.0 * length * length)
    return replace(stats, n_triangles=max(stats.n_triangles, per_cell * cells))


_TIMES_4N = frozenset({"meshing_surface_subdivision_midpoint", "meshing_surface_subdivision_loop",
                       "meshing_surface_subdivision_butterfly", "meshing_surface_subdivision_ls3_loop"})
_TIMES_2_4N = frozenset({"meshing_surface_subdivision_catmull_clark",
                         "meshing_surface_subdivision_doo_sabin"})
_RESOLUTION = frozenset({"generate_marching_cubes_apss", "generate_marching_cubes_rimls",
                         "create_noisy_isosurface"})


def estimate_meshlab(name: str, vals: dict, stats: MeshStats) -> MeshStats:
    """Estimated current mesh after MeshLab filter ``name`` (an upper bound where known)."""
    if name in _TIMES_4N or name in _TIMES_2_4N:
        it = _param(name, vals, "iterations")
        it = 1 if it is None else max(int(it), 0)
        return stats.times((2.0 if name in _TIMES_2_4N else 1.0) * 4.0 ** min(it, 400))
    if name in ("meshing_tri_to_quad_by_4_8_subdivision", "meshing_refine_by_function"):
        return stats.times(4.0)
    if name == "meshing_isotropic_explicit_remeshing":
        return _by_length(stats, _length(_param(name, vals, "targetlen"), stats.diagonal), 2.0)
    if name in ("generate_resampled_uniform_mesh", "generate_surface_reconstruction_vcg"):
        key = "cellsize" if name == "generate_resampled_uniform_mesh" else "voxsize"
        return _by_length(stats, _length(_param(name, vals, key), stats.diagonal), 16.0)
    if name == "generate_surface_reconstruction_screened_poisson":
        depth = _param(name, vals, "depth")
        depth = 8 if depth is None else min(max(int(depth), 0), 400)
        return replace(stats, n_triangles=12.0 * 4.0 ** depth)
    if name in _RESOLUTION:
        res = _param(name, vals, "resolution")
        res = 64 if res is None else max(float(res), 0.0)
        return replace(stats, n_triangles=12.0 * res * res)
    if name == "generate_solid_wireframe":
        return stats.times(64.0)
    return stats


def _count(n: float) -> str:
    return f"{n:,.0f}" if math.isfinite(n) and n < 1e15 else (
        "infinitely many" if not math.isfinite(n) else f"{n:.3g}")


def check_budget(estimate: MeshStats | None, budget: int, basis: str) -> None:
    """Raise FilterError when ``estimate`` exceeds ``budget`` triangles.

    ``basis`` says what the estimate started from (e.g. "the input's 16 triangles").
    """
    if estimate is None or estimate.n_triangles <= budget:
        return
    raise FilterError(f"about {_count(estimate.n_triangles)} triangles after this step "
                      f"(estimated from {basis}), over the budget of {budget:,} "
                      "(--max-triangles); refused")


def check_measured(n: int, budget: int) -> None:
    """Raise FilterError when a step made more than ``budget`` triangles."""
    if n > budget:
        raise FilterError(f"made {n:,} triangles, over the budget of {budget:,} "
                          "(--max-triangles); stopped")
