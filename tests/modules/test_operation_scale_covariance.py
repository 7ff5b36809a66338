"""Scale covariance of every operation: ``mt.move``, ``mt.morph``, ``mt.deform`` and
``mt.optimize`` of a mesh scaled by ``s`` (``2**k``, ``|k| ≤ 40``, or ``10**e``,
``|e| ≤ 12``), every length-valued input scaled alike, give the unit-size results scaled
by ``s`` to 1e-9 relative, for planar triangles, surface triangles and tetrahedra."""

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
    """``j(Q) = c·Σ_rim Q / s``: an objective of the mesh scaled by ``s`` that takes the
    same values on the scaled meshes (a pull of the rim)."""

    def __init__(self, s: float):
        self.s, self.c = s, np.array([0.015, -0.01])

    def value(self, Q):
        return float(np.sum(Q[RIM] * self.c) / self.s)

    def derivative(self, Q):
        D = np.zeros_like(Q)
        D[RIM] = self.c / self.s
        return D


#: each operation and kind: the frames of the operation on the inputs scaled by ``s``
OPERATIONS = {
    "move planar": lambda s: mt.move(DISC.with_points(DISC.points * s), RIM,
                                     DISC.points[RIM] * [1.3, 0.8] * s),
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
}


def _surface_move(s: float):
    return mt.move(SurfaceMesh(ICO_V * s, ICO_F), CAPS, _twisted(ICO_V)[CAPS] * s)


@cache
def _unit(name: str) -> np.ndarray:
    return _frames((OPERATIONS.get(name) or _surface_move)(1.0))


def _relative_difference(name: str, scale: float) -> float:
    """``max |op(s X)/s − op(X)| / max |op(X)|`` over the frames."""
    run = OPERATIONS.get(name) or _surface_move
    unit = _unit(name)
    return float(np.abs(_frames(run(scale)) / scale - unit).max() / np.abs(unit).max())


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(OPERATIONS))
@settings(max_examples=3, deadline=None)
@given(scale=SCALES)
@example(scale=1e12)
@example(scale=1e-12)
def test_every_operation_is_scale_covariant(name, scale):
    assert _relative_difference(name, scale) <= 1e-9


@pytest.mark.slow
@settings(max_examples=3, deadline=None)
@given(k=st.integers(-40, 40))
def test_a_surface_move_is_scale_covariant_at_powers_of_two(k):
    assert _relative_difference("move surface", float(np.ldexp(1.0, k))) <= 1e-9


# the first increment weighs each triangle by its distortion over the rms one; at the
# rest both are rounding noise, which the weights must not follow
@pytest.mark.slow
@settings(max_examples=3, deadline=None)
@given(e=st.integers(1, 12) | st.integers(-12, -1))
@example(e=12)
def test_a_surface_move_is_scale_covariant_at_powers_of_ten(e):
    assert _relative_difference("move surface", 10.0**e) <= 1e-9
