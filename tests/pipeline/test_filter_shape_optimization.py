"""The apply_coord_shape_optimization filter through Python, JSON and .mlx."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshopt_toolkit.datasets import data_path
from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.io import load
from meshopt_toolkit.optimize import ProblemSpec, optimize
from meshopt_toolkit.pipeline import Document, Pipeline, load_pipeline, registry, save_pipeline
from meshopt_toolkit.fem.poisson import PoissonObjective

STEP = {"name": "apply_coord_shape_optimization",
        "params": {"variant": "complete-euclidean", "rhs": "1", "penalty": "0.1,0.01,0,0.5",
                   "max_iterations": 4, "tolerance": 0}}


@pytest.fixture(scope="module")
def disc():
    return load(data_path("disc_25.msh")).as_planar()


def _expected(mesh, method="lbfgs"):
    # the filter weighs j to the mesh by default (objective_scale "auto")
    return optimize(mesh, None, problem=ProblemSpec(rhs="1", scale="auto"),
                    variant="complete-euclidean", method=method,
                    penalty=(0.1, 0.01, 0, 0.5), max_iterations=4,
                    options=dict(tolerance=None))


def test_filter_with_scale_1_is_the_plain_library_call(disc):
    doc = Document([disc])
    registry.get(STEP["name"])()(doc, **STEP["params"], objective_scale="1")
    plain = optimize(disc, PoissonObjective(disc, rhs="1"), variant="complete-euclidean",
                     penalty=(0.1, 0.01, 0, 0.5), max_iterations=4,
                    options=dict(tolerance=None))
    np.testing.assert_allclose(doc.mesh.points, plain.x, rtol=0, atol=1e-12)


@pytest.mark.parametrize("kind", ["python", "json", "mlx"])
def test_filter_equals_library_call(kind, disc, tmp_path):
    doc = Document([disc])
    if kind == "python":
        summary = registry.get(STEP["name"])()(doc, **STEP["params"])
        assert summary["iterations"] == 4
    else:
        path = tmp_path / f"p.{kind}"
        if kind == "json":
            path.write_text(json.dumps({"filters": [STEP]}))
        else:
            save_pipeline(Pipeline.from_dict({"filters": [STEP]}), path)
            assert "Shape Optimization (meshopt)" in path.read_text()
        doc = load_pipeline(path).run(doc)
    expected = _expected(disc)
    np.testing.assert_allclose(doc.mesh.points, expected.x, rtol=0, atol=1e-12)
    assert not np.allclose(doc.mesh.points, disc.points)


def test_filter_refuses_unsafe_rhs_and_bad_beta(disc):
    f = registry.get("apply_coord_shape_optimization")()
    with pytest.raises(FilterError, match="rhs.*only calls of named functions"):
        f(Document([disc]), rhs="__import__('os').system('true')", max_iterations=1)
    with pytest.raises(FilterError, match="expected 4"):
        f(Document([disc]), penalty="1,2", max_iterations=1)


@pytest.mark.parametrize("method", ["cg", "steepest"])
def test_filter_method_parameter_selects_the_method(method, disc):
    doc = Document([disc])
    summary = registry.get(STEP["name"])()(doc, **{**STEP["params"], "method": method})
    assert summary["method"] == method
    np.testing.assert_allclose(doc.mesh.points, _expected(disc, method).x, rtol=0, atol=1e-12)
