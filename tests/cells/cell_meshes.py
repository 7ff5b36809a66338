"""Small meshes of every cell kind for the tests of ``meshopt_toolkit.cells``: points and
cells of the shared grids (``conftest.grid_mesh``, ``test_tet_move.cube_tets``), the
planar one lifted onto a bump for surfaces (no file, no mesh generator)."""

from __future__ import annotations

import numpy as np
from conftest import grid_mesh
from scipy.spatial.transform import Rotation
from test_tet_move import cube_tets

from meshopt_toolkit.cells.planar import PLANAR
from meshopt_toolkit.cells.surface import SURFACE
from meshopt_toolkit.cells.tetrahedra import TETRAHEDRA


def planar(n: int = 4, jitter: float = 0.3, seed: int = 0):
    """[0, 1]² in n² squares of two counter-clockwise triangles, interior jittered."""
    mesh = grid_mesh(n, jitter, seed)
    return np.array(mesh.points), np.array(mesh.triangles)


def surface(n: int = 4, jitter: float = 0.3, seed: int = 0):
    """The planar grid lifted onto the bump z = ½·x(1 − x)·(1 + y)."""
    P, T = planar(n, jitter, seed)
    z = 0.5 * P[:, 0] * (1 - P[:, 0]) * (1 + P[:, 1])
    return np.column_stack([P, z]), T


def tets(n: int = 2, jitter: float = 0.3, seed: int = 0):
    """[0, 1]³ in n³ cubes of six positively oriented tets each (Kuhn), interior jittered."""
    return cube_tets(n, jitter, seed)


#: each kind with a mesh of it
CASES = {"planar": (PLANAR, planar), "surface": (SURFACE, surface), "tets": (TETRAHEDRA, tets)}


def rotation(kind, seed: int) -> np.ndarray:
    """A random proper rotation of the kind's points (d × d)."""
    if kind.point_dimension == 3:
        return Rotation.random(random_state=seed).as_matrix()
    t = np.random.default_rng(seed).uniform(0, 2 * np.pi)
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def perturbed(points: np.ndarray, seed: int, amount: float) -> np.ndarray:
    """``points`` plus a random displacement of at most ``amount`` per coordinate (the
    meshes' cells stay positive up to 0.01: the measures keep a third of their size over
    a thousand meshes and displacements)."""
    return points + amount * np.random.default_rng(seed).uniform(-1, 1, points.shape)
