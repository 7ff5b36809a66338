"""Pipelines on meshes in space: a triangle surface through pymeshlab's filters and ours
(JSON and MeshLab ``.mlx``), keeping its file's groups and data while the faces are kept
and naming them in a warning when a MeshLab step changes the faces; a tet mesh through
our move filter, and a MeshLab step on it refused with one line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from meshopt_toolkit.batch.file_job import RunOptions, run_file
from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load_cells, save_cells
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.kernels.tetrahedra import signed_volumes
from meshopt_toolkit.motion.surface.folds import FoldTest
from meshopt_toolkit.pipeline import formats
from meshopt_toolkit.pipeline.runner import Pipeline

pymeshlab = pytest.importorskip("pymeshlab")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import bench_surface as bench  # noqa: E402

SMOOTH = {"name": "apply_coord_laplacian_smoothing", "params": {"stepsmoothnum": 2}}
MOVE = {"name": "apply_coord_prescribed_motion",
        "params": {"selection": "end", "map": "x; y + 0.3; z"}}
QUALITY = {"name": "compute_scalar_by_shape_quality_per_face",
           "params": {"metric": "aspect ratio 2r/R"}}


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    """The closed bar [0, 6]×[0, 1]×[0, 1] (418 vertices) as gmsh: physical groups
    ``left``/``right``, point data ``temperature`` and ``end`` (1 on the cap x = 6)."""
    V, F = bench.box_surface([6.0, 1.0, 1.0], 0.25)
    tags = np.where(V[F].mean(axis=1)[:, 0] > 3, 2, 1)
    path = tmp_path_factory.mktemp("bar") / "bar.msh"
    save_cells(CellMesh(V, [("triangle", F)],
                        point_data={"temperature": V[:, 0] ** 2,
                                    "end": (V[:, 0] > 5.99) * 1.0},
                        cell_data={"gmsh:physical": [tags], "gmsh:geometrical": [tags]},
                        field_data={"left": np.array([1, 2]), "right": np.array([2, 2])}),
               path)
    return path


def _smoothed(points, triangles, steps: int = 2) -> np.ndarray:
    """pymeshlab's Laplacian smoothing, run directly."""
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(points, float), np.asarray(triangles)))
    ms.apply_coord_laplacian_smoothing(stepsmoothnum=steps)
    return ms.current_mesh().vertex_matrix()


def _aspect_ratios(P, T) -> np.ndarray:
    """2r/R = 8A²/(s·abc), A by Heron's formula (not our kernels)."""
    a, b, c = (np.linalg.norm(P[T[:, i]] - P[T[:, j]], axis=1)
               for i, j in ((1, 2), (2, 0), (0, 1)))
    s = (a + b + c) / 2
    area2 = s * (s - a) * (s - b) * (s - c)
    return 8 * area2 / (s * a * b * c)


def _triangles(cm) -> np.ndarray:
    return np.concatenate([c for t, c in cm.cells if t == "triangle"])


def _quality(cm) -> np.ndarray:
    return np.concatenate(cm.cell_data["quality"])


def _run(pipeline, src, out, **options):
    out.mkdir()
    rec = run_file(pipeline, src, out, options=RunOptions(ext=".vtu", **options))
    return rec, (load_cells(rec["outputs"][-1]) if rec["outputs"] else None)


def _check_surface_result(src, b) -> None:
    """Smoothing applied, the cap moved exactly, no fold, quality right, extras kept."""
    a = load_cells(src)
    F = _triangles(a)
    S = _smoothed(a.points, F)
    end = np.flatnonzero(a.point_data["end"])
    expected = S[end] + [0.0, 0.3, 0.0]
    np.testing.assert_array_equal(b.points[end], expected)  # bitwise, after smoothing
    assert np.abs(S[end] - a.points[end]).max() > 1e-3  # the smoothing step did act
    assert not FoldTest(S, F).mask(b.points).any()
    np.testing.assert_array_equal(_triangles(b), F)  # .vtu: one block of them
    np.testing.assert_allclose(_quality(b), _aspect_ratios(b.points, F), rtol=1e-12)
    for key in ("temperature", "end"):
        np.testing.assert_array_equal(b.point_data[key], a.point_data[key])
    np.testing.assert_array_equal(np.concatenate(b.cell_data["gmsh:physical"]),
                                  np.concatenate(a.cell_data["gmsh:physical"]))
    assert set(b.field_data) == {"left", "right"}


