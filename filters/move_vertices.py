"""Filter ``apply_prescribed_motion``: move handle vertices exactly, keep every triangle healthy."""

from __future__ import annotations

from meshopt_toolkit.bounds import MAX_STEPS
from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.pipeline.filter import Filter, register
from meshopt_toolkit.pipeline.params import FloatParam, IntParam, PathParam, StringParam


@register
class PrescribedMotion(Filter):
    """Move chosen vertices of the current planar mesh exactly to their targets; the other
    vertices follow along a path of the per-triangle distortion metric, so no triangle
    inverts (``mt.move``, ``meshopt move``).

    Give either ``targets`` (CSV rows ``index,x,y`` or a ``.npy`` k × 3 array; ``{stem}`` is
    replaced by the input file's stem) or ``map`` (``"X_EXPR; Y_EXPR"``: the new position of
    each boundary vertex where ``where`` holds, e.g. ``"x**2 + y**2 < 0.25"``; the other
    boundary vertices stay). The moved mesh replaces the current one. The motion is computed
    at unit size (:mod:`meshopt_toolkit.scaling`) and scaled back, like ``meshopt move``.
    """

    name = "apply_prescribed_motion"
    label = "Prescribed Motion (meshopt)"
    description = "Move handle vertices exactly to targets; the rest follows without inverting."
    parameters = (
        PathParam("targets", "", "CSV 'index,x,y' or .npy (k, 3) handle targets", label="Targets"),
        StringParam("map", "", "new boundary positions 'X_EXPR; Y_EXPR' in x, y", label="Map"),
        StringParam("where", "", "with map: which boundary vertices move, e.g. 'x < 0.5'",
                    label="Where"),
        IntParam("steps", 4, "continuation steps (split further when needed)", label="Steps",
                 min=1, max=MAX_STEPS),
        FloatParam("weight", 1.0, "w of the metric M + w² JᵀJ", label="Weight", min=0.0,
                   exclusive_min=True),
    )

    def apply(self, document, *, targets: str = "", map: str = "", where: str = "",
              steps: int = 8, weight: float = 1.0) -> dict:
        from meshopt_toolkit.motion.move import move
        from meshopt_toolkit.motion.targets import read_target_table, targets_from_map

        entry = document.current_entry
        if bool(targets) == bool(map):
            raise FilterError(f"{self.name}: give exactly one of targets and map")
        if where and not map:
            raise FilterError(f"{self.name}: where needs map")
        # the plane's coordinates at unit size; the file's blocks, tags and data kept
        wp = entry.workpiece(self.name).admissible(self.name)
        if targets:
            handles, positions = read_target_table(targets.replace("{stem}", entry.name))
        else:  # the expressions are in the mesh's units
            handles, positions = targets_from_map(wp.user_mesh, map, where or None)
        result = move(wp.mesh, handles, wp.to_unit(positions), steps=steps, weight=weight)
        entry.set_workpiece(wp.moved(result.mesh.points))
        return {**result.summary(), "unit_scale": wp.scale.factor}
