"""Fuzz of the pipeline loader: random bytes and mutated valid pipelines, JSON
and MeshLab .mlx, raise only MeshoptError (one line for the CLI), never hang, and a bad
expression in a filter parameter is refused when the pipeline is checked."""

from __future__ import annotations

import json
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from meshopt_toolkit.errors import FilterError, MeshoptError
from meshopt_toolkit.pipeline import Pipeline, load_pipeline, save_pipeline

VALID = {"filters": [
    {"name": "meshing_uniform_refinement", "params": {"iterations": 1}},
    {"name": "apply_coord_shape_optimization", "params": {"max_iterations": 2, "rhs": "x**2 + y"}},
    {"name": "compute_scalar_by_shape_quality_per_face", "params": {}},
]}

SETTINGS = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def _load(path):
    t0 = time.perf_counter()
    try:
        load_pipeline(path)
    except MeshoptError:
        pass
    assert time.perf_counter() - t0 < 5.0


@SETTINGS
@given(data=st.binary(max_size=2000), suffix=st.sampled_from([".json", ".mlx"]))
def test_random_bytes_raise_only_meshopt_errors(tmp_path, data, suffix):
    path = tmp_path / f"p{suffix}"
    path.write_bytes(data)
    _load(path)


@pytest.fixture(scope="module")
def valid_texts(tmp_path_factory):
    folder = tmp_path_factory.mktemp("valid")
    save_pipeline(Pipeline.from_dict(VALID), folder / "p.mlx")
    return {".json": json.dumps(VALID).encode(), ".mlx": (folder / "p.mlx").read_bytes()}


@SETTINGS
@given(suffix=st.sampled_from([".json", ".mlx"]),
       edits=st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255),
                                st.sampled_from(["replace", "insert", "delete"])),
                      min_size=1, max_size=8))
def test_mutated_pipelines_raise_only_meshopt_errors(tmp_path, valid_texts, suffix, edits):
    data = bytearray(valid_texts[suffix])
    for pos, byte, kind in edits:
        i = pos % (len(data) + 1)
        if kind == "insert":
            data.insert(i, byte)
        elif data and i < len(data):
            if kind == "replace":
                data[i] = byte
            else:
                del data[i]
    path = tmp_path / f"p{suffix}"
    path.write_bytes(bytes(data))
    _load(path)


@pytest.mark.parametrize("rhs", ["1/0", "log(-1)", "x + q", "x +", "x + z"])
def test_bad_rhs_is_refused_when_the_pipeline_is_checked(rhs):
    bad = {"filters": [{"name": "apply_coord_shape_optimization", "params": {"rhs": rhs}}]}
    with pytest.raises(FilterError, match="rhs"):
        Pipeline.from_dict(bad).validate()