def test_json_surface_pipeline_mixes_meshlab_and_meshopt(bar, tmp_path):
    rec, b = _run({"filters": [SMOOTH, MOVE, QUALITY]}, bar, tmp_path / "out")
    assert rec["status"] == "ok" and rec["warnings"] == [], rec
    _check_surface_result(bar, b)
    move = next(r for r in rec["results"] if r["filter"] == MOVE["name"])
    assert move["folds"] == 0 and move["handles"] == int(load_cells(bar).point_data["end"].sum())


def test_mlx_surface_pipeline_gives_the_same_mesh(bar, tmp_path):
    pipeline = Pipeline.from_dict({"filters": [SMOOTH, MOVE, QUALITY]})
    mlx = tmp_path / "surface.mlx"
    formats.save_pipeline(pipeline, mlx)
    text = mlx.read_text()
    assert "Prescribed Motion (meshopt)" in text and "Laplacian" in text
    assert [s.name for s in formats.load_pipeline(mlx).steps] == [
        SMOOTH["name"], MOVE["name"], QUALITY["name"]]
    out = tmp_path / "out"
    assert main(["run", str(mlx), str(bar), "-o", str(out), "--to", ".vtu"]) == 0
    b = load_cells(out / "bar.vtu")
    _check_surface_result(bar, b)
    _, c = _run({"filters": [SMOOTH, MOVE, QUALITY]}, bar, tmp_path / "json")
    np.testing.assert_array_equal(b.points, c.points)


@pytest.mark.parametrize("step, grows", [
    ({"name": "meshing_isotropic_explicit_remeshing",
      "params": {"iterations": 2, "targetlen": "1%"}}, True),
    ({"name": "meshing_decimation_quadric_edge_collapse",
      "params": {"targetfacenum": 300}}, False),
])
def test_a_meshlab_step_that_changes_the_faces_names_what_is_lost(bar, tmp_path, step,
                                                                  grows):
    rec, b = _run({"filters": [MOVE, step, QUALITY]}, bar, tmp_path / "out")
    a = load_cells(bar)
    assert rec["status"] == "ok", rec
    assert (len(b.points) > len(a.points)) if grows else (len(b.points) < len(a.points))
    assert len(rec["warnings"]) == 1
    line = rec["warnings"][0]
    assert line.startswith(f"step 2 ({step['name']}): bar: a MeshLab step changed the faces")
    for lost in ("'temperature'", "'end'", "'gmsh:physical'", "'left', 'right'"):
        assert lost in line, line
    assert "temperature" not in b.point_data and "gmsh:physical" not in b.cell_data
    np.testing.assert_allclose(_quality(b), _aspect_ratios(b.points, _triangles(b)),
                               rtol=1e-12)  # our step ran on the new faces


