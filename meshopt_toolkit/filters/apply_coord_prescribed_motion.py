"""Filter ``apply_coord_prescribed_motion``: move handle vertices exactly, keep every triangle healthy."""

from __future__ import annotations

from meshopt_toolkit.bounds import MAX_STEPS
from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.pipeline.filter import Filter, register
from meshopt_toolkit.pipeline.params import (BoolParam, FloatParam, IntParam, PathParam,
                                              StringParam)


@register
class PrescribedMotion(Filter):
    """Move chosen vertices of the current planar mesh exactly to their targets; the other
    vertices follow along a path of the per-triangle distortion metric, so no triangle
    inverts (``mt.move``, ``meshopt move``).

    Give either ``targets`` (CSV rows ``index,x,y`` or a ``.npy`` k × 3 array; ``{stem}`` is
    replaced by the input file's stem; the boundary vertices it does not list stay unless
    ``free_boundary``) or ``map`` (``"X_EXPR; Y_EXPR"``: the new position of each boundary
    vertex, or with ``group`` of each node of that physical group, where ``where`` holds,
    e.g. ``"x**2 + y**2 < 0.25"``; the other boundary vertices stay). The moved mesh
    replaces the current one. The motion is computed at unit size
    (:mod:`meshopt_toolkit.scaling`) and scaled back, like ``meshopt move``.
    """

    name = "apply_coord_prescribed_motion"
    label = "Prescribed Motion (meshopt)"
    #: the former name, still accepted in saved pipelines
    aliases = ("apply_prescribed_motion",)
    description = "Move handle vertices exactly to targets; the rest follows without inverting."
    parameters = (
        PathParam("targets", "", "CSV 'index,x,y' or .npy (k, 3) handle targets", label="Targets"),
        StringParam("map", "", "new boundary positions 'X_EXPR; Y_EXPR' in x, y", label="Map"),
        StringParam("where", "", "with map: which boundary vertices move, e.g. 'x < 0.5'",
                    label="Where"),
        StringParam("group", "", "with map: move this physical group's nodes (name or number)",
                    label="Group"),
        BoolParam("free_boundary", False, "with targets: unlisted boundary vertices move freely",
                  label="Free boundary"),
        IntParam("steps", 4, "continuation steps (split further when needed)", label="Steps",
                 min=1, max=MAX_STEPS),
        FloatParam("weight", 1.0, "w of the metric M + w² JᵀJ", label="Weight", min=0.0,
                   exclusive_min=True),
    )

    def apply(self, document, *, targets: str = "", map: str = "", where: str = "",
              group: str = "", free_boundary: bool = False, steps: int = 8,
              weight: float = 1.0) -> dict:
        from meshopt_toolkit.motion.move import move
        from meshopt_toolkit.motion.targets import handles_of

        entry = document.current_entry
        if bool(targets) == bool(map):
            raise FilterError(f"{self.name}: give exactly one of targets and map")
        for name, given in (("where", where), ("group", group)):
            if given and not map:
                raise FilterError(f"{self.name}: {name} needs map")
        if free_boundary and not targets:
            raise FilterError(f"{self.name}: free_boundary is for targets")
        # the plane's coordinates at unit size; the file's blocks, tags and data kept
        wp = entry.workpiece(self.name).admissible(self.name)
        # handles and targets in the mesh's units
        handles, positions = handles_of(
            wp.user_mesh, targets=targets.replace("{stem}", entry.name) or None,
            mapping=map or None, where=where or None, group=group or None,
            free_boundary=free_boundary)
        result = move(wp.mesh, handles, wp.to_unit(positions), steps=steps, weight=weight)
        entry.set_workpiece(wp.moved(result.mesh.points))
        return {**result.summary(), "unit_scale": wp.scale.factor}
