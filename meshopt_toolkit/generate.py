"""Meshes and motions for the test and benchmark cases (gmsh for the meshes).

The annulus (inner circle turned) and the channel with a cylinder (cylinder pushed towards
a wall) are the standard cases of ``benchmarks/bench_move.py`` and the README; ``twisted``
and ``log_twist`` make the morph targets.
"""

from __future__ import annotations

import numpy as np

from ._typing import FloatArray
from .gmsh_session import gmsh_session
from .mesh import PlanarMesh


def _mesh_current_model(gmsh, size: float) -> PlanarMesh:
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.model.occ.synchronize()
    gmsh.model.mesh.generate(2)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    _, _, nodes = gmsh.model.mesh.getElements(2)
    tri = index[np.concatenate(nodes).astype(np.int64).reshape(-1, 3)]
    points = coords.reshape(-1, 3)[:, :2]
    used = np.unique(tri)
    remap = np.full(len(points), -1)
    remap[used] = np.arange(len(used))
    points, tri = points[used], remap[tri]
    e1 = points[tri[:, 1]] - points[tri[:, 0]]
    e2 = points[tri[:, 2]] - points[tri[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    tri[cw] = tri[cw][:, ::-1]
    return PlanarMesh(points, tri)


def annulus(size: float = 0.05, inner: float = 0.3, outer: float = 1.0) -> PlanarMesh:
    """Unstructured annulus ``inner ≤ r ≤ outer`` with element size ``size`` (0.05: ~2.7k
    triangles)."""
    with gmsh_session(deterministic=True) as gmsh:
        o = gmsh.model.occ.addDisk(0, 0, 0, outer, outer)
        i = gmsh.model.occ.addDisk(0, 0, 0, inner, inner)
        gmsh.model.occ.cut([(2, o)], [(2, i)])
        return _mesh_current_model(gmsh, size)


def channel_with_cylinder(size: float = 0.05, radius: float = 0.15,
                          center: tuple[float, float] = (1.0, 0.5)) -> PlanarMesh:
    """Channel ``[0, 3] × [0, 1]`` with a circular hole (the cylinder)."""
    with gmsh_session(deterministic=True) as gmsh:
        r = gmsh.model.occ.addRectangle(0, 0, 0, 3, 1)
        c = gmsh.model.occ.addDisk(center[0], center[1], 0, radius, radius)
        gmsh.model.occ.cut([(2, r)], [(2, c)])
        return _mesh_current_model(gmsh, size)


def rotate_inner_boundary(mesh: PlanarMesh, degrees: float, split_radius: float = 0.5
                          ) -> tuple[np.ndarray, FloatArray]:
    """Handles (all boundary vertices) and targets for the annulus case: the boundary
    vertices within ``split_radius`` of the origin turn by ``degrees``, the rest stay."""
    b = np.unique(mesh.boundary_edges)
    P = mesh.points[b]
    th = np.radians(degrees)
    rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    inner = np.hypot(P[:, 0], P[:, 1]) < split_radius
    targets = P.copy()
    targets[inner] = P[inner] @ rot.T
    return b, targets


def shift_hole(mesh: PlanarMesh, shift: tuple[float, float], center: tuple[float, float] = (1.0, 0.5),
               radius: float = 0.15) -> tuple[np.ndarray, FloatArray]:
    """Handles (all boundary vertices) and targets for the channel case: the hole's
    boundary moves by ``shift``, the walls stay."""
    b = np.unique(mesh.boundary_edges)
    P = mesh.points[b]
    on_hole = np.hypot(P[:, 0] - center[0], P[:, 1] - center[1]) < 1.5 * radius
    targets = P.copy()
    targets[on_hole] += np.asarray(shift, float)
    return b, targets


def log_twist(mesh: PlanarMesh, degrees: float, inner: float = 0.3, outer: float = 1.0) -> PlanarMesh:
    """The annulus with its inner circle turned by ``degrees`` and the angle interpolated
    in log-radius (uniform shear): a morph target."""
    P = mesh.points
    r = np.hypot(P[:, 0], P[:, 1])
    s = np.clip(np.log(r / outer) / np.log(inner / outer), 0.0, 1.0)
    th = np.arctan2(P[:, 1], P[:, 0]) + np.radians(degrees) * s
    return mesh.with_points(np.column_stack([r * np.cos(th), r * np.sin(th)]))


def twisted(mesh: PlanarMesh, degrees: float = 225.0, power: float = 2.0,
            centre=(0.0, 0.0)) -> PlanarMesh:
    """The mesh with its interior twisted about ``centre``, boundary fixed.

    Each vertex at distance r from the centre turns by ``θ(r) = degrees·(1 − r)^power``
    (r ≥ 1 does not turn); boundary vertices stay put. On a unit disc this makes a target
    that linear interpolation cannot reach without inverting triangles when ``degrees`` is
    large (≈ 225°). The result is not checked for admissibility.
    """
    P = mesh.points - np.asarray(centre, float)
    r = np.linalg.norm(P, axis=1)
    th = np.deg2rad(degrees) * np.clip(1.0 - r, 0.0, None) ** power
    c, s = np.cos(th), np.sin(th)
    Q = np.stack([c * P[:, 0] - s * P[:, 1], s * P[:, 0] + c * P[:, 1]], 1)
    Q += np.asarray(centre, float)
    b = mesh.boundary_vertices
    Q[b] = mesh.points[b]
    return mesh.with_points(Q)