def test_meshopt_run_prints_the_loss_on_stderr(bar, tmp_path, capsys):
    pipeline = tmp_path / "p.json"
    pipeline.write_text(json.dumps({"filters": [
        {"name": "meshing_decimation_quadric_edge_collapse",
         "params": {"targetfacenum": 300}}]}))
    assert main(["run", str(pipeline), str(bar), "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "changed the faces" in err and "'temperature'" in err


# ------------------------------------------------------------------ tetrahedra
@pytest.fixture(scope="module")
def box(tmp_path_factory):
    """gmsh tets of [-1, 1]³ minus a ball of radius 0.4 (groups ``hole``, ``walls``, ``solid``) with
    the point datum ``temperature``."""
    pytest.importorskip("gmsh")
    from gmsh_files import box_with_hole_msh

    path = box_with_hole_msh(tmp_path_factory.mktemp("tets") / "box.msh", radius=0.4, size=0.5)
    cm = load_cells(path)
    cm.point_data["temperature"] = np.linalg.norm(cm.points, axis=1)
    save_cells(cm, path)
    return path


def test_a_tet_mesh_moves_in_a_pipeline_with_its_file_kept(box, tmp_path):
    shift = {"name": "apply_coord_prescribed_motion",
             "params": {"group": "hole", "map": "x + 0.1; y; z"}}
    rec = run_file({"filters": [shift]}, box, tmp_path)
    assert rec["status"] == "ok" and rec["warnings"] == [], rec
    a, b = load_cells(box), load_cells(rec["outputs"][-1])
    hole = np.flatnonzero(np.linalg.norm(a.points, axis=1) < 0.4 + 1e-9)
    np.testing.assert_array_equal(b.points[hole], a.points[hole] + [0.1, 0.0, 0.0])
    assert rec["results"][0]["handles"] > len(hole)  # the outer boundary is held too
    assert [t for t, _ in a.cells] == [t for t, _ in b.cells]
    for (_, ca), (_, cb) in zip(a.cells, b.cells):
        np.testing.assert_array_equal(ca, cb)
    for u, v in zip(a.cell_data["gmsh:physical"], b.cell_data["gmsh:physical"]):
        np.testing.assert_array_equal(u, v)
    np.testing.assert_array_equal(a.point_data["temperature"], b.point_data["temperature"])
    assert set(b.field_data) == {"hole", "walls", "solid"}
    tets = np.concatenate([c for t, c in b.cells if t == "tetra"])
    assert signed_volumes(b.points, tets).min() > 0


@pytest.mark.parametrize("dry_run", [False, True])
def test_a_meshlab_step_on_tets_is_refused_in_one_line(box, tmp_path, dry_run):
    rec = run_file({"filters": [SMOOTH]}, box, tmp_path, options=RunOptions(dry_run=dry_run))
    assert rec["status"] == "failed" and rec["outputs"] == []
    assert rec["error"] == (f"step 1 ({SMOOTH['name']}): supports planar triangle meshes "
                            "and triangle surfaces in 3D (pymeshlab holds triangles only); "
                            "the current mesh is a tetrahedral mesh")
    assert not (tmp_path / "box.msh").exists()


def test_face_quality_of_tets_is_refused(box, tmp_path):
    rec = run_file({"filters": [QUALITY]}, box, tmp_path)
    assert rec["status"] == "failed"
    assert rec["error"] == (f"step 1 ({QUALITY['name']}): supports planar triangle meshes "
                            "and triangle surfaces in 3D; the current mesh is a tetrahedral mesh")


@pytest.mark.parametrize("name", ["surface_move.json", "surface_move.mlx"])
def test_the_documented_examples_run(bar, tmp_path, name):
    example = Path(__file__).resolve().parents[2] / "examples" / "pipelines" / name
    pipeline = formats.load_pipeline(example)
    assert [s.name for s in pipeline.steps] == [SMOOTH["name"], MOVE["name"], QUALITY["name"]]
    rec, b = _run(pipeline, bar, tmp_path / "out")
    assert rec["status"] == "ok" and rec["warnings"] == [], rec
    _check_surface_result(bar, b)


def test_documents_made_in_python_take_tet_and_surface_meshes(box):
    from meshopt_toolkit.mesh import SurfaceMesh
    from meshopt_toolkit.pipeline.document import Document

    tets = load_cells(box).to_tet_mesh()
    hole = tets.tagged_vertices("hole")
    doc = Document([tets])
    Pipeline.from_dict({"filters": [{"name": "apply_coord_prescribed_motion",
                                     "params": {"group": "hole", "map": "x; y; z + 0.05"}}]}
                       ).run(doc)
    np.testing.assert_array_equal(doc.mesh.points[hole], tets.points[hole] + [0, 0, 0.05])
    assert signed_volumes(doc.mesh.points, doc.mesh.tets).min() > 0
    V, F = bench.box_surface([2.0, 1.0, 1.0], 0.25)
    doc = Document([SurfaceMesh(V, F)])
    Pipeline.from_dict({"filters": [QUALITY]}).run(doc)
    np.testing.assert_allclose(doc.current_entry.face_attributes["quality"],
                               _aspect_ratios(V, F), rtol=1e-12)
