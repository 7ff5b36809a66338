"""Scale covariance of every operation: ``mt.move``, ``mt.morph``, ``mt.deform`` and
``mt.optimize`` of a mesh scaled by ``s`` (``2**k``, ``|k| ≤ 40``, or ``10**e``,
``|e| ≤ 12``), every length-valued input scaled alike, give the unit-size results scaled
by ``s`` to 1e-9 relative, for planar triangles, surface triangles and tetrahedra; for
``s`` a power of two the same numbers scaled, bit for bit."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_tet_move import cube_tets

import meshopt_toolkit as mt
from meshopt_toolkit import data_path
from meshopt_toolkit.io import load
from meshopt_toolkit.mesh import SurfaceMesh, TetMesh

#: the scales: powers of two and of ten (only the former are exact in floating point)
SCALES = st.one_of(st.integers(-40, 40).map(lambda k: float(np.ldexp(1.0, k))),
                   st.integers(-12, 12).map(lambda e: 10.0**e))

DISC = load(data_path("disc_25.msh")).as_planar()
RIM = DISC.boundary_vertices
TET_P, TET_T = cube_tets(2, jitter=0.4, seed=3)
TET_P = 2.0 * TET_P - 1.0
TET_RIM = np.flatnonzero((np.abs(TET_P) == 1).any(axis=1))


def _icosphere():
    """An icosphere (42 vertices) with its vertices jittered: no two triangles alike,
    so no choice among equals (the worst triangles) is left to rounding."""
    import trimesh

    m = trimesh.creation.icosphere(1)
    V = np.array(m.vertices)
    return V + 0.03 * np.random.default_rng(1).uniform(-1, 1, V.shape), np.array(m.faces)


ICO_V, ICO_F = _icosphere()
CAPS = np.flatnonzero(np.abs(ICO_V[:, 2]) > 0.6)


def _twisted(X):
    """Turned about z by 0.6 z and stretched 1.1 along z."""
    a = 0.6 * X[:, 2]
    return np.stack([X[:, 0] * np.cos(a) - X[:, 1] * np.sin(a),
                     X[:, 0] * np.sin(a) + X[:, 1] * np.cos(a), 1.1 * X[:, 2]], 1)


def _frames(result) -> np.ndarray:
    return np.array([np.asarray(f.points) for f in result.frames])


def _velocity(s: float) -> np.ndarray:
    """The rim pushed by ``s`` times a shear, the interior at rest."""
    V = np.zeros_like(DISC.points)
    V[RIM] = DISC.points[RIM] * [0.3, -0.2] * s
    return V


class _Pull:
    """``j(Q) = c·Σ_rows Q / s``: an objective of the mesh scaled by ``s`` that takes the
    same values on the scaled meshes (a pull of some vertices)."""

    def __init__(self, s: float, rows=RIM, c=(0.015, -0.01)):
        self.s, self.rows, self.c = s, rows, np.array(c)

    def value(self, Q):
        return float(np.sum(Q[self.rows] * self.c) / self.s)

    def derivative(self, Q):
        D = np.zeros_like(Q)
        D[self.rows] = self.c / self.s
        return D


#: one cube of six tets (8 vertices), its face x = 0 fixed, the face x = 1 pulled (the
#: tet optimizer's exact admissibility test of every trial step is the cost of a run)
CUBE_P, CUBE_T = cube_tets(1)
CUBE_BASE, CUBE_FACE = (np.flatnonzero(CUBE_P[:, 0] == x) for x in (0, 1))

#: each operation and kind: the operation on its inputs scaled by ``s`` (every kind an
#: operation takes: move and morph planar, surface and tet meshes, deform planar ones,
#: optimize planar and tet meshes)
OPERATIONS = {
    "move planar": lambda s: mt.move(DISC.with_points(DISC.points * s), RIM,
                                     DISC.points[RIM] * [1.3, 0.8] * s),
    "move surface": lambda s: mt.move(SurfaceMesh(ICO_V * s, ICO_F), CAPS,
                                      _twisted(ICO_V)[CAPS] * s),
    "move tets": lambda s: mt.move(TetMesh(TET_P * s, TET_T), TET_RIM,
                                   _twisted(TET_P)[TET_RIM] * s),
    "morph planar": lambda s: mt.morph(DISC.with_points(DISC.points * s),
                                       DISC.with_points(DISC.points * [1.3, 0.8] * s), 4),
    "morph planar complete": lambda s: mt.morph(
        DISC.with_points(DISC.points * s), DISC.with_points(DISC.points * [1.3, 0.8] * s), 4,
        metric="complete"),
    "morph surface": lambda s: mt.morph(SurfaceMesh(ICO_V * s, ICO_F),
                                        SurfaceMesh(ICO_V * [1.4, 1.0, 0.7] * s, ICO_F), 4),
    "morph tets": lambda s: mt.morph(TetMesh(TET_P * s, TET_T),
                                     TetMesh(TET_P * [1.3, 1.0, 0.8] * s, TET_T), 4),
    "deform planar": lambda s: mt.deform(DISC.with_points(DISC.points * s), _velocity(s),
                                         frames=3),
    "deform planar f2": lambda s: mt.deform(DISC.with_points(DISC.points * s), _velocity(s),
                                            frames=3, penalty=(1.0, 0.1, 0.0, 0.1)),
    "optimize planar": lambda s: mt.optimize(DISC.with_points(DISC.points * s), _Pull(s),
                                             max_iterations=10),
    "optimize tets": lambda s: mt.optimize(TetMesh(CUBE_P * s, CUBE_T),
                                           _Pull(s, CUBE_FACE, (-0.05, 0.02, 0.0)),
                                           fixed=CUBE_BASE, max_iterations=3),
}
#: those whose test takes about 5 s or more (a unit run of over ~0.6 s)
SLOW = {"move surface", "move tets", "morph planar complete", "morph tets"}


@cache
def _unit(name: str) -> np.ndarray:
    return _frames(OPERATIONS[name](1.0))


def _relative_difference(name: str, scale: float) -> float:
    """``max |op(s X)/s − op(X)| / max |op(X)|`` over the frames."""
    unit = _unit(name)
    return float(np.abs(_frames(OPERATIONS[name](scale)) / scale - unit).max()
                 / np.abs(unit).max())


# the first increment of a surface move weighs each triangle by its distortion over the
# rms one; at the rest both are rounding noise, which the weights must not follow (1e12)
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW
                                  else n for n in sorted(OPERATIONS)])
@settings(max_examples=3, deadline=None, derandomize=True, database=None)
@given(scale=SCALES)
@example(scale=1e12)
@example(scale=1e-12)
@example(scale=2.0**-40)
def test_every_operation_is_scale_covariant(name, scale):
    if np.frexp(scale)[0] == 0.5:  # a power of two: the same unit problem, bit for bit
        assert np.array_equal(_frames(OPERATIONS[name](scale)), _unit(name) * scale)
    else:
        assert _relative_difference(name, scale) <= 1e-9
