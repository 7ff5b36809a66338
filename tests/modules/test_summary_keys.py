"""Every operation's ``summary()`` and every built-in filter's result use snake_case keys
(``worst_relative_quality``, ``handle_error``, ...), through nested dicts too."""

from __future__ import annotations

import re

import numpy as np
import pytest
from test_tet_move import cube_tets

import meshopt_toolkit as mt
from meshopt_toolkit import data_path
from meshopt_toolkit.fem.poisson import PoissonObjective
from meshopt_toolkit.io import load
from meshopt_toolkit.mesh import SurfaceMesh, TetMesh
from meshopt_toolkit.pipeline import Document, registry

SNAKE = re.compile(r"^[a-z][a-z0-9_]*$")


def _bad_keys(obj, where: str = "") -> list[str]:
    """The keys of ``obj`` (recursively through dicts and lists) that are not snake_case."""
    if isinstance(obj, dict):
        return [f"{where}/{k}" for k in obj if not (isinstance(k, str) and SNAKE.match(k))] + [
            bad for k, v in obj.items() for bad in _bad_keys(v, f"{where}/{k}")]
    if isinstance(obj, (list, tuple)):
        return [bad for i, v in enumerate(obj) for bad in _bad_keys(v, f"{where}[{i}]")]
    return []


def test_the_checker_finds_spaced_capital_and_nested_keys():
    assert _bad_keys({"worst relative quality": 1.0}) == ["/worst relative quality"]
    assert _bad_keys({"ok": {"Folds": 0}, "list": [{"a b": 1}]}) == ["/ok/Folds", "/list[0]/a b"]
    assert _bad_keys({"worst_relative_quality": 1.0, "n_2": {"x": [1, 2]}}) == []


def _icosphere():
    import trimesh

    m = trimesh.creation.icosphere(1)
    return np.array(m.vertices), np.array(m.faces)


DISC = load(data_path("disc_25.msh")).as_planar()
ICO_V, ICO_F = _icosphere()
TET_P, TET_T = cube_tets(1)


def _move_planar():
    b = DISC.boundary_vertices
    return mt.move(DISC, b, DISC.points[b] * [1.2, 0.9])


def _move_tet():
    top = np.flatnonzero(TET_P[:, 2] > 0.5)
    bottom = np.flatnonzero(TET_P[:, 2] < 0.5)
    h = np.r_[bottom, top]
    return mt.move(TetMesh(TET_P, TET_T), h, TET_P[h] + (TET_P[h, 2:] > 0.5) * [0.2, 0, 0])


def _move_surface():
    h = np.flatnonzero(np.abs(ICO_V[:, 2]) > 0.8)
    return mt.move(SurfaceMesh(ICO_V, ICO_F), h, ICO_V[h] * [1.0, 1.0, 1.2])


def _morph_planar():
    return mt.morph(DISC, DISC.with_points(DISC.points * [1.3, 0.8]), frames=3)


def _morph_tet():
    return mt.morph(TetMesh(TET_P, TET_T), TetMesh(TET_P * [1.3, 1.0, 0.8], TET_T), frames=3)


def _morph_surface():
    return mt.morph(SurfaceMesh(ICO_V, ICO_F), SurfaceMesh(ICO_V * [1.3, 1.0, 0.8], ICO_F),
                    frames=3)


def _deform():
    V = np.zeros_like(DISC.points)
    b = DISC.boundary_vertices
    V[b, 1] = -0.3 * DISC.points[b, 1]
    return mt.deform(DISC, V, time=1.0, frames=3)


def _optimize():
    return mt.optimize(DISC, PoissonObjective(DISC, rhs="1"), max_iterations=2)


OPERATIONS = {"move planar": _move_planar, "move tet": _move_tet,
              "move surface": _move_surface, "morph planar": _morph_planar,
              "morph tet": _morph_tet, "morph surface": _morph_surface,
              "deform": _deform, "optimize": _optimize}


@pytest.mark.parametrize("name", sorted(OPERATIONS))
def test_every_operation_summary_has_snake_case_keys(name):
    summary = OPERATIONS[name]().summary()
    assert summary and _bad_keys(summary) == []


def test_one_key_per_concept_across_cell_kinds():
    planar, tet, surface = _move_planar(), _move_tet(), _move_surface()
    for result in (planar, tet, surface):
        assert {"handle_error", "seconds"} <= set(result.summary())
    assert "worst_relative_quality" in surface.summary()
    morphs = [f().summary() for f in (_morph_planar, _morph_tet, _morph_surface)]
    for key in ("initial_path", "strain_bound", "gradient_norm", "iterations", "seconds"):
        assert all(key in s for s in morphs), key
    # a per-frame list is spelled ``<measure>_per_frame``
    summaries = [r.summary() for r in (planar, tet, surface)] + morphs
    assert not [k for s in summaries for k in s if k.startswith("frames_")]
    assert "min_aspect_ratio_per_frame" in planar.summary()
    assert "min_mean_ratio_per_frame" in tet.summary()
    assert "worst_relative_quality_per_frame" in morphs[2]


def _filter_runs(tmp_path):
    """(filter name, document, params) for each built-in filter, on every cell kind it takes."""
    V = np.zeros_like(DISC.points)
    V[DISC.boundary_vertices, 1] = -0.3 * DISC.points[DISC.boundary_vertices, 1]
    np.save(tmp_path / "v.npy", V)
    disc2 = lambda: Document([DISC, DISC.with_points(DISC.points * [1.3, 0.8])])  # noqa: E731
    motion = {"where": "y > 0.5", "map": "x; y + 0.1; z"}
    saving = Document([DISC])
    saving.output_dir = tmp_path
    return [
        ("load_mesh", Document([DISC]), {"path": str(data_path("disc_25.msh"))}),
        ("save_mesh", saving, {"path": "out.msh"}),
        ("meshing_uniform_refinement", Document([DISC]), {}),
        ("compute_scalar_by_shape_quality_per_face", Document([DISC]), {}),
        ("compute_scalar_by_shape_quality_per_face", Document([SurfaceMesh(ICO_V, ICO_F)]), {}),
        ("apply_coord_prescribed_motion", Document([DISC]),
         {"where": "y > 0.5", "map": "x; y + 0.1"}),
        ("apply_coord_prescribed_motion", Document([SurfaceMesh(ICO_V, ICO_F)]),
         {"where": "z > 0.8", "map": "x; y; z + 0.1"}),
        ("apply_coord_prescribed_motion", Document([TetMesh(TET_P, TET_T)]), motion),
        ("generate_geodesic_morph", disc2(), {"frames": 3}),
        ("generate_geodesic_morph", Document([SurfaceMesh(ICO_V, ICO_F),
                                              SurfaceMesh(ICO_V * [1.3, 1.0, 0.8], ICO_F)]),
         {"frames": 3}),
        ("apply_coord_quality_preserving_deformation", Document([DISC]),
         {"displacement": str(tmp_path / "v.npy")}),
        ("apply_coord_shape_optimization", Document([DISC]),
         {"rhs": "1", "max_iterations": 2}),
    ]


def test_every_builtin_filter_result_has_snake_case_keys(tmp_path):
    runs = _filter_runs(tmp_path)
    builtin = {n for n in registry.names() if registry.get(n).__module__.startswith(
        "meshopt_toolkit.filters.")}
    assert builtin and builtin <= {name for name, _, _ in runs}  # a new filter joins this list
    for name, doc, params in runs:
        result = registry.get(name)()(doc, **params)
        assert result is None or _bad_keys(result) == [], (name, _bad_keys(result))
