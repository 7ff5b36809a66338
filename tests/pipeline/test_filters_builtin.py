"""Built-in filters, each through Python, JSON and .mlx, against independent references."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import grid_mesh, square5
from meshopt_toolkit.errors import FilterError, MeshoptError
from meshopt_toolkit.io import load, save
from meshopt_toolkit.mesh import TriangleMesh
from meshopt_toolkit.pipeline import Document, Pipeline, load_pipeline, registry, save_pipeline
from meshopt_toolkit.batch.file_job import run_file

pymeshlab = pytest.importorskip("pymeshlab")

SQ3 = np.sqrt(3.0)


def _via(kind: str, steps: list[dict], tmp_path, mesh) -> Document:
    """Run ``steps`` on ``mesh`` built in Python, from a JSON file, or from a .mlx file."""
    if kind == "python":
        doc = Document([mesh])
        for s in steps:
            registry.get(s["name"])()(doc, **s.get("params", {}))
        return doc
    path = tmp_path / f"p{len(list(tmp_path.iterdir()))}.{kind}"
    if kind == "json":
        path.write_text(json.dumps({"filters": steps}))
    else:
        save_pipeline(Pipeline.from_dict({"filters": steps}), path)
        assert "<filter name=" in path.read_text()
    return load_pipeline(path).run(Document([mesh]))


def _triangle_mesh():
    """Equilateral, right isosceles and a 1:4 sliver: closed-form qualities."""
    pts = [[0, 0], [1, 0], [0.5, SQ3 / 2],      # equilateral
           [2, 0], [3, 0], [2, 1],              # right isosceles, legs 1
           [4, 0], [8, 0], [6, 1]]              # base 4, height 1
    tri = [[0, 1, 2], [3, 4, 5], [6, 7, 8]]
    return TriangleMesh(pts, tri)  # readable only: quality needs no manifold


KINDS = ["python", "json", "mlx"]


@pytest.mark.parametrize("kind", KINDS)
def test_shape_quality_closed_forms(kind, tmp_path):
    mesh = _triangle_mesh()
    doc = _via(kind, [{"name": "compute_scalar_by_shape_quality_per_face"}], tmp_path, mesh)
    q = doc.current_entry.face_attributes["quality"]
    # 1/psi = sum E^2 / (4 sqrt3 A): equilateral 1; right isosceles 4/(4 sqrt3 / 2);
    # base 4 height 1: E^2 = 16 + 5 + 5, A = 2
    np.testing.assert_allclose(q, [1.0, 2 / SQ3, 26 / (8 * SQ3)], rtol=1e-14)
    doc = _via(kind, [{"name": "compute_scalar_by_shape_quality_per_face",
                       "params": {"metric": "aspect ratio 2r/R"}}], tmp_path, mesh)
    q = doc.current_entry.face_attributes["quality"]
    # 2r/R: equilateral 1, right isosceles 2(sqrt2 - 1); base 4 height 1: r = A/s, R = abc/4A
    s = (4 + 2 * np.sqrt(5)) / 2
    ref3 = 2 * (2 / s) / (4 * 5 / (4 * 2))
    np.testing.assert_allclose(q, [1.0, 2 * (np.sqrt(2) - 1), ref3], rtol=1e-13)


def test_shape_quality_summary_and_meshlab_agreement():
    """Our 2r/R equals MeshLab's 'inradius/circumradius' on every face."""
    mesh = grid_mesh(4, jitter=0.4, seed=7)
    doc = Document([mesh])
    res = registry.get("compute_scalar_by_shape_quality_per_face")()(doc, metric="aspect ratio 2r/R")
    ours = doc.current_entry.face_attributes["quality"]
    ms = doc.to_meshset()
    ms.compute_scalar_by_aspect_ratio_per_face(metric="inradius/circumradius")
    np.testing.assert_allclose(ours, ms.current_mesh().face_scalar_array(), rtol=1e-6)
    assert res["min"] == pytest.approx(ours.min()) and res["mean"] == pytest.approx(ours.mean())
    assert res["min_aspect_ratio"] == pytest.approx(ours.min())
    assert res["n_inverted"] == 0


