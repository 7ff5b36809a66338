"""The apply_coord_quality_preserving_deformation filter through Python, JSON and .mlx."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshopt_toolkit.datasets import data_path
from meshopt_toolkit.deform import deform
from meshopt_toolkit.errors import FilterError, InvalidMeshError
from meshopt_toolkit.kernels.triangles import signed_areas
from meshopt_toolkit.io import load
from meshopt_toolkit.pipeline import Document, Pipeline, load_pipeline, registry, save_pipeline

NAME = "apply_coord_quality_preserving_deformation"


@pytest.fixture(scope="module")
def disc():
    return load(data_path("disc_25.msh")).as_planar()


def squeeze(mesh):
    """Boundary-only velocity that flattens the disc: its Euclidean path inverts at t = 1."""
    V = np.zeros_like(mesh.points)
    b = mesh.boundary_vertices
    V[b, 1] = -1.2 * mesh.points[b, 1]
    return V


@pytest.mark.parametrize("kind", ["python", "json", "mlx"])
def test_filter_equals_library_and_never_inverts(kind, disc, tmp_path):
    V = squeeze(disc)
    np.save(tmp_path / "v.npy", V)
    assert signed_areas(disc.points + V, disc.triangles).min() <= 0  # the straight path fails
    step = {"name": NAME, "params": {"displacement": str(tmp_path / "v.npy"), "time": 1.0}}
    doc = Document([disc])
    if kind == "python":
        registry.get(NAME)()(doc, **step["params"])
    else:
        path = tmp_path / f"p.{kind}"
        if kind == "json":
            path.write_text(json.dumps({"filters": [step]}))
        else:
            save_pipeline(Pipeline.from_dict({"filters": [step]}), path)
        doc = load_pipeline(path).run(doc)
    expected = deform(disc, V, time=1.0).mesh.points
    np.testing.assert_allclose(doc.mesh.points, expected, rtol=0, atol=1e-12)
    assert signed_areas(doc.mesh.points, disc.triangles).min() > 0


def test_filter_errors(disc, tmp_path):
    f = registry.get(NAME)()
    with pytest.raises(FilterError, match="required"):
        f(Document([disc]))
    np.save(tmp_path / "bad.npy", np.zeros((3, 2)))
    with pytest.raises(InvalidMeshError, match="shape"):
        f(Document([disc]), displacement=str(tmp_path / "bad.npy"))
    np.save(tmp_path / "v.npy", squeeze(disc))
    with pytest.raises(FilterError, match="not both"):
        f(Document([disc]), displacement=str(tmp_path / "v.npy"), alpha="1,0,1", beta="1,1,0,1")
