"""Document ↔ pymeshlab.MeshSet: order, attributes, tags, several meshes."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import grid_mesh, square5
from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.io import load
from meshopt_toolkit.pipeline import Document, Pipeline

pymeshlab = pytest.importorskip("pymeshlab")


def test_round_trip_keeps_order_and_attributes(rng):
    mesh = grid_mesh(4, jitter=0.3)
    doc = Document([mesh])
    e = doc.current_entry
    n, t = mesh.n_vertices, mesh.n_triangles
    vals = {
        "vq": rng.standard_normal(n), "fq": rng.standard_normal(t),
        "vc": rng.uniform(0, 1, (n, 4)), "fc": rng.uniform(0, 1, (t, 4)),
        "vs": rng.standard_normal(n), "fp": rng.standard_normal((t, 3)),
    }
    e.set_vertex_attribute("quality", vals["vq"])
    e.set_face_attribute("quality", vals["fq"])
    e.set_vertex_attribute("color", vals["vc"])
    e.set_face_attribute("color", vals["fc"])
    e.set_vertex_attribute("temperature", vals["vs"])
    e.set_face_attribute("flux", vals["fp"])
    ms = doc.to_meshset()
    m = ms.current_mesh()
    np.testing.assert_array_equal(m.vertex_matrix()[:, :2], mesh.points)
    np.testing.assert_array_equal(m.face_matrix(), mesh.triangles)
    np.testing.assert_array_equal(m.face_scalar_array(), vals["fq"])
    np.testing.assert_array_equal(m.vertex_custom_scalar_attribute_array("temperature"), vals["vs"])
    back = Document.from_meshset(ms)
    assert back.mesh == mesh  # exact positions and connectivity, planar again
    doc.update_from_meshset(ms)
    a = doc.current_entry
    np.testing.assert_array_equal(a.vertex_attributes["quality"], vals["vq"])
    np.testing.assert_array_equal(a.face_attributes["quality"], vals["fq"])
    np.testing.assert_allclose(a.vertex_attributes["color"], vals["vc"], atol=1 / 255)  # 8-bit
    np.testing.assert_allclose(a.face_attributes["color"], vals["fc"], atol=1 / 255)
    np.testing.assert_array_equal(a.vertex_attributes["temperature"], vals["vs"])
    np.testing.assert_array_equal(a.face_attributes["flux"], vals["fp"])


def test_several_meshes_and_current():
    doc = Document([square5(), grid_mesh(2), grid_mesh(3)])
    doc.set_current(1)
    ms = doc.to_meshset()
    assert ms.mesh_number() == 3
    assert ms.current_mesh().vertex_number() == grid_mesh(2).n_vertices
    doc2 = Document.from_meshset(ms)
    assert doc2.current == 1 and [e.mesh for e in doc2.entries] == [e.mesh for e in doc.entries]
    with pytest.raises(FilterError, match="no mesh 5"):
        doc.set_current(5)
    with pytest.raises(FilterError, match="no mesh"):
        Document().mesh


def test_meshlab_step_keeps_tags_when_faces_unchanged():
    from meshopt_toolkit.datasets import data_path

    mesh = load(data_path("disc_77.msh"))
    pipe = Pipeline.from_dict({"filters": [
        {"name": "apply_coord_laplacian_smoothing", "params": {"stepsmoothnum": 1}}]})
    doc = pipe.run(Document([mesh]))
    out = doc.mesh
    np.testing.assert_array_equal(out.triangles, mesh.triangles)
    assert not np.array_equal(out.points, mesh.points)  # it did move
    if mesh.triangle_tags is not None:
        np.testing.assert_array_equal(out.triangle_tags, mesh.triangle_tags)
    assert out.tag_names == mesh.tag_names
    if mesh.lines is not None:
        np.testing.assert_array_equal(out.lines, mesh.lines)


def test_topology_change_drops_stale_attributes():
    mesh = grid_mesh(2)
    doc = Document([mesh])
    doc.current_entry.set_face_attribute("flux", np.ones(mesh.n_triangles))
    Pipeline.from_dict({"filters": [{"name": "meshing_surface_subdivision_midpoint",
                                     "params": {"iterations": 1, "threshold": {"abs": 0}}}]}).run(doc)
    assert doc.mesh.n_triangles == 4 * mesh.n_triangles
    assert "flux" not in doc.current_entry.face_attributes
    with pytest.raises(FilterError, match="needs"):
        doc.current_entry.set_face_attribute("x", np.ones(3))
