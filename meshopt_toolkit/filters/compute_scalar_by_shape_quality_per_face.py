"""Filter ``compute_scalar_by_shape_quality_per_face``: 1/ψ or 2r/R into face quality."""

from __future__ import annotations

import numpy as np

from meshopt_toolkit.kernels.triangles import aspect_ratios, inverse_shape_quality, quality_summary
from meshopt_toolkit.pipeline.filter import PLANAR, SURFACE, Filter, register
from meshopt_toolkit.pipeline.params import EnumParam

METRICS = ("inverse shape quality 1/psi", "aspect ratio 2r/R")


@register
class ShapeQualityPerFace(Filter):
    """Per-face shape quality of a planar mesh or a triangle surface in 3D, stored as
    MeshLab face quality.

    ``1/ψ = (E0² + E1² + E2²) / (4√3 A)`` (5.23), 1 for an equilateral triangle and large
    for a bad one (negative when inverted, infinite when degenerate); or the aspect ratio
    ``2r/R`` in (0, 1], 1 for equilateral (0 when degenerate). The values go into the
    face attribute ``quality`` (MeshLab's face quality, so a later MeshLab step such as
    "Select by Face Quality" sees them); the summary holds min/max/mean of the values and
    the mesh quality summary (AR (5.49), Λ (6.25), angles, areas) of a planar mesh. A
    surface in 3D has no orientation of its own: its values are those of the unsigned
    area. A tet mesh has no faces of its own and is refused.
    """

    name = "compute_scalar_by_shape_quality_per_face"
    label = "Per Face Shape Quality (meshopt)"
    description = "Shape quality 1/psi or aspect ratio 2r/R of each face into face quality, plus a summary."
    kinds = (PLANAR, SURFACE)
    parameters = (
        EnumParam("metric", METRICS[0], "1/psi (>= 1, 1 is best) or 2r/R (<= 1, 1 is best)",
                  label="Metric", choices=METRICS),
    )

    def apply(self, document, *, metric: str = METRICS[0]) -> dict:
        from meshopt_toolkit.mesh.kinds import is_tets

        entry = document.current_entry
        required = is_tets(entry.mesh)  # refused with one line
        wp = entry.workpiece(self.name, required=required)
        if wp is None:  # a surface in 3D
            return _in_space(entry, metric)
        mesh = wp.mesh  # in its plane's coordinates
        pts = mesh.points
        tri = mesh.triangles
        values = inverse_shape_quality(pts, tri) if metric == METRICS[0] else aspect_ratios(pts, tri)
        return {**_stored(entry, metric, values), **quality_summary(pts, tri).as_dict()}


def _stored(entry, metric: str, values) -> dict:
    """``values`` (one per face) into the face quality of ``entry``; their summary."""
    entry.set_face_attribute("quality", values.astype(np.float64))
    finite = values[np.isfinite(values)]
    return {"metric": metric,
            "min": float(finite.min()) if finite.size else float("nan"),
            "max": float(values.max()), "mean": float(values.mean())}


def _in_space(entry, metric: str) -> dict:
    """The values of a triangle surface in 3D (unsigned area) into face quality."""
    from meshopt_toolkit.kernels.cell_maps import surface_inverse_shape_quality
    from meshopt_toolkit.kernels.surface import aspect_ratios as surface_aspect_ratios

    pts, tri = entry.mesh.points, entry.mesh.triangles
    values = (surface_inverse_shape_quality(pts, tri) if metric == METRICS[0]
              else surface_aspect_ratios(pts, tri))
    return _stored(entry, metric, values)