def test_shape_quality_feeds_a_meshlab_selection(tmp_path):
    """Face quality stored by our filter is what MeshLab's 'Select by Face Quality' reads."""
    mesh = grid_mesh(4, jitter=0.45, seed=2)
    q = 1 / _psi_ref(mesh)
    srt = np.sort(q)  # thresholds strictly between values: no float32 ties in MeshLab
    lo, thr = (srt[0] + srt[1]) / 2, float(np.median(q))
    pipe = Pipeline.from_dict({"filters": [
        {"name": "compute_scalar_by_shape_quality_per_face", "params": {"metric": 0}},
        {"name": "Select by Face Quality", "params": {"minq": lo, "maxq": thr,
                                                      "inclusive": False}},
    ]})
    doc = pipe.run(Document([mesh]))
    sel = doc.current_entry.face_attributes["selected"]
    np.testing.assert_array_equal(sel, (q >= lo) & (q <= thr))
    assert 0 < sel.sum() < len(sel)


def _psi_ref(mesh):
    """psi by a plain loop-free but independent formula: 4 sqrt3 A / sum E^2 via Heron."""
    p = mesh.points[mesh.triangles]
    a = np.linalg.norm(p[:, 1] - p[:, 2], axis=1)
    b = np.linalg.norm(p[:, 2] - p[:, 0], axis=1)
    c = np.linalg.norm(p[:, 0] - p[:, 1], axis=1)
    s = (a + b + c) / 2
    area = np.sqrt(s * (s - a) * (s - b) * (s - c))
    return 4 * SQ3 * area / (a * a + b * b + c * c)


def test_shape_quality_of_a_3d_surface_is_unsigned():
    # one triangle is always on a plane (it is measured in it): a bent pair is not
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1]], [[0, 1, 2], [1, 3, 2]])
    doc = Document([mesh])
    registry.get("compute_scalar_by_shape_quality_per_face")()(doc)
    np.testing.assert_allclose(doc.current_entry.face_attributes["quality"],
                               1 / _psi_ref(mesh), rtol=1e-13)


@pytest.mark.parametrize("kind", KINDS)
def test_uniform_refinement(kind, tmp_path):
    mesh = grid_mesh(3, jitter=0.3, seed=1)
    doc = Document([mesh])
    doc.current_entry.set_vertex_attribute("u", mesh.points[:, 0] * 2 + mesh.points[:, 1])
    doc.current_entry.set_face_attribute("id", np.arange(mesh.n_triangles, dtype=float))
    steps = [{"name": "meshing_uniform_refinement", "params": {"iterations": 2}}]
    if kind == "python":
        registry.get(steps[0]["name"])()(doc, **steps[0]["params"])
    else:
        path = tmp_path / f"r.{kind}"
        save_pipeline(Pipeline.from_dict({"filters": steps}), path)
        load_pipeline(path).run(doc)
    out = doc.mesh
    n, e, t = mesh.n_vertices, len(mesh.edges), mesh.n_triangles
    e2 = 2 * e + 3 * t  # edges after one refinement
    assert out.n_triangles == 16 * t
    assert out.n_vertices == n + e + e2  # Euler: each round adds one vertex per edge
    np.testing.assert_array_equal(out.points[:n], mesh.points)  # old vertices first, in order
    # area conserved, every triangle CCW, quality of children equals parent's
    assert out.signed_areas().min() > 0
    assert out.signed_areas().sum() == pytest.approx(mesh.signed_areas().sum(), rel=1e-13)
    parent = np.repeat(_psi_ref(mesh), 16)
    np.testing.assert_allclose(_psi_ref(out), parent, rtol=1e-9)
    # a linear vertex field stays exact; face attributes follow their parent
    u = doc.current_entry.vertex_attributes["u"]
    np.testing.assert_allclose(u, out.points[:, 0] * 2 + out.points[:, 1], atol=1e-14)
    np.testing.assert_array_equal(doc.current_entry.face_attributes["id"],
                                  np.repeat(np.arange(t), 16))


def test_uniform_refinement_keeps_tags():
    mesh = load(_data("square5.msh"))
    doc = Document([mesh])
    registry.get("meshing_uniform_refinement")()(doc)
    assert doc.mesh == mesh.as_planar().refine()
    if mesh.lines is not None:
        assert len(doc.mesh.lines) == 2 * len(mesh.lines)


def _data(name):
    from meshopt_toolkit.datasets import data_path

    return data_path(name)


