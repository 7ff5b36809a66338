"""Small meshes of every cell kind for the tests of ``meshopt_toolkit.cells``: points and
cells built here from closed-form grids (no file, no mesh generator)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from meshopt_toolkit.cells.planar import PLANAR
from meshopt_toolkit.cells.surface import SURFACE
from meshopt_toolkit.cells.tetrahedra import TETRAHEDRA


def planar(n: int = 4, jitter: float = 0.3, seed: int = 0):
    """[0, 1]² in n² squares of two counter-clockwise triangles, interior jittered."""
    x = np.linspace(0.0, 1.0, n + 1)
    P = np.stack(np.meshgrid(x, x, indexing="xy"), -1).reshape(-1, 2)
    inner = ((P > 0) & (P < 1)).all(1)
    P[inner] += jitter / n * np.random.default_rng(seed).uniform(-1, 1, (inner.sum(), 2))
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return P, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def surface(n: int = 4, jitter: float = 0.3, seed: int = 0):
    """The planar grid lifted onto the bump z = ½·x(1 − x)·(1 + y)."""
    P, T = planar(n, jitter, seed)
    z = 0.5 * P[:, 0] * (1 - P[:, 0]) * (1 + P[:, 1])
    return np.column_stack([P, z]), T


def tets(n: int = 2, jitter: float = 0.3, seed: int = 0):
    """[0, 1]³ in n³ cubes of six positively oriented tets each (Kuhn), interior jittered."""
    x = np.linspace(0.0, 1.0, n + 1)
    P = np.stack(np.meshgrid(x, x, x, indexing="ij"), -1).reshape(-1, 3)
    inner = ((P > 0) & (P < 1)).all(1)
    P[inner] += jitter / n * np.random.default_rng(seed).uniform(-1, 1, (inner.sum(), 3))
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    corner = idx[:-1, :-1, :-1].ravel()
    step = np.array([(n + 1) ** 2, n + 1, 1])
    T = []
    for perm in [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]:
        b = corner + step[perm[0]]
        c = b + step[perm[1]]
        T.append(np.stack([corner, b, c, c + step[perm[2]]], 1))
    T = np.concatenate(T)
    e = np.swapaxes(P[T][:, 1:] - P[T][:, :1], 1, 2)
    flip = np.linalg.det(e) < 0
    T[flip] = T[flip][:, [1, 0, 2, 3]]
    return P, T


#: each kind with a mesh of it
CASES = {"planar": (PLANAR, planar), "surface": (SURFACE, surface), "tets": (TETRAHEDRA, tets)}


def rotation(kind, seed: int) -> np.ndarray:
    """A random proper rotation of the kind's points (d × d)."""
    if kind.point_dimension == 3:
        return Rotation.random(random_state=seed).as_matrix()
    t = np.random.default_rng(seed).uniform(0, 2 * np.pi)
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def perturbed(points: np.ndarray, seed: int, amount: float) -> np.ndarray:
    """``points`` plus a small random displacement (relative to the unit-size meshes)."""
    return points + amount * np.random.default_rng(seed).uniform(-1, 1, points.shape)
