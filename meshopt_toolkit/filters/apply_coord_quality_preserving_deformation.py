"""Filter ``apply_coord_quality_preserving_deformation``: follow a complete-metric geodesic."""

from __future__ import annotations

import numpy as np

from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.pipeline.filter import PLANAR, Filter, register
from meshopt_toolkit.pipeline.params import FloatParam, NumberListParam, PathParam, number_list


@register
class QualityPreservingDeformation(Filter):
    """Deform the current planar mesh along the geodesic of the complete metric
    ``g = I + ∇f∇fᵀ`` (thesis §5.5) with initial velocity ``V`` read from a file.

    ``displacement`` is a ``.npy``/``.csv`` (N, 2) array or a mesh with the same
    connectivity (``V`` = its points − the current points); ``{stem}`` in the path is
    replaced by the input file's stem. At ``time = 1`` a Euclidean path would have moved
    every vertex by exactly ``V``; the geodesic never inverts a triangle. The penalty is f1
    with ``alpha`` (default thesis §5.5: 1, 0, 1) or f2 with ``penalty`` (β4 unscaled). The
    deformed mesh replaces the current one; per-face quality is left untouched. As with
    ``meshopt deform``, the mesh goes to ``mt.deform`` at the file's scale (``mt.deform``
    works at unit size itself, :mod:`meshopt_toolkit.scaling`); the penalties reported are
    those of the unit-size problem.
    """

    name = "apply_coord_quality_preserving_deformation"
    label = "Quality Preserving Deformation (meshopt)"
    #: the former name, still accepted in saved pipelines
    aliases = ("apply_quality_preserving_deformation",)
    renamed_parameters = {"beta": "penalty"}
    description = "Move the mesh along a complete-metric geodesic with a given initial velocity; never inverts."
    kinds = (PLANAR,)
    parameters = (
        PathParam("displacement", "", "initial velocity: .npy/.csv (N, 2) array or a mesh with the same connectivity",
                  label="Displacement"),
        FloatParam("time", 1.0, "final time T of the geodesic", label="Time", min=0.0),
        NumberListParam("alpha", "", "f1 parameters a1,a2,a3 (default 1,0,1)", label="Alpha", count=3),
        NumberListParam("penalty", "", "use f2 with b1,b2,b3,b4 instead (b4 unscaled)",
                        label="Penalty", count=4),
    )

    def apply(self, document, *, displacement: str = "", time: float = 1.0, alpha: str = "",
              penalty: str = "") -> dict:
        from meshopt_toolkit.deform import deform, load_displacement

        entry = document.current_entry
        if not displacement:
            raise FilterError(f"{self.name}: the displacement parameter is required")
        a, b = number_list(alpha, 3, "alpha"), number_list(penalty, 4, "penalty")
        if a is not None and b is not None:
            raise FilterError(f"{self.name}: give alpha or penalty, not both")
        # the plane's coordinates at the file's scale; the file's blocks, tags and data kept
        wp = entry.workpiece(self.name).admissible(self.name)
        mesh = wp.mesh
        V = load_displacement(displacement.replace("{stem}", entry.name), mesh,
                              wp.plane_coordinates)
        result = deform(mesh, V, time=time, alpha=a, penalty=b)
        entry.set_workpiece(wp.moved(result.mesh.points))
        with np.errstate(over="ignore"):  # a displacement past the float range: inf
            moved = float(np.abs(result.mesh.points - mesh.points).max())
        return {"time": float(time), "min_aspect_ratio": float(np.min(result.aspect_ratio)),
                "max_displacement": moved,
                "penalty_start": float(result.geodesic.penalty[0]),
                "penalty_end": float(result.geodesic.penalty[-1])}