def test_uniform_refinement_of_3d_surface_routes_to_meshlab():
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    tri = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]  # a closed tetrahedron
    doc = Document([TriangleMesh(pts, tri)])
    res = registry.get("meshing_uniform_refinement")()(doc, iterations=1)
    assert res["n_triangles"] == 16 and doc.mesh.n_vertices == 4 + 6
    assert not doc.mesh.is_planar
    # every new vertex is the midpoint of an original edge
    mids = {tuple(np.round((np.array(pts[a]) + np.array(pts[b])) / 2, 12))
            for a in range(4) for b in range(a + 1, 4)}
    got = {tuple(np.round(p, 12)) for p in doc.mesh.points[4:]}
    assert got == mids


@pytest.mark.parametrize("kind", KINDS)
def test_load_and_save_steps(kind, tmp_path):
    src = tmp_path / "in.msh"
    save(square5(), src)
    steps = [
        {"name": "load_mesh", "params": {"path": "{input_dir}/in.msh"}},
        {"name": "meshing_uniform_refinement"},
        {"name": "save_mesh", "params": {"path": "{stem}_fine.ply"}},
    ]
    outdir = tmp_path / "out"
    outdir.mkdir()
    doc = Document()
    doc.output_dir = outdir
    doc.variables = {"stem": "in", "input_dir": str(tmp_path)}
    doc.inputs, doc.allow_read = [src], []  # confined reads: only the input
    if kind == "python":
        for s in steps:
            registry.get(s["name"])()(doc, **s.get("params", {}))
    else:
        path = tmp_path / f"io.{kind}"
        save_pipeline(Pipeline.from_dict({"filters": steps}), path)
        load_pipeline(path).run(doc)
    written = load(outdir / "in_fine.ply")
    assert written == square5().refine()
    # never overwrites without permission, and a failed write leaves the old file
    before = (outdir / "in_fine.ply").read_bytes()
    with pytest.raises(MeshoptError, match="exists"):
        registry.get("save_mesh")()(doc, path="{stem}_fine.ply")
    assert (outdir / "in_fine.ply").read_bytes() == before
    # the step's own "overwrite" cannot grant it; only the command line (--force) can
    with pytest.raises(MeshoptError, match="only --force"):
        registry.get("save_mesh")()(doc, path="{stem}_fine.ply", overwrite=True)
    assert (outdir / "in_fine.ply").read_bytes() == before
    doc.overwrite = True
    registry.get("save_mesh")()(doc, path="{stem}_fine.ply")


def test_save_step_bad_template(tmp_path):
    doc = Document([square5()])
    doc.output_dir = tmp_path
    with pytest.raises(FilterError, match="bad template"):
        registry.get("save_mesh")()(doc, path="{nope}.ply")


@pytest.mark.parametrize("kind", ["json", "mlx"])
def test_save_step_encoding_and_msh_version(kind, tmp_path):
    """save_mesh writes what ``meshopt convert --ascii --msh-version 2.2`` writes, from
    JSON and .mlx pipelines alike; the mesh reads back unchanged."""
    steps = [{"name": "save_mesh", "params": {"path": "{stem}.msh", "encoding": "ascii",
                                              "msh_version": "2.2"}},
             {"name": "save_mesh", "params": {"path": "{stem}_b.msh", "encoding": "binary"}}]
    path = tmp_path / f"p.{kind}"
    save_pipeline(Pipeline.from_dict({"filters": steps}), path)
    doc = Document([square5()])
    doc.output_dir = tmp_path / "out"
    doc.output_dir.mkdir()
    doc.variables = {"stem": "sq"}
    load_pipeline(path).run(doc)
    text = (doc.output_dir / "sq.msh").read_bytes()
    assert text.startswith(b"$MeshFormat\n2.2 0 8\n")  # version 2.2, ASCII (file type 0)
    assert (doc.output_dir / "sq_b.msh").read_bytes().startswith(b"$MeshFormat\n4.1 1 8\n")
    for name in ("sq.msh", "sq_b.msh"):
        back = load(doc.output_dir / name)
        np.testing.assert_array_equal(back.triangles, square5().triangles)
        np.testing.assert_array_equal(back.points, square5().points)


def test_run_file_records_errors_per_file(tmp_path):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 2 3\n")
    pipe = Pipeline.from_dict({"filters": [{"name": "meshing_uniform_refinement"}]})
    rec = run_file(pipe, bad, tmp_path)
    assert rec["status"] == "failed" and "bad.obj" in rec["error"]
    good = tmp_path / "good.msh"
    save(square5(), good)
    rec = run_file(pipe, good, tmp_path / "o", dry_run=True)
    assert rec["status"] == "ok" and not (tmp_path / "o").exists()
