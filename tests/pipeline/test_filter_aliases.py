"""Pipelines saved with the former filter and parameter names keep running, and give what
the current names give; the CLI's former option spellings keep working."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meshopt_toolkit.cli import build_parser, main
from meshopt_toolkit.datasets import data_path
from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.io import load
from meshopt_toolkit.pipeline import Document, Pipeline, load_pipeline, registry

#: the names the filters had before they were named in pymeshlab's style (apply_coord_*
#: for the filters that move vertices), written out here rather than read from the code
FORMER = {
    "apply_prescribed_motion": "apply_coord_prescribed_motion",
    "apply_quality_preserving_deformation": "apply_coord_quality_preserving_deformation",
    "compute_shape_optimization": "apply_coord_shape_optimization",
}
CURRENT = {"apply_coord_prescribed_motion", "apply_coord_quality_preserving_deformation",
           "apply_coord_shape_optimization", "compute_scalar_by_shape_quality_per_face",
           "generate_geodesic_morph", "load_mesh", "meshing_uniform_refinement", "save_mesh"}


@pytest.fixture(scope="module")
def disc():
    return load(data_path("disc_25.msh")).as_planar()


@pytest.fixture
def velocity(disc, tmp_path):
    V = np.zeros_like(disc.points)
    b = disc.boundary_vertices
    V[b, 1] = -0.6 * disc.points[b, 1]
    np.save(tmp_path / "v.npy", V)
    return str(tmp_path / "v.npy")


@pytest.mark.parametrize("old, new", FORMER.items())
def test_former_name_finds_the_renamed_filter(old, new):
    assert registry.get(old).name == new
    assert registry.get(old) is registry.get(new)
    assert old in registry.get(new).aliases


@pytest.mark.parametrize("label, name", [
    ("Prescribed Motion (meshopt)", "apply_coord_prescribed_motion"),
    ("Quality Preserving Deformation (meshopt)", "apply_coord_quality_preserving_deformation"),
    ("Shape Optimization (meshopt)", "apply_coord_shape_optimization"),
    ("Per Face Shape Quality (meshopt)", "compute_scalar_by_shape_quality_per_face"),
    ("Geodesic Morph (meshopt)", "generate_geodesic_morph"),
    ("Uniform Refinement (meshopt)", "meshing_uniform_refinement"),
])
def test_meshlab_labels_of_saved_scripts_are_unchanged(label, name):
    # .mlx scripts name filters by label: the labels stayed as they were
    assert registry.get(name).label == label


def test_every_builtin_module_is_named_as_its_filter():
    import importlib
    import pkgutil

    import meshopt_toolkit.filters as pkg

    modules = {i.name for i in pkgutil.iter_modules(pkg.__path__) if not i.name.startswith("_")}
    assert modules == CURRENT
    for name in modules:
        module = importlib.import_module(f"meshopt_toolkit.filters.{name}")
        assert [c.name for c in vars(module).values()
                if isinstance(c, type) and getattr(c, "__module__", "") == module.__name__
                and hasattr(c, "parameters")] == [name]


def test_filters_lists_current_names_only(capsys):
    assert main(["filters"]) == 0
    listed = {line.split()[0] for line in capsys.readouterr().out.splitlines() if line}
    assert CURRENT <= listed
    assert not listed & set(FORMER)
    assert main(["filters", "apply_quality_preserving_deformation"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("apply_coord_quality_preserving_deformation")
    assert "also: apply_quality_preserving_deformation" in out
    assert "penalty : string = '' (also: beta)" in out


def _steps(velocity, *, former: bool, penalties: bool = True) -> list[dict]:
    """Move, deform, optimize and morph: under the former or the current names."""
    name = {v: k for k, v in FORMER.items()} if former else {}
    deform = {"displacement": velocity, "time": 0.5}
    morph = {"source": 0, "frames": 3, "metric": "scalar"}
    if penalties and former:
        deform["beta"] = "10,1,0,2.5"
        morph.update(beta1=1.0, beta2=0.5, beta4=2.0)  # beta3 left out: its default 0
    elif penalties:
        deform["penalty"] = "10,1,0,2.5"
        morph["penalty"] = "1,0.5,0,2"
    steps = [("apply_coord_prescribed_motion", {"map": "1.1*x; y", "steps": 2}),
             ("apply_coord_quality_preserving_deformation", deform),
             ("apply_coord_shape_optimization",
              {"variant": "complete-euclidean", "rhs": "1", "penalty": "0.1,0.01,0,0.5",
               "max_iterations": 2, "tolerance": 0}),
             ("generate_geodesic_morph", morph)]
    return [{"name": name.get(n, n), "params": p} for n, p in steps]


def _run(pipeline: Pipeline, disc) -> Document:
    # mesh 0 stays as read (the morph's source), mesh 1 is moved by the steps
    return pipeline.run(Document([disc, disc]))


def _points(doc: Document) -> list[np.ndarray]:
    return [e.mesh.points for e in doc.entries]


def test_json_saved_with_former_names_runs_as_the_current_names(disc, velocity, tmp_path):
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"filters": _steps(velocity, former=True)}))
    pipeline = load_pipeline(old)
    # written back, the pipeline uses the current names
    saved = pipeline.to_dict()["filters"]
    assert [s["name"] for s in saved] == [s["name"] for s in _steps(velocity, former=False)]
    assert "penalty" in saved[1]["params"] and "beta" not in saved[1]["params"]
    assert saved[3]["params"]["penalty"] == "1.0,0.5,0.0,2.0"
    assert not {"beta1", "beta2", "beta3", "beta4"} & set(saved[3]["params"])

    got = _run(pipeline, disc)
    want = _run(Pipeline.from_dict({"filters": _steps(velocity, former=False)}), disc)
    assert len(got) == len(want) == 5
    for a, b in zip(_points(got), _points(want)):
        assert np.array_equal(a, b)
    timing = {"seconds", "wall_seconds", "elapsed"}
    assert [{k: v for k, v in r.items() if k not in timing} for r in got.results] == \
        [{k: v for k, v in r.items() if k not in timing} for r in want.results]
    # the former parameters' values were used: without them the meshes differ
    plain = _run(Pipeline.from_dict({"filters": _steps(velocity, former=False,
                                                       penalties=False)}), disc)
    assert not np.allclose(_points(plain)[1], _points(got)[1])  # the deformation's β
    assert not np.allclose(_points(plain)[3], _points(got)[3])  # the morph's middle frame


def _param(kind: str, name: str, value: str, extra: str = "") -> str:
    return f'  <Param type="{kind}" name="{name}" value="{value}" description="{name}" ' \
           f'tooltip=""{extra}/>\n'


def _former_mlx(velocity: str) -> str:
    """A filter script as the filters wrote it before the renames: MeshLab labels, the
    deformation's ``beta`` string and the morph's four floats ``beta1`` … ``beta4``."""
    metric = ' enum_cardinality="2" enum_val0="distortion" enum_val1="scalar"'
    method = ' enum_cardinality="3" enum_val0="discrete" enum_val1="shooting" enum_val2="auto"'
    return (
        "<!DOCTYPE FilterScript>\n<FilterScript>\n"
        ' <filter name="Quality Preserving Deformation (meshopt)">\n'
        + _param("RichOpenFile", "displacement", velocity)
        + _param("RichFloat", "time", "0.5", ' min="0"')
        + _param("RichString", "alpha", "")
        + _param("RichString", "beta", "10,1,0,2.5")
        + " </filter>\n"
        ' <filter name="Geodesic Morph (meshopt)">\n'
        + _param("RichInt", "source", "0")
        + _param("RichInt", "target", "-1")
        + _param("RichInt", "frames", "3", ' min="2" max="1000"')
        + _param("RichEnum", "metric", "1", metric)
        + _param("RichFloat", "weight", "1", ' min="0"')
        + _param("RichFloat", "beta1", "1", ' min="0"')
        + _param("RichFloat", "beta2", "0.5", ' min="0"')
        + _param("RichFloat", "beta3", "0", ' min="0"')
        + _param("RichFloat", "beta4", "2", ' min="0"')
        + _param("RichBool", "normalize", "true")
        + _param("RichEnum", "method", "0", method)
        + " </filter>\n</FilterScript>\n"
    )


def test_mlx_saved_with_former_parameters_runs_as_the_current_ones(disc, velocity, tmp_path):
    old = tmp_path / "old.mlx"
    old.write_text(_former_mlx(velocity))
    got = _run(load_pipeline(old), disc)
    current = _steps(velocity, former=False)
    want = _run(Pipeline.from_dict({"filters": [current[1], current[3]]}), disc)
    assert len(got) == len(want) == 5
    for a, b in zip(_points(got), _points(want)):
        assert np.array_equal(a, b)
    # a script naming a filter by its former name works as well
    by_name = old.read_text().replace('"Quality Preserving Deformation (meshopt)"',
                                      '"apply_quality_preserving_deformation"')
    old.write_text(by_name)
    assert np.array_equal(_run(load_pipeline(old), disc).entries[1].mesh.points,
                          _points(want)[1])


@pytest.mark.parametrize("params, fragment", [
    ({"beta": "1,1,0,1", "penalty": "1,1,0,1"}, "give 'penalty' or its former name 'beta'"),
])
def test_former_and_current_parameter_together_is_refused(params, fragment):
    cls = registry.get("apply_quality_preserving_deformation")
    with pytest.raises(FilterError, match=fragment):
        cls.validate_params(params)


@pytest.mark.parametrize("params, fragment", [
    ({"beta2": 1.0, "penalty": "1,1,0,1"}, "give 'penalty' or its former beta2"),
    ({"beta1": "one"}, "parameter 'beta1': expected a number"),
    ({"beta1": -1.0}, "non-negative"),
])
def test_former_morph_betas_are_checked(params, fragment):
    with pytest.raises(FilterError, match=fragment):
        registry.get("generate_geodesic_morph").validate_params(params)


@pytest.mark.parametrize("command, words, dest, value", [
    ("optimize", ["--max-iter", "7"], "max_iterations", 7),
    ("optimize", ["--max-iterations", "7"], "max_iterations", 7),
    ("optimize", ["--tol", "0.5"], "tolerance", 0.5),
    ("optimize", ["--tolerance", "0.5"], "tolerance", 0.5),
    ("morph", ["a", "b", "-o", "o", "--max-iter", "7"], "max_iterations", 7),
    ("morph", ["a", "b", "-o", "o", "--max-iterations", "7"], "max_iterations", 7),
    ("morph", ["a", "b", "-o", "o", "--beta", "1,2,0,3"], "beta", (1.0, 2.0, 0.0, 3.0)),
    ("morph", ["a", "b", "-o", "o", "--penalty", "1,2,0,3"], "beta", (1.0, 2.0, 0.0, 3.0)),
    ("deform", ["m", "-o", "o", "--displacement", "v", "--beta", "1,2,0,3"], "penalty",
     (1.0, 2.0, 0.0, 3.0)),
    ("deform", ["m", "-o", "o", "--displacement", "v", "--penalty", "1,2,0,3"], "penalty",
     (1.0, 2.0, 0.0, 3.0)),
])
def test_cli_former_spellings_set_the_same_option(command, words, dest, value):
    args = build_parser(command).parse_args([command, *words])
    assert tuple(np.atleast_1d(getattr(args, dest))) == tuple(np.atleast_1d(value))


def test_registry_refuses_an_alias_taken_by_another_filter():
    from meshopt_toolkit.pipeline.filter import Filter, FilterRegistry

    reg = FilterRegistry(builtin_package=None, group=None)

    class A(Filter):
        name, label, description = "meshing_a", "A (test)", "a"

    class B(Filter):
        name, label, description = "meshing_b", "B (test)", "b"
        aliases = ("meshing_a",)

    reg.register(A)
    with pytest.raises(FilterError, match="'meshing_a' already used by 'meshing_a'"):
        reg.register(B)


def test_docs_table_lists_every_filter_and_its_former_name():
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "pipelines.md").read_text()
    section = text.split("## Filter names and parameters")[1].split("\n## ")[0]
    rows = [r for r in section.splitlines() if r.startswith("| `")]
    named = {}
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        for name in re.findall(r"`([a-z_]+)`", cells[0]):
            named[name] = re.findall(r"`([a-z_]+)`", cells[-1])
    filters = {n: f for n, f in named.items() if n in CURRENT}
    assert set(filters) == CURRENT
    for name, former in filters.items():
        assert tuple(former) == registry.get(name).aliases, name
