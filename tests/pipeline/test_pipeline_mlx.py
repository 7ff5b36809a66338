"""MeshLab .mlx scripts: pymeshlab-saved scripts run, write → read round trips, hostile XML."""

from __future__ import annotations

import time

import numpy as np
import pytest

from conftest import grid_mesh
from meshopt_toolkit.conversions import to_pymeshlab
from meshopt_toolkit.errors import FilterError, MeshoptError
from meshopt_toolkit.pipeline import Document, Pipeline, load_pipeline, registry, save_pipeline
from meshopt_toolkit.pipeline import mlx
from test_pipeline_params import AllKinds

pymeshlab = pytest.importorskip("pymeshlab")


@pytest.fixture
def all_kinds():
    registry.register(AllKinds)
    yield AllKinds
    registry.unregister(AllKinds.name)


def _pymeshlab_script(tmp_path, mesh):
    """A script saved by pymeshlab itself (labels, camelCase names, all Rich types)."""
    ms = pymeshlab.MeshSet()
    ms.add_mesh(to_pymeshlab(mesh))
    ms.meshing_surface_subdivision_midpoint(iterations=1, threshold=pymeshlab.PureValue(0))
    ms.compute_scalar_by_aspect_ratio_per_face(metric="Mean ratio")
    ms.compute_selection_by_scalar_per_face(minq=0.0, maxq=0.95)
    ms.apply_coord_laplacian_smoothing(stepsmoothnum=2, selected=True)
    ms.compute_color_from_scalar_per_face(colormap="Viridis")
    path = tmp_path / "saved.mlx"
    ms.save_filter_script(str(path))
    return path


def _run_with_pymeshlab(path, mesh):
    ms = pymeshlab.MeshSet()
    ms.add_mesh(to_pymeshlab(mesh))
    ms.load_filter_script(str(path))
    ms.apply_filter_script()
    return ms, ms.current_mesh()  # the mesh is only valid while its MeshSet lives


def test_pymeshlab_saved_script_runs_unchanged(tmp_path):
    mesh = grid_mesh(4, jitter=0.3)
    path = _pymeshlab_script(tmp_path, mesh)
    pipe = load_pipeline(path)
    assert [s.kind for s in pipe.steps] == ["meshlab"] * 5
    assert pipe.steps[0].name == "meshing_surface_subdivision_midpoint"
    assert pipe.steps[3].name == "apply_coord_laplacian_smoothing"
    doc = pipe.run(Document([mesh]))
    _ms, ref = _run_with_pymeshlab(path, mesh)  # pymeshlab's own script runner is the reference
    np.testing.assert_array_equal(doc.mesh.triangles, ref.face_matrix())
    np.testing.assert_allclose(doc.mesh.points, ref.vertex_matrix()[:, :2], rtol=0, atol=1e-15)
    np.testing.assert_allclose(doc.current_entry.face_attributes["quality"], ref.face_scalar_array())
    np.testing.assert_allclose(doc.current_entry.face_attributes["color"], ref.face_color_matrix())


def test_meshlab_steps_written_back_unchanged(tmp_path):
    """Our written .mlx of a pymeshlab script runs in pymeshlab with the same result."""
    mesh = grid_mesh(3, jitter=0.2, seed=3)
    src = _pymeshlab_script(tmp_path, mesh)
    out = tmp_path / "ours.mlx"
    save_pipeline(load_pipeline(src), out)
    _ma, a = _run_with_pymeshlab(src, mesh)
    _mb, b = _run_with_pymeshlab(out, mesh)
    np.testing.assert_array_equal(a.vertex_matrix(), b.vertex_matrix())
    assert load_pipeline(out).to_dict() == load_pipeline(src).to_dict()


def test_write_read_preserves_parameters(tmp_path, all_kinds):
    params = {"flag": False, "count": 9, "weight": 0.123456789, "free": -2e-7,
              "mode": "Area", "note": "a <b> & 'c' \"d\"\n", "target": "x/{stem}_y.obj",
              "size": "7.5%"}
    pipe = Pipeline.from_dict({"filters": [
        {"name": "test_all_kinds", "params": params},
        {"name": "meshing_uniform_refinement", "params": {"iterations": 3}},
        {"name": "Per Face Shape Quality (meshopt)", "params": {"metric": "aspect ratio 2r/R"}},
    ]})
    path = tmp_path / "p.mlx"
    save_pipeline(pipe, path)
    text = path.read_text()
    assert text.startswith("<!DOCTYPE FilterScript>")
    assert '<filter name="Test All Kinds">' in text
    back = load_pipeline(path)
    assert back.to_dict() == pipe.to_dict()
    vals = back.validate()[0]
    assert vals["weight"] == 0.123456789 and vals["free"] == -2e-7  # full precision kept
    assert vals["note"] == params["note"]
    with pytest.raises(MeshoptError, match="exists"):
        save_pipeline(pipe, path)
    save_pipeline(pipe, path, overwrite=True)


