"""Filter ``meshing_uniform_refinement``: every triangle into four at its edge midpoints."""

from __future__ import annotations

import numpy as np

from meshopt_toolkit.pipeline.filter import PLANAR, SURFACE, Filter, register
from meshopt_toolkit.pipeline.params import IntParam


def _refine_attributes(entry, old_mesh) -> None:
    """Carry attributes across one refinement.

    Face attributes are inherited by the 4 children (``PlanarMesh.refine`` puts the
    children of triangle k at rows 4k..4k+3); vertex attributes are interpolated linearly
    at the new edge midpoints (appended in edge order).
    """
    e = old_mesh.edges
    va = {}
    for name, a in entry.vertex_attributes.items():
        a = np.asarray(a)
        if name == "selected":
            mid = a[e[:, 0]] & a[e[:, 1]]
        else:
            mid = 0.5 * (a[e[:, 0]] + a[e[:, 1]])
        va[name] = np.concatenate([a, mid.astype(a.dtype)])
    fa = {name: np.repeat(np.asarray(a), 4, axis=0) for name, a in entry.face_attributes.items()}
    entry.vertex_attributes = va
    entry.face_attributes = fa


@register
class UniformRefinement(Filter):
    """Uniform refinement ``PlanarMesh.refine`` repeated ``iterations`` times.

    Planar meshes (on any plane) keep their vertices (new ones appended) and everything
    their file holds: line elements are split with their edges (both halves keep the
    tags), cell data is copied to the children, float point data interpolated at the new
    midpoints (other point data is dropped with a warning), vertex cells and physical
    names kept (:meth:`meshopt_toolkit.io.workpiece.Workpiece.refined`). The shape
    quality of every child equals its parent's. A 3D surface is routed to pymeshlab's
    midpoint subdivision (``meshing_surface_subdivision_midpoint`` with threshold 0), where
    MeshLab decides the order of the new vertices and attributes are dropped.
    """

    name = "meshing_uniform_refinement"
    label = "Uniform Refinement (meshopt)"
    description = "Split every triangle into four at its edge midpoints (repeated N times)."
    kinds = (PLANAR, SURFACE)
    parameters = (
        IntParam("iterations", 1, "number of refinement rounds (each multiplies triangles by 4)",
                 label="Iterations", min=1, max=8),
    )

    @classmethod
    def plan(cls, document, params, stats):
        """Every round multiplies the triangles by 4 (exact for planar meshes)."""
        return None if stats is None else stats.times(4.0 ** params["iterations"])

    def apply(self, document, *, iterations: int = 1) -> dict:
        entry = document.current_entry
        before = entry.mesh.n_triangles
        wp = entry.workpiece(self.name, required=False)
        if wp is not None:
            for _ in range(iterations):
                _refine_attributes(entry, wp.mesh)
                wp = wp.refined()
            entry.set_workpiece(wp)
        else:
            self._surface(document, iterations)
        return {"n_triangles_before": int(before), "n_triangles": int(document.mesh.n_triangles),
                "n_vertices": int(document.mesh.n_vertices)}

    @staticmethod
    def _surface(document, iterations: int) -> None:
        from meshopt_toolkit.pipeline import meshlab

        ms = document.to_meshset()
        meshlab.apply(ms, "meshing_surface_subdivision_midpoint",
                      {"iterations": iterations, "threshold": {"abs": 0.0}})
        cur = document.current
        entry = document.current_entry
        entry.vertex_attributes, entry.face_attributes = {}, {}
        document.update_from_meshset(ms)
        document.current = cur
