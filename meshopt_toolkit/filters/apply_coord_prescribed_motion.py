"""Filter ``apply_coord_prescribed_motion``: move handle vertices exactly, keep every cell healthy."""

from __future__ import annotations

from meshopt_toolkit.bounds import MAX_STEPS
from meshopt_toolkit.errors import FilterError, OptionError
from meshopt_toolkit.pipeline.filter import MESH_KINDS, Filter, register
from meshopt_toolkit.pipeline.params import BoolParam, IntParam, PathParam, StringParam
from meshopt_toolkit.filters._shared import DISTORTION_WEIGHT

#: the messages of :func:`~meshopt_toolkit.motion.engine.handles.handles_in_space` name parameters
_OPTIONS = {"group": "group", "selection": "selection", "map": "map", "targets": "targets",
            "where": "where"}


@register
class PrescribedMotion(Filter):
    """Move chosen vertices of the current mesh exactly to their targets; the other
    vertices follow along a path of the per-cell distortion metric, so no cell inverts
    (``mt.move``, ``meshopt move``). The mesh is planar triangles, a triangle surface in
    3D or a tet mesh.

    Give either ``targets`` (CSV rows ``index,x,y`` or a ``.npy`` k × 3 array; rows
    ``index,x,y,z`` or k × 4 in 3D; ``{stem}`` is replaced by the input file's stem; the
    boundary vertices it does not list stay unless ``free_boundary``) or ``map``
    (``"X_EXPR; Y_EXPR"``, in 3D ``"X_EXPR; Y_EXPR; Z_EXPR"`` in ``x, y, z``: the new
    position of each boundary vertex (a surface: each vertex), or with ``group`` of each
    node of that physical group, or with ``selection`` of each vertex whose point datum
    or vertex attribute of that name is nonzero (a ``.ply`` vertex property such as
    MeshLab's ``quality``, or ``selected`` after a MeshLab selection step), where
    ``where`` holds, e.g. ``"x**2 + y**2 < 0.25"``; the other boundary vertices stay).
    The moved mesh replaces the current one with every block, group and datum of its
    file. The mesh goes to ``mt.move`` at the file's scale, as with ``meshopt move``
    (``mt.move`` works at unit size itself, :mod:`meshopt_toolkit.scaling`).
    """

    name = "apply_coord_prescribed_motion"
    label = "Prescribed Motion (meshopt)"
    #: the former name, still accepted in saved pipelines
    aliases = ("apply_prescribed_motion",)
    description = "Move handle vertices exactly to targets; the rest follows without inverting."
    kinds = MESH_KINDS
    parameters = (
        PathParam("targets", "", "CSV 'index,x,y' ('index,x,y,z' in 3D) or .npy (k, 3|4) "
                  "handle targets", label="Targets"),
        StringParam("map", "", "new positions 'X_EXPR; Y_EXPR' in x, y "
                    "('X_EXPR; Y_EXPR; Z_EXPR' in 3D)", label="Map"),
        StringParam("where", "", "with map: which candidate vertices move, e.g. 'x < 0.5'",
                    label="Where"),
        StringParam("group", "", "with map: move this physical group's nodes (name or number)",
                    label="Group"),
        StringParam("selection", "", "with map: move the vertices whose point datum or "
                    "vertex attribute of this name is nonzero", label="Selection"),
        BoolParam("free_boundary", False, "with targets: unlisted boundary vertices move freely",
                  label="Free boundary"),
        IntParam("steps", 4, "continuation steps (split further when needed)", label="Steps",
                 min=1, max=MAX_STEPS),
        DISTORTION_WEIGHT,
    )

    def apply(self, document, *, targets: str = "", map: str = "", where: str = "",
              group: str = "", selection: str = "", free_boundary: bool = False,
              steps: int = 4, weight: float = 1.0) -> dict:
        from meshopt_toolkit.motion.engine.handles import handles_in_space
        from meshopt_toolkit.motion.move import move
        from meshopt_toolkit.motion.moved_file import MovedFile

        entry = document.current_entry
        if free_boundary and not targets:
            raise FilterError(f"{self.name}: free_boundary is for targets")
        given = {"targets": targets.replace("{stem}", entry.name) or None,
                 "mapping": map or None, "where": where or None, "group": group or None,
                 "selection": selection or None, "free_boundary": free_boundary,
                 "point_data": entry.point_data(), "source": entry.name,
                 "options": _OPTIONS}
        try:
            # the mesh mt.move moves (a planar one in its plane's coordinates, at the
            # file's scale) and the way back; its kind is decided there
            moving = MovedFile.of_mesh(
                entry.mesh, lambda: entry.workpiece(self.name, required=False), self.name)
            handles, positions = handles_in_space(moving.mesh, **given)
        except OptionError as exc:
            raise FilterError(f"{self.name}: {exc}") from None
        result = move(moving.mesh, handles, positions, steps=steps, weight=weight)
        moved = moving.moved(result.mesh)
        # same vertices and cells: attributes and the file's blocks, groups and data kept
        entry.replace_mesh(moved.file_mesh)
        if moved.workpiece is not None:
            entry.source_workpiece = moved.workpiece
        return moving.summary(result, handles)
