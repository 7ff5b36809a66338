"""Boundary data of the Poisson problem by physical group: Dirichlet values and Neumann fluxes.

A *group* is a gmsh physical group of line elements, given by name or number (a string of
digits is a number). Dirichlet data ``y = g_D`` (a constant per group) is imposed at the
group's vertices; Neumann data ``∂y/∂n = g_N`` (a constant per group) adds the load
``b_a += g_N |e|/2`` for each end ``a`` of each of the group's edges ``e``. Unless a group
says otherwise, ``y = 0`` holds on every boundary vertex that is not an interior point of
a Neumann part (a vertex shared by a Neumann and a Dirichlet edge is a Dirichlet vertex).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError, MeshoptError
from ..mesh.kinds import is_tets
from ..mesh.topology import physical_tag

__all__ = ["BoundaryData", "group_edges", "group_facets", "group_key", "neumann_load",
           "neumann_shape_derivative"]


def group_key(group) -> int | str:
    """A group as :meth:`PlanarMesh.tagged_vertices` takes it: a string of digits is a
    physical number, any other string a physical name."""
    if isinstance(group, str) and group.strip().isdigit():
        return int(group)
    if isinstance(group, (int, np.integer)) and not isinstance(group, bool):
        return int(group)
    if isinstance(group, str) and group:
        return group
    raise InvalidMeshError(f"a physical group is a name or a number, not {group!r}")


def group_edges(mesh, group) -> IntArray:
    """The line elements ``(E, 2)`` of physical group ``group`` (name or number)."""
    return _group_cells(mesh, group, mesh.lines, mesh.line_tags, "line element")


def group_facets(mesh, group) -> IntArray:
    """The boundary facets of a physical group: its line elements ``(E, 2)`` on a planar
    mesh, its triangles ``(F, 3)`` on a tet mesh."""
    if not is_tets(mesh):
        return group_edges(mesh, group)
    return _group_cells(mesh, group, mesh.triangles, mesh.triangle_tags, "triangle")


def _group_cells(mesh, group, cells, tags, what: str) -> IntArray:
    """The ``cells`` whose ``tags`` are the number of ``group``; none is an error naming
    ``what`` they are."""
    key = physical_tag(group_key(group), mesh.tag_names)[0]
    if cells is None or not np.any(tags == key):
        raise InvalidMeshError(f"no {what} carries physical group {group!r}")
    return np.asarray(cells[tags == key], dtype=np.int64)


def neumann_load(Q: FloatArray, edges: IntArray, g: FloatArray, n: int) -> FloatArray:
    """``b_a = Σ_{e ∋ a} g_e |e| / 2`` over the Neumann edges ``(E, 2)``; returns ``(n,)``."""
    length = np.linalg.norm(Q[edges[:, 1]] - Q[edges[:, 0]], axis=1)
    w = 0.5 * g * length
    return np.bincount(edges.ravel(), weights=np.repeat(w, 2), minlength=n)


def neumann_shape_derivative(Q: FloatArray, edges: IntArray, g: FloatArray,
                             p: FloatArray) -> FloatArray:
    """``∂_Q (pᵀ b_N)`` for :func:`neumann_load`: ``Σ_e g_e (p_a + p_b)/2 · ∂|e|/∂Q`` with
    ``∂|e|/∂q_b = (q_b − q_a)/|e| = −∂|e|/∂q_a``. Returns ``(N, 2)``."""
    t = Q[edges[:, 1]] - Q[edges[:, 0]]
    length = np.linalg.norm(t, axis=1)
    c = (0.5 * g * (p[edges[:, 0]] + p[edges[:, 1]]) / length)[:, None] * t
    n = len(Q)
    out = np.zeros((n, 2))
    for k in (0, 1):
        out[:, k] = (np.bincount(edges[:, 1], weights=c[:, k], minlength=n)
                     - np.bincount(edges[:, 0], weights=c[:, k], minlength=n))
    return out


@dataclass(frozen=True)
class BoundaryData:
    """Resolved boundary conditions on one mesh.

    Attributes
    ----------
    dirichlet : (D,) sorted Dirichlet vertices
    lift : (N,) the Dirichlet values at their vertices, 0 elsewhere
    neumann_edges : (E, 2) Neumann edges
    neumann_values : (E,) ``g_N`` per Neumann edge
    """

    dirichlet: IntArray
    lift: FloatArray
    neumann_edges: IntArray
    neumann_values: FloatArray

    @classmethod
    def of(cls, mesh, dirichlet: Mapping | None = None,
           neumann: Mapping | None = None) -> BoundaryData:
        """Resolve ``{group: value}`` maps on ``mesh`` (see the module docstring)."""
        n = mesh.n_vertices
        e_list, g_list = [np.zeros((0, 2), np.int64)], [np.zeros(0)]
        for group, value in (neumann or {}).items():
            e = group_edges(mesh, group)
            e_list.append(e)
            g_list.append(np.full(len(e), _finite(value, group, "Neumann")))
        edges, g = np.concatenate(e_list), np.concatenate(g_list)
        # y = 0 on the boundary vertices of the non-Neumann boundary edges
        be = np.sort(mesh.boundary_edges, axis=1)
        if len(edges):
            ne = {tuple(x) for x in np.sort(edges, axis=1).tolist()}
            keep = np.array([tuple(x) not in ne for x in be.tolist()], dtype=bool)
            be = be[keep]
        lift = np.zeros(n)
        nodes = [np.unique(be)]
        for group, value in (dirichlet or {}).items():
            v = np.unique(group_edges(mesh, group))
            lift[v] = _finite(value, group, "Dirichlet")
            nodes.append(v)
        dirichlet_nodes = np.unique(np.concatenate(nodes)).astype(np.int64)
        if dirichlet_nodes.size == 0:
            raise MeshoptError("the Poisson problem needs a Dirichlet part: every boundary "
                               "group is Neumann (the solution is then not unique)")
        return cls(dirichlet_nodes, lift, edges, g)


def _finite(value, group, kind: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise MeshoptError(f"{kind} value of group {group!r} is not a number: {value!r}") from None
    if not np.isfinite(v):
        raise MeshoptError(f"{kind} value of group {group!r} is not finite: {value!r}")
    return v
