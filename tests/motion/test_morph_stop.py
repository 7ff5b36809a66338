"""When a morph stops (``stop="auto" | "healthy" | "converged"``), one vocabulary through
``mt.morph``, ``meshopt morph --stop`` and the ``generate_geodesic_morph`` filter: on a
surface pair whose start is healthy but not stationary, "converged" takes steps and ends
with a lower path energy than "healthy", the same frames as the solver's own energy
stop; "auto" is "healthy" for surfaces; planar and tet morphs, which stop on their energy
tests only, refuse "healthy" in one line before any work."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import grid_mesh

import meshopt_toolkit as mt
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import FilterError, OptionError
from meshopt_toolkit.io import load_cells, save, save_cells
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.mesh import SurfaceMesh, TetMesh
from meshopt_toolkit.motion.surface.morph import morph_surface
from meshopt_toolkit.motion.surface.move import move_surface
from meshopt_toolkit.pipeline import Document, load_pipeline
from meshopt_toolkit.pipeline.document import load_entry
from meshopt_toolkit.pipeline.filter import registry
from meshopt_toolkit.scaling import size_scale

trimesh = pytest.importorskip("trimesh")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import _surface_measures as sm  # noqa: E402
import bench_surface as bench  # noqa: E402

FRAMES = 5


@pytest.fixture(scope="module")
def sphere():
    """An icosphere (320 triangles), its cap turned 90° about a line off its centre by
    move_surface, the bottom fixed: the as-rigid-as-possible start is healthy but not
    stationary (one Levenberg–Marquardt step lowers the path energy by ~6 %)."""
    m = trimesh.creation.icosphere(subdivisions=2)
    V, F = np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
    cap, bottom = np.flatnonzero(V[:, 2] > 0.7), np.flatnonzero(V[:, 2] < -0.7)
    turned = bench.turning(V[cap], np.array([0, 0, 0.3]), [1, 0, 0], np.deg2rad(90))(1.0)
    V1 = move_surface(V, F, np.concatenate([cap, bottom]),
                      np.concatenate([turned, V[bottom]]), steps=4).points
    return V, F, np.asarray(V1, float)


def _morph(sphere, stop):
    V, F, V1 = sphere
    return mt.morph(SurfaceMesh(V, F), SurfaceMesh(V1, F), FRAMES, stop=stop)


def test_api_converged_lowers_the_energy_healthy_keeps_the_worst_frame(sphere):
    V, F, V1 = sphere
    healthy, converged, auto = (_morph(sphere, s) for s in ("healthy", "converged", "auto"))
    assert healthy.status == "healthy" and converged.status == "converged"
    assert healthy.morph.iterations == 0 and converged.morph.iterations >= 1
    assert converged.morph.energy < 0.99 * healthy.morph.energy
    # the option reaches the solver: its own stop rules at unit size, bitwise
    scale = size_scale(V, V1, columns=3)
    for res, flag in ((healthy, True), (converged, False)):
        own = morph_surface(scale.down(V), scale.down(V1), F, FRAMES, stop_when_healthy=flag)
        assert np.array_equal(np.array([f.points for f in res.frames])[1:-1],
                              scale.points_up(own.points, V)[1:-1])
    assert all(np.array_equal(a.points, b.points) for a, b in zip(auto.frames, healthy.frames))
    # stopped as healthy: every interior frame at least as healthy as the worse end
    # (independent measure), so no better worst frame exists
    worse_end = min(1.0, sm.worst_relative_quality(V, V1, F, []))
    for f in healthy.frames[1:-1]:
        assert sm.worst_relative_quality(V, np.asarray(f.points), F, []) >= worse_end - 1e-12


def test_api_refuses_healthy_where_it_does_not_apply():
    mesh = grid_mesh(3, jitter=0.2)
    target = mesh.with_points(mesh.points + 0.05 * np.sin(np.pi * mesh.points[:, :1]))
    for metric in ("distortion", "complete"):
        with pytest.raises(OptionError, match="surfaces in 3D only; planar morphs"):
            mt.morph(mesh, target, 3, metric=metric, stop="healthy")
    with pytest.raises(OptionError, match="unknown stop rule 'soon'"):
        mt.morph(mesh, target, 3, stop="soon")
    # "converged" is the planar morph's only rule: the same frames as the default
    a, b = mt.morph(mesh, target, 3), mt.morph(mesh, target, 3, stop="converged")
    assert all(np.array_equal(x.points, y.points) for x, y in zip(a.frames, b.frames))
    P, T = _cube_tets()
    with pytest.raises(OptionError, match="surfaces in 3D only; tet morphs"):
        mt.morph(TetMesh(P, T), TetMesh(1.1 * P, T), 3, stop="healthy")


def _cube_tets():
    """The unit cube cut into six positive tets around its diagonal."""
    P = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    T = np.array([[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7],
                  [0, 5, 1, 7]])
    v = np.einsum("ij,ij->i", np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]),
                  P[T[:, 3]] - P[T[:, 0]])
    T[v < 0] = T[v < 0][:, [1, 0, 2, 3]]
    return P, T


def _obj(tmp_path, name, V, F) -> Path:
    path = tmp_path / name
    save_cells(CellMesh.from_surface_mesh(SurfaceMesh(V, F)), path)
    return path


def test_cli_stop_converged_lowers_the_energy(sphere, tmp_path, capsys):
    V, F, V1 = sphere
    src, tgt = _obj(tmp_path, "a.obj", V, F), _obj(tmp_path, "b.obj", V1, F)
    runs = {}
    for stop in ("healthy", "converged", None):
        out = tmp_path / f"out-{stop}"
        argv = ["morph", str(src), str(tgt), "-o", str(out), "--frames", str(FRAMES), "--json"]
        assert main(argv + (["--stop", stop] if stop else [])) == 0
        runs[stop] = (json.loads(capsys.readouterr().out),
                      load_cells(out / "frame_002.obj").points)
    (healthy, mid_h), (converged, mid_c), (default, mid_d) = runs.values()
    assert healthy["status"] == "healthy" == default["status"]
    assert converged["status"] == "converged"
    assert converged["energy"] < 0.99 * healthy["energy"]
    assert np.array_equal(mid_d, mid_h) and not np.allclose(mid_c, mid_h, atol=1e-6)


def test_cli_refuses_healthy_for_planar_and_tet_files_in_one_line(tmp_path, capsys):
    mesh = grid_mesh(3, jitter=0.2)
    save(mesh, tmp_path / "a.msh")
    save(mesh.with_points(mesh.points * 1.1), tmp_path / "b.msh")
    P, T = _cube_tets()
    save_cells(CellMesh(P, [("tetra", T)]), tmp_path / "a.vtu")
    save_cells(CellMesh(1.1 * P, [("tetra", T)]), tmp_path / "b.vtu")
    for ext, kind in (("msh", "planar"), ("vtu", "tet")):
        out = tmp_path / f"out-{ext}"
        assert main(["morph", str(tmp_path / f"a.{ext}"), str(tmp_path / f"b.{ext}"), "-o",
                     str(out), "--stop", "healthy"]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err
        assert "--stop healthy applies to surfaces in 3D only" in err and f"{kind} morphs" in err
        assert not out.exists()
    with pytest.raises(SystemExit) as bad:
        main(["morph", str(tmp_path / "a.msh"), str(tmp_path / "b.msh"), "-o",
              str(tmp_path / "o"), "--stop", "soon"])
    assert bad.value.code == 2 and "invalid choice: 'soon'" in capsys.readouterr().err


def _pipeline(tmp_path, target: Path, **params) -> Path:
    path = tmp_path / f"morph-{len(list(tmp_path.glob('morph-*.json')))}.json"
    path.write_text(json.dumps({"filters": [
        {"name": "load_mesh", "params": {"path": str(target)}},
        {"name": "generate_geodesic_morph", "params": {"frames": FRAMES, **params}}]}))
    return path


def test_filter_in_a_json_pipeline_stops_as_asked(sphere, tmp_path):
    V, F, V1 = sphere
    src, tgt = _obj(tmp_path, "a.obj", V, F), _obj(tmp_path, "b.obj", V1, F)
    docs = {}
    for stop in ("healthy", "converged", None):
        params = {} if stop is None else {"stop": stop}
        docs[stop] = load_pipeline(_pipeline(tmp_path, tgt, **params)).run(
            Document([load_entry(src)]))
    (healthy, converged, default) = docs.values()
    for doc in docs.values():
        assert [e.name for e in doc.entries[2:]] == [f"morph_{k:03d}" for k in range(FRAMES)]
        assert np.array_equal(doc.entries[2].mesh.points, V)
        assert np.array_equal(doc.mesh.points, V1)
        assert doc.current_entry.face_attributes["quality"].min() > 0
    assert healthy.results[-1]["status"] == "healthy" == default.results[-1]["status"]
    assert converged.results[-1]["status"] == "converged"
    assert converged.results[-1]["energy"] < 0.99 * healthy.results[-1]["energy"]
    library = _morph(sphere, "converged")
    assert np.array_equal(converged.entries[4].mesh.points, library.frames[2].points)


def test_filter_refuses_healthy_for_planar_meshes():
    mesh = grid_mesh(3, jitter=0.2)
    doc = Document([mesh, mesh.with_points(mesh.points * 1.1)])
    with pytest.raises(FilterError, match="surfaces in 3D only; planar morphs"):
        registry.get("generate_geodesic_morph")()(doc, frames=3, stop="healthy")
    assert len(doc) == 2
    P, T = _cube_tets()
    doc = Document([TetMesh(P, T), TetMesh(1.1 * P, T)])
    with pytest.raises(FilterError, match="a surface in 3D; .* has 6 tetrahedra"):
        registry.get("generate_geodesic_morph")()(doc, frames=3)
    assert len(doc) == 2