def test_absperc_with_diameter_is_absolute(all_kinds):
    pipe = Pipeline.from_dict({"filters": [{"name": "test_all_kinds", "params": {"size": "10%"}}]})
    text = mlx.dumps(pipe, diameter=3.0)
    back = mlx.loads(text)
    assert back.validate()[0]["size"].resolve(123.0) == pytest.approx(0.3)


HOSTILE = {
    "billion laughs": """<?xml version="1.0"?>
<!DOCTYPE FilterScript [
 <!ENTITY a "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa">
 <!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">
 <!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">
 <!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;">
 <!ENTITY e "&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;">
 <!ENTITY f "&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;">
]>
<FilterScript><filter name="&f;"/></FilterScript>""",
    "external entity": """<?xml version="1.0"?>
<!DOCTYPE FilterScript [<!ENTITY x SYSTEM "file:///etc/passwd">]>
<FilterScript><filter name="&x;"/></FilterScript>""",
    "external dtd": """<?xml version="1.0"?>
<!DOCTYPE FilterScript SYSTEM "http://example.invalid/evil.dtd">
<FilterScript><filter name="Laplacian Smooth"/></FilterScript>""",
    "parameter entity": """<?xml version="1.0"?>
<!DOCTYPE FilterScript [<!ENTITY % p SYSTEM "http://example.invalid/p.dtd"> %p;]>
<FilterScript/>""",
}


@pytest.mark.parametrize("kind", sorted(HOSTILE))
def test_hostile_xml_refused_fast(tmp_path, kind):
    path = tmp_path / "evil.mlx"
    path.write_text(HOSTILE[kind])
    t0 = time.perf_counter()
    with pytest.raises(FilterError, match="refused") as info:
        load_pipeline(path)
    assert time.perf_counter() - t0 < 2.0
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("<FilterScript><filter name='Laplacian Smooth'>", "malformed XML at line 1"),
        ("<FilterScript><filter name='No Such Filter At All'/></FilterScript>", "unknown filter"),
        ("<FilterScript><filter name='Laplacian Smoth'/></FilterScript>",
         "did you mean 'apply_coord_laplacian_smoothing'"),
        ("<FilterScript><filter name='Uniform Refinement (meshopt)'>"
         "<Param type='RichInt' name='iteratoins' value='2'/></filter></FilterScript>",
         "did you mean 'iterations'"),
        ("<FilterScript><filter name='Uniform Refinement (meshopt)'>"
         "<Param type='RichInt' name='iterations' value='two'/></filter></FilterScript>",
         "expected an integer"),
        ("<FilterScript><filter name='Laplacian Smooth'>"
         "<Param type='RichInt' name='stepSmoothNum'/></filter></FilterScript>", "malformed"),
        ("<FilterScript><filter/></FilterScript>", "without a name"),
        ("<Project/>", "not a MeshLab filter script"),
        ("", "malformed XML"),
    ],
)
def test_bad_scripts_give_clear_errors(text, fragment):
    with pytest.raises(FilterError, match=None) as info:
        mlx.loads(text, "bad.mlx")
    assert fragment in str(info.value)
    assert str(info.value).startswith("bad.mlx: ")


def test_unknown_meshlab_parameter_caught_before_running():
    text = ("<FilterScript><filter name='Laplacian Smooth'>"
            "<Param type='RichInt' name='stepSmoothNumber' value='2'/></filter></FilterScript>")
    pipe = mlx.loads(text)
    with pytest.raises(FilterError, match="did you mean 'stepsmoothnum'"):
        pipe.validate()


def test_gpu_filter_refused_up_front():
    pipe = Pipeline.from_dict({"filters": [{"name": "compute_scalar_ambient_occlusion_gpu"}]})
    with pytest.raises(FilterError, match="aborts the whole process"):
        pipe.validate()


def test_oversized_script_refused(tmp_path):
    path = tmp_path / "big.mlx"
    path.write_bytes(b"<FilterScript>" + b" " * (mlx.MAX_BYTES + 1) + b"</FilterScript>")
    with pytest.raises(FilterError, match="larger than"):
        load_pipeline(path)


