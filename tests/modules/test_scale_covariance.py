"""Scale invariance of ``meshopt info``'s measures and scale covariance of ``mt.move`` and
``mt.morph`` for tetrahedra, surfaces in 3D and planar meshes at 1e±300 (the scales up to
1e±12 of every operation: ``test_operation_scale_covariance``)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import meshio
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_tet_move import cube_tets

import meshopt_toolkit as mt
from meshopt_toolkit import data_path
from meshopt_toolkit.cli.info import mesh_info
from meshopt_toolkit.io import load
from meshopt_toolkit.mesh import SurfaceMesh, TetMesh

def _tets():
    """[-1, 1]³ in 2³ cubes of six tets (Kuhn), interior vertex jittered (27 points)."""
    P, T = cube_tets(2, jitter=0.4, seed=3)
    return 2.0 * P - 1.0, T


def _icosphere():
    """An icosphere (one subdivision: 42 vertices), radius 1, outward."""
    import trimesh

    m = trimesh.creation.icosphere(1)
    return np.array(m.vertices), np.array(m.faces)


TET_P, TET_T = _tets()
ICO_V, ICO_F = _icosphere()
DISC = load(data_path("disc_25.msh")).as_planar()
CASES = {
    "tetrahedra": (TET_P, [("tetra", TET_T)],
                   ["min_mean_ratio", "mean_mean_ratio", "min_dihedral_deg",
                    "max_dihedral_deg"]),
    "surface triangles": (ICO_V, [("triangle", ICO_F)],
                          ["min_aspect_ratio", "mean_aspect_ratio"]),
    "planar triangles": (np.c_[DISC.points, np.zeros(DISC.n_vertices)],
                         [("triangle", DISC.triangles)],
                         ["min_aspect_ratio", "mean_shape_quality", "min_angle_deg",
                          "max_angle_deg"]),
}


def _info(kind: str, scale: float) -> dict:
    points, cells, _ = CASES[kind]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.vtu"
        meshio.write(path, meshio.Mesh(points * scale, cells))  # binary: exact floats
        return mesh_info(path)


UNIT = {kind: _info(kind, 1.0) for kind in CASES}


@settings(max_examples=10, deadline=None)
@given(kind=st.sampled_from(sorted(CASES)), exponent=st.floats(-300.0, 300.0))
@example(kind="tetrahedra", exponent=-100.0)
@example(kind="tetrahedra", exponent=300.0)
@example(kind="tetrahedra", exponent=-300.0)
@example(kind="surface triangles", exponent=-300.0)
@example(kind="surface triangles", exponent=300.0)
@example(kind="planar triangles", exponent=300.0)
@example(kind="planar triangles", exponent=-300.0)
def test_info_measures_are_the_same_at_every_scale(kind, exponent):
    info = _info(kind, 10.0 ** exponent)
    unit = UNIT[kind]
    assert info["cell_kind"] == kind
    assert info.get("admissible", True) and info.get("n_degenerate", 0) == 0
    assert not info["problems"]
    for key in CASES[kind][2]:
        # the scaled points are rounded: the measures agree to rounding
        assert info[key] == pytest.approx(unit[key], rel=1e-12), key


# --- moves -------------------------------------------------------------------------------
TET_HANDLES = np.flatnonzero((np.abs(TET_P) == 1).any(axis=1))  # the cube's boundary
SURFACE_HANDLES = np.flatnonzero(np.abs(ICO_V[:, 2]) > 0.6)  # two caps


def _twisted(points, scale: float):
    """Turned about z by 0.6 z (in units of ``scale``) and stretched 1.1 along z."""
    X = points / scale
    a = 0.6 * X[:, 2]
    return scale * np.stack([X[:, 0] * np.cos(a) - X[:, 1] * np.sin(a),
                             X[:, 0] * np.sin(a) + X[:, 1] * np.cos(a), 1.1 * X[:, 2]], 1)


def _tet_move(scale: float):
    P = TET_P * scale
    return mt.move(TetMesh(P, TET_T), TET_HANDLES, _twisted(P, scale)[TET_HANDLES])


def _surface_move(scale: float):
    V = ICO_V * scale
    return mt.move(SurfaceMesh(V, ICO_F), SURFACE_HANDLES,
                   _twisted(V, scale)[SURFACE_HANDLES])


def _planar_move(scale: float):
    b = DISC.boundary_vertices
    return mt.move(DISC.with_points(DISC.points * scale), b, DISC.points[b] * [1.3, 0.8] * scale)


MOVES = {"tets": (_tet_move, "min_mean_ratio"),
         "surface": (_surface_move, "worst_relative_quality"),
         "planar": (_planar_move, "min_aspect_ratio")}
UNIT_MOVES = {name: move(1.0) for name, (move, _) in MOVES.items()}


@settings(max_examples=4, deadline=None)
@given(name=st.sampled_from(sorted(MOVES)), exponent=st.integers(-990, 990))
@example(name="tets", exponent=-997)  # about 1e-300
@example(name="tets", exponent=997)  # about 1e300
@example(name="surface", exponent=-997)
@example(name="surface", exponent=997)
@example(name="planar", exponent=997)
def test_moves_at_powers_of_two_up_to_1e300_are_exact(name, exponent):
    move, key = MOVES[name]
    scale = float(np.ldexp(1.0, exponent))
    result = move(scale)
    unit = UNIT_MOVES[name]
    assert np.array_equal(np.asarray(result.mesh.points), np.ldexp(
        np.asarray(unit.mesh.points), exponent))
    assert result.summary()[key] == unit.summary()[key]


@pytest.mark.parametrize("name", sorted(MOVES))
@pytest.mark.parametrize("scale", [1e300, 1e-300, 1e100, 1e-100])
def test_moves_at_1e300_keep_their_quality(name, scale):
    move, key = MOVES[name]
    result = move(scale)
    unit = UNIT_MOVES[name]
    q, q_unit = result.summary()[key], unit.summary()[key]
    # tets and planar meshes follow any scale to rounding; the surface solver's result
    # moves with rounding-level changes of its input
    # (test_operation_scale_covariance.test_every_operation_is_scale_covariant, 1e12)
    assert q == pytest.approx(q_unit, rel=1e-9 if name != "surface" else 2e-2)
    assert np.isfinite(np.asarray(result.mesh.points)).all()


# --- morphs ------------------------------------------------------------------------------
def _tet_morph(scale: float):
    return mt.morph(TetMesh(TET_P * scale, TET_T),
                    TetMesh(TET_P * [1.3, 1.0, 0.8] * scale, TET_T), frames=4)


def _surface_morph(scale: float):
    return mt.morph(SurfaceMesh(ICO_V * scale, ICO_F),
                    SurfaceMesh(ICO_V * [1.4, 1.0, 0.7] * scale, ICO_F), frames=4)


def _planar_morph(scale: float):
    return mt.morph(DISC.with_points(DISC.points * scale),
                    DISC.with_points(DISC.points * [1.3, 0.8] * scale), frames=4)


def _complete_morph(scale: float):
    return mt.morph(DISC.with_points(DISC.points * scale),
                    DISC.with_points(DISC.points * [1.3, 0.8] * scale), frames=3,
                    metric="complete")


# the complete morph's summary holds areas: those of the unit-size problem (at 1e300 the
# user's would be past the float range, at 1e-300 below it)
MORPHS = {"tets": (_tet_morph, "min_mean_ratio"),
          "surface": (_surface_morph, "worst_relative_quality"),
          "planar": (_planar_morph, "min_aspect_ratio"),
          "planar complete": (_complete_morph, "linear_min_area")}
UNIT_MORPHS = {name: morph(1.0) for name, (morph, _) in MORPHS.items()}


@pytest.mark.parametrize("name", sorted(MORPHS))
@pytest.mark.parametrize("scale", [1e300, 1e-300])
def test_a_morph_at_1e300_is_the_unit_morph_scaled(name, scale):
    morph, key = MORPHS[name]
    result, unit = morph(scale), UNIT_MORPHS[name]
    frames = np.array([np.asarray(f.points) for f in result.frames])
    unit_frames = np.array([np.asarray(f.points) for f in unit.frames])
    assert np.abs(frames / scale - unit_frames).max() <= 1e-9 * np.abs(unit_frames).max()
    assert result.summary()[key] == pytest.approx(unit.summary()[key], rel=1e-9)


@settings(max_examples=30, deadline=None)
@given(exponents=st.lists(st.integers(-1070, 1020), min_size=1, max_size=6),
       seed=st.integers(0, 2**16))
def test_unit_cells_scales_each_cell_exactly_to_its_own_size(exponents, seed):
    from meshopt_toolkit.scaling import unit_cells

    rng = np.random.default_rng(seed)
    v = np.ldexp(rng.uniform(-1.0, 1.0, (3, len(exponents), 3)),
                 np.array(exponents)[None, :, None])
    unit, e = unit_cells(v, axis=1)
    largest = np.abs(unit).max(axis=(0, 2))
    normal = np.abs(v).min(axis=(0, 2)) > 2.0**-1000  # no subnormal component
    assert ((largest >= 0.5) & (largest < 1.0) | (largest == 0))[normal].all()
    assert np.array_equal(np.ldexp(unit, e[None, :, None])[:, normal], v[:, normal])
