"""Triangle surfaces in 3D: :class:`SurfaceMesh`.

An immutable value like :class:`~meshopt_toolkit.mesh.PlanarMesh`: points ``(N, 3)``,
triangles ``(T, 3)``, physical tags as :class:`~meshopt_toolkit.mesh.TriangleMesh` keeps
them (it holds one for the readable checks and the edge tables). Open or closed; the
topology is cached: edge- and vertex-manifold tests, orientability and consistent
orientation, boundary loops, Euler characteristic and genus per connected component.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError
from ..kernels.surface import area_vectors, aspect_ratios, degenerate_triangles, pad3
from ..orientation import (component_labels, half_edge_pairs, orient_components,
                           orientation_labels)
from .core import TriangleMesh
from .topology import _frozen
from .value import MeshValue

__all__ = ["SurfaceMesh"]

#: indices listed in a message before "..."
SHOWN = 5


def listed(indices, shown: int = SHOWN) -> str:
    """``"3, 8, 12"`` or ``"3, 8, 12, 15, 20, ..."``: the first indices of a problem."""
    idx = [str(int(i)) for i in np.asarray(indices).reshape(-1)[:shown]]
    return ", ".join(idx) + (", ..." if np.size(indices) > shown else "")


class SurfaceMesh(MeshValue):
    """A triangle surface in 3D ``SurfaceMesh(points, triangles)``.

    Parameters
    ----------
    points : (N, 3) array_like of float
        ``(N, 2)`` input gets z = 0.
    triangles : (T, 3) array_like of int
    triangle_tags, lines, line_tags, tag_names, source
        As for :class:`~meshopt_toolkit.mesh.TriangleMesh`.

    Raises
    ------
    InvalidMeshError
        The readable checks of :class:`~meshopt_toolkit.mesh.TriangleMesh` fail.
    """

    _cells, _count = "triangles", "n_triangles"  # repr and == (MeshValue)

    def __init__(self, points, triangles, *, triangle_tags=None, lines=None, line_tags=None,
                 tag_names: dict | None = None, source: str | None = None) -> None:
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim == 2 and pts.shape[1] == 2:
            pts = pad3(pts)
        if pts.ndim != 2 or pts.shape[1] != 3:
            where = f"{source}: " if source else ""
            raise InvalidMeshError(f"{where}surface points must have shape (N, 3), got "
                                   f"{pts.shape}")
        self._mesh = TriangleMesh(pts, triangles, triangle_tags=triangle_tags, lines=lines,
                                  line_tags=line_tags, tag_names=tag_names, source=source)

    @classmethod
    def from_triangle_mesh(cls, mesh: TriangleMesh) -> SurfaceMesh:
        """The same triangles and tags as a surface (2D points get z = 0)."""
        return cls(mesh.points, mesh.triangles, triangle_tags=mesh.triangle_tags,
                   lines=mesh.lines, line_tags=mesh.line_tags, tag_names=mesh.tag_names,
                   source=mesh.source)

    def with_points(self, points) -> SurfaceMesh:
        """This surface with other points ``(N, 3)``: the same triangles, lines, tags and
        names."""
        return SurfaceMesh(points, self.triangles, triangle_tags=self.triangle_tags,
                           lines=self.lines, line_tags=self.line_tags,
                           tag_names=self.tag_names, source=self.source)

    def as_triangle_mesh(self) -> TriangleMesh:
        """This surface as a readable :class:`TriangleMesh` (what ``io.save`` writes)."""
        return self._mesh

    def tagged_vertices(self, tag: int | str) -> IntArray:
        """Sorted vertices of the line elements and triangles carrying a physical tag or
        name, as :meth:`TriangleMesh.tagged_vertices`."""
        return self._mesh.tagged_vertices(tag)

    # -- plain data -----------------------------------------------------------------
    points = property(lambda self: self._mesh.points, doc="Read-only ``(N, 3)`` float64.")
    triangles = property(lambda self: self._mesh.triangles, doc="Read-only ``(T, 3)`` int64.")
    triangle_tags = property(lambda self: self._mesh.triangle_tags, doc="``(T,)`` or None.")
    lines = property(lambda self: self._mesh.lines, doc="Tagged lines ``(L, 2)`` or None.")
    line_tags = property(lambda self: self._mesh.line_tags, doc="``(L,)`` or None.")
    tag_names = property(lambda self: self._mesh.tag_names, doc="``{name: (tag, dim)}``.")
    source = property(lambda self: self._mesh.source, doc="The file it was read from.")
    n_vertices = property(lambda self: self._mesh.n_vertices)
    n_triangles = property(lambda self: self._mesh.n_triangles)
    edges = property(lambda self: self._mesh.edges, doc="Unique edges ``(E, 2)``, i < j.")
    edge_triangle_counts = property(lambda self: self._mesh.edge_triangle_counts)
    boundary_edges = property(lambda self: self._mesh.boundary_edges,
                              doc="Edges of one triangle ``(B, 2)``, directed as in it.")

    # -- topology (cached) ----------------------------------------------------------
    @cached_property
    def _pairs(self) -> tuple[IntArray, IntArray, IntArray]:
        """``(h1, h2, same)`` of :func:`~meshopt_toolkit.orientation.half_edge_pairs`."""
        return tuple(_frozen(a) for a in half_edge_pairs(self.triangles, self.n_vertices))

    @cached_property
    def non_manifold_edges(self) -> IntArray:
        """Edges in three or more triangles ``(K, 2)``."""
        return _frozen(self.edges[self.edge_triangle_counts > 2])

    @property
    def is_edge_manifold(self) -> bool:
        """Every edge is in one or two triangles."""
        return not len(self.non_manifold_edges)

    @cached_property
    def vertex_fans(self) -> IntArray:
        """Number of fans (triangles around a vertex connected through its edges) per
        vertex ``(N,)``; 0 for unused vertices, 1 for a manifold vertex."""
        tri = self.triangles
        nt = len(tri)
        h1, h2, same = self._pairs
        t1, l1 = h1 % nt, h1 // nt
        t2, l2 = h2 % nt, h2 // nt
        # corner j T + t is local vertex j of triangle t; each shared edge joins the corners
        # of its two ends in its two triangles
        a1, b1 = ((l1 + 1) % 3) * nt + t1, ((l1 + 2) % 3) * nt + t1
        a2 = np.where(same, (l2 + 1) % 3, (l2 + 2) % 3) * nt + t2
        b2 = np.where(same, (l2 + 2) % 3, (l2 + 1) % 3) * nt + t2
        label = component_labels(3 * nt, np.concatenate([a1, b1]), np.concatenate([a2, b2]))
        vertex = np.ascontiguousarray(tri.T).ravel()
        fans = np.unique(vertex * np.int64(3 * nt) + label)
        return _frozen(np.bincount(fans // (3 * nt), minlength=self.n_vertices))

    @cached_property
    def non_manifold_vertices(self) -> IntArray:
        """Vertices whose triangles form two or more fans, sorted."""
        return _frozen(np.flatnonzero(self.vertex_fans > 1))

    @property
    def is_vertex_manifold(self) -> bool:
        """Every used vertex has one fan of triangles."""
        return not len(self.non_manifold_vertices)

    @property
    def is_manifold(self) -> bool:
        """Edge- and vertex-manifold."""
        return self.is_edge_manifold and self.is_vertex_manifold

    @property
    def is_closed(self) -> bool:
        """No boundary edge."""
        return not len(self.boundary_edges)

    @cached_property
    def components(self) -> IntArray:
        """Connected component (0, 1, ...) of each triangle ``(T,)``, through shared
        vertices, numbered by their smallest vertex."""
        e = self.edges
        label = component_labels(self.n_vertices, e[:, 0], e[:, 1])
        _, comp = np.unique(label[self.triangles[:, 0]], return_inverse=True)
        return _frozen(comp.reshape(-1))

    @property
    def n_components(self) -> int:
        return int(self.components.max()) + 1

    @cached_property
    def _vertex_components(self) -> IntArray:
        """Component of each vertex ``(N,)``, -1 for unused vertices."""
        out = np.full(self.n_vertices, -1, np.int64)
        out[self.triangles.ravel()] = np.repeat(self.components, 3)
        return out

    @cached_property
    def boundary_loop_labels(self) -> IntArray:
        """Boundary loop (0, 1, ...) of each boundary edge ``(B,)``: connected components
        of the boundary edges."""
        b = self.boundary_edges
        if not len(b):
            return _frozen(np.zeros(0, np.int64))
        label = component_labels(self.n_vertices, b[:, 0], b[:, 1])
        _, loop = np.unique(label[b[:, 0]], return_inverse=True)
        return _frozen(loop.reshape(-1))

    @property
    def n_boundary_loops(self) -> int:
        return int(self.boundary_loop_labels.max()) + 1 if len(self.boundary_loop_labels) else 0

    @cached_property
    def _orientation(self) -> tuple[IntArray, bool]:
        """Per component: orientable or not (the parity constraints of its shared edges,
        :func:`~meshopt_toolkit.orientation.orientation_labels`)."""
        nt = self.n_triangles
        h1, h2, same = self._pairs
        label = orientation_labels(nt, h1 % nt, h2 % nt, same)
        bad = label[:nt] == label[nt:]
        bad_comp = np.bincount(self.components, weights=bad, minlength=self.n_components) > 0
        return _frozen(~bad_comp), bool(not same.any())

    @property
    def orientable_components(self) -> IntArray:
        """Whether each component is orientable ``(C,)`` (across its two-triangle edges)."""
        return self._orientation[0]

    @property
    def is_orientable(self) -> bool:
        return bool(self.orientable_components.all())

    @property
    def is_oriented(self) -> bool:
        """Consistently oriented: every two-triangle edge is used once in each direction."""
        return self._orientation[1]

    @cached_property
    def euler_characteristics(self) -> IntArray:
        """``χ = V − E + F`` of each component ``(C,)`` (unused vertices not counted)."""
        nc = self.n_components
        vc = self._vertex_components
        v = np.bincount(vc[vc >= 0], minlength=nc)
        e = np.bincount(vc[self.edges[:, 0]], minlength=nc)
        f = np.bincount(self.components, minlength=nc)
        return _frozen(v - e + f)

    @cached_property
    def boundary_loops_per_component(self) -> IntArray:
        """Number of boundary loops of each component ``(C,)``."""
        out = np.zeros(self.n_components, np.int64)
        if len(self.boundary_edges):
            comp = self._vertex_components[self.boundary_edges[:, 0]]
            loops = np.unique(np.stack([comp, self.boundary_loop_labels]), axis=1)
            np.add.at(out, loops[0], 1)
        return _frozen(out)

    @property
    def genera(self) -> list[int | None]:
        """Genus ``g = (2 − χ − b) / 2`` of each component (b boundary loops); None for a
        component that is not an orientable manifold (the formula does not apply)."""
        ok = self.orientable_components & self.is_manifold
        chi, b = self.euler_characteristics, self.boundary_loops_per_component
        return [int((2 - c - n) // 2) if good else None for c, n, good in zip(chi, b, ok)]

    @cached_property
    def degenerate_triangles(self) -> IntArray:
        """Triangles with a repeated vertex or (numerically) zero area, sorted."""
        return _frozen(degenerate_triangles(self.points, self.triangles))

    # -- geometry -------------------------------------------------------------------
    def aspect_ratios(self) -> FloatArray:
        """Aspect ratio 2r/R of every triangle ``(T,)``."""
        return aspect_ratios(self.points, self.triangles)

    def enclosed_volume(self) -> float:
        """Signed volume enclosed by a closed surface, ``Σ q0 · (q1 × q2) / 6``: positive
        when consistently oriented outward. Meaningful for closed oriented surfaces."""
        p = self.points[self.triangles[:, 0]]
        return float(np.einsum("tk,tk->", p, area_vectors(self.points, self.triangles))) / 6

    def consistently_oriented(self) -> SurfaceMesh:
        """The same surface with each orientable component oriented consistently (the
        majority orientation of a component is kept)."""
        tri, n, _ = orient_components(self.triangles, self.n_vertices)
        if not n:
            return self
        return SurfaceMesh(self.points, tri, triangle_tags=self.triangle_tags,
                           lines=self.lines, line_tags=self.line_tags,
                           tag_names=self.tag_names, source=self.source)

    # -- checks ---------------------------------------------------------------------
    @property
    def problems(self) -> list[str]:
        """One line per problem: non-manifold edges or vertices, non-orientable components,
        inconsistent orientation, degenerate triangles. Empty for a valid surface."""
        out = []
        bad = self.non_manifold_edges
        if len(bad):
            out.append(f"{len(bad)} edges in more than two triangles (first: "
                       f"({bad[0, 0]}, {bad[0, 1]}))")
        if len(self.non_manifold_vertices):
            out.append(f"{len(self.non_manifold_vertices)} non-manifold vertices (two or more "
                       f"fans of triangles): {listed(self.non_manifold_vertices)}")
        if not self.is_orientable:
            out.append(f"{int((~self.orientable_components).sum())} components are not "
                       "orientable")
        elif not self.is_oriented:
            out.append("triangles are not consistently oriented (neighbours use a shared "
                       "edge in the same direction)")
        if len(self.degenerate_triangles):
            out.append(f"{len(self.degenerate_triangles)} degenerate triangles: "
                       f"{listed(self.degenerate_triangles)}")
        return out

    def require_valid(self) -> SurfaceMesh:
        """Return self, or raise :class:`InvalidMeshError` with the first problem."""
        problems = self.problems
        if problems:
            where = f"{self.source}: " if self.source else ""
            raise InvalidMeshError(f"{where}{problems[0]}")
        return self
