"""Tetrahedral benchmark meshes from gmsh (OpenCASCADE kernel) and the prescribed motions
of their obstacle surfaces.

Two domains: the box ``[-1, 1]³`` with a spherical hole of radius 0.35 at the origin, and
the channel ``[0, 3] × [0, 1] × [0, 1]`` with a sphere of radius 0.15 at ``(1, 0.5, 0.5)``.
Each has the physical surface groups ``outer`` and ``obstacle``; every boundary vertex is a
handle, the outer ones stay, the obstacle's follow the motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from meshopt_toolkit.gmsh_session import gmsh_session
from meshopt_toolkit.kernels.tetrahedra import signed_volumes as tet_signed_volumes

BOX_RADIUS = 0.35
CHANNEL_CENTER = np.array([1.0, 0.5, 0.5])
CHANNEL_RADIUS = 0.15


@dataclass
class TetDomain:
    """A tet mesh with its boundary split into the fixed outer part and the obstacle."""

    name: str
    points: np.ndarray  # (N, 3)
    tets: np.ndarray  # (C, 4), positively oriented
    outer: np.ndarray  # vertex indices on the outer boundary
    obstacle: np.ndarray  # vertex indices on the obstacle surface
    center: np.ndarray  # obstacle centre

    @property
    def handles(self) -> np.ndarray:
        return np.concatenate([self.outer, self.obstacle])


def generate_tets(gmsh, size: float, surface_groups) -> tuple:
    """Mesh the open gmsh session's model with edge length ``size`` throughout: the points
    some tet uses, the tets (positively oriented) and, for each 2D physical group tag of
    ``surface_groups``, the indices of its nodes among those points."""
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.Optimize", 1)
    gmsh.model.mesh.generate(3)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(tags.max()) + 1, -1)
    index[tags.astype(int)] = np.arange(len(tags))
    points = coords.reshape(-1, 3)
    _, conn = gmsh.model.mesh.getElementsByType(4)
    tets = index[conn.astype(int)].reshape(-1, 4)
    groups = [index[gmsh.model.mesh.getNodesForPhysicalGroup(2, tag)[0].astype(int)]
              for tag in surface_groups]
    used = np.unique(tets)  # drop nodes no tet uses (geometry points)
    remap = np.full(len(points), -1)
    remap[used] = np.arange(len(used))
    points, tets = np.ascontiguousarray(points[used]), remap[tets]
    flip = tet_signed_volumes(points, tets) < 0
    tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    return points, tets, [np.unique(remap[g]) for g in groups]


def _mesh(outer_box, center, radius, size: float, name: str) -> TetDomain:
    """Mesh the box ``outer_box = (x0, y0, z0, dx, dy, dz)`` minus the ball with gmsh
    (edge length ``size`` throughout); the obstacle's faces are those inside the ball's
    bounding box."""
    center = np.asarray(center, float)
    with gmsh_session() as gmsh:
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add(name)
        occ = gmsh.model.occ
        box = occ.addBox(*outer_box)
        ball = occ.addSphere(*center, radius)
        volume, _ = occ.cut([(3, box)], [(3, ball)])
        occ.synchronize()
        faces = [t for _, t in gmsh.model.getBoundary(volume, oriented=False)]
        lo, hi = center - 1.01 * radius, center + 1.01 * radius

        def on_ball(tag):
            bb = np.array(gmsh.model.getBoundingBox(2, tag))
            return bool(np.all(bb[:3] >= lo) and np.all(bb[3:] <= hi))

        gmsh.model.addPhysicalGroup(3, [t for _, t in volume], 1, name="domain")
        gmsh.model.addPhysicalGroup(2, [t for t in faces if not on_ball(t)], 2, name="outer")
        gmsh.model.addPhysicalGroup(2, [t for t in faces if on_ball(t)], 3, name="obstacle")
        points, tets, (outer, obstacle) = generate_tets(gmsh, size, (2, 3))
    outer = np.setdiff1d(outer, obstacle)
    return TetDomain(name, points, tets, outer, obstacle, center)


def box_with_ball(size: float = 0.11) -> TetDomain:
    """``[-1, 1]³`` minus the ball of radius 0.35 at the origin, edge length ``size``."""
    return _mesh((-1, -1, -1, 2, 2, 2), np.zeros(3), BOX_RADIUS, size, "box_with_ball")


def channel_with_ball(size: float = 0.05) -> TetDomain:
    """``[0, 3] × [0, 1]²`` minus the ball of radius 0.15 at (1, 0.5, 0.5)."""
    return _mesh((0, 0, 0, 3, 1, 1), CHANNEL_CENTER, CHANNEL_RADIUS, size,
                 "channel_with_ball")


def obstacle_path(domain: TetDomain, *, turn: float = 0.0, shift=(0.0, 0.0, 0.0),
                  scale: float = 1.0):
    """Handles (outer, then obstacle vertices) and their path ``t ↦ (H, 3)``: the outer
    boundary stays, the obstacle turns by ``t · turn`` degrees about the z axis through its
    centre, scales by ``1 + t (scale − 1)`` about it and moves by ``t · shift``."""
    handles = domain.handles
    rest = domain.points[handles]
    moving = np.zeros(len(handles), bool)
    moving[len(domain.outer):] = True
    rel = rest[moving] - domain.center
    shift = np.asarray(shift, float)

    def path(t: float) -> np.ndarray:
        a = np.radians(turn) * t
        c, s = np.cos(a), np.sin(a)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        out = rest.copy()
        out[moving] = domain.center + t * shift + (1 + t * (scale - 1)) * rel @ R.T
        return out

    return handles, path