def test_json_write_read_round_trip(tmp_path, all_kinds):
    pipe = Pipeline.from_dict({"filters": [
        {"name": "test_all_kinds", "params": {"size": 0.25, "mode": 0, "count": "4"}},
        {"name": "Laplacian Smooth", "params": {"stepsmoothnum": 2}},
        {"name": "meshing_surface_subdivision_midpoint", "params": {"threshold": "1%"}},
    ]})
    path = tmp_path / "p.json"
    save_pipeline(pipe, path)
    back = load_pipeline(path)
    assert back.to_dict() == pipe.to_dict()
    vals = back.validate()
    assert vals[0]["size"].resolve(10.0) == 0.25 and vals[0]["mode"] == "area/max side"
    assert vals[0]["count"] == 4
    assert [s.kind for s in back.steps] == ["meshopt", "meshlab", "meshlab"]
    assert back.steps[1].name == "apply_coord_laplacian_smoothing"


def test_json_meshlab_steps_written_as_real_meshlab_script(tmp_path):
    """MeshLab steps given in JSON are written with MeshLab labels and camelCase Params
    (recorded by pymeshlab), so pymeshlab's own script loader runs our file."""
    pipe = Pipeline.from_dict({"filters": [
        {"name": "meshing_surface_subdivision_midpoint", "params": {"iterations": 1, "threshold": 0}},
        {"name": "apply_coord_laplacian_smoothing", "params": {"stepsmoothnum": 3, "cotangentweight": False}},
        {"name": "compute_scalar_by_aspect_ratio_per_face", "params": {"metric": "Mean ratio"}},
    ]})
    path = tmp_path / "j.mlx"
    save_pipeline(pipe, path)
    text = path.read_text()
    assert '<filter name="Laplacian Smooth">' in text and 'name="stepSmoothNum"' in text
    assert 'enum_cardinality="8"' in text
    mesh = grid_mesh(3, jitter=0.3)
    _ms, got = _run_with_pymeshlab(path, mesh)
    ref = pymeshlab.MeshSet()
    ref.add_mesh(to_pymeshlab(mesh))
    ref.meshing_surface_subdivision_midpoint(iterations=1, threshold=pymeshlab.PureValue(0))
    ref.apply_coord_laplacian_smoothing(stepsmoothnum=3, cotangentweight=False)
    ref.compute_scalar_by_aspect_ratio_per_face(metric="Mean ratio")
    np.testing.assert_array_equal(got.vertex_matrix(), ref.current_mesh().vertex_matrix())
    np.testing.assert_array_equal(got.face_scalar_array(), ref.current_mesh().face_scalar_array())
    back = load_pipeline(path).to_dict()["filters"]
    assert back[1]["params"]["stepsmoothnum"] == 3 and back[1]["params"]["cotangentweight"] is False


def test_bounded_float_not_clamped_when_recorded(tmp_path):
    pipe = Pipeline.from_dict({"filters": [
        {"name": "compute_selection_by_scalar_per_face", "params": {"minq": 2.5, "maxq": 7.25}}]})
    path = tmp_path / "s.mlx"
    save_pipeline(pipe, path)
    params = load_pipeline(path).to_dict()["filters"][0]["params"]
    assert (params["minq"], params["maxq"]) == (2.5, 7.25)


def test_label_resolution_agrees_with_pymeshlab_reader(tmp_path):
    """Our label → name mapping equals what pymeshlab's own script reader makes of it."""
    from meshopt_toolkit.pipeline import meshlab

    labels = ["Subdivision Surfaces: Midpoint", "Laplacian Smooth", "Select by Face Quality",
              "Per Face Quality according to Triangle shape and aspect ratio",
              "Colorize by face Quality", "Tri to Quad by 4-8 Subdivision", "Merge Close Vertices"]
    path = tmp_path / "labels.mlx"
    path.write_text("<!DOCTYPE FilterScript>\n<FilterScript>\n"
                    + "".join(f' <filter name="{lab}"/>\n' for lab in labels) + "</FilterScript>\n")
    ms = pymeshlab.MeshSet()
    ms.load_filter_script(str(path))
    printed = meshlab._capture_stdout(ms.print_filter_script)
    old_names = [line.split(": ", 1)[1].strip() for line in printed.splitlines()
                 if line[:1].isdigit() and ": " in line]
    assert old_names == [meshlab.snake_case(lab) for lab in labels]
    keys = meshlab.keys_table()
    for lab, old in zip(labels, old_names):
        assert meshlab.resolve(lab) == keys[old]
        assert meshlab.resolve(lab) in pymeshlab.filter_list()
