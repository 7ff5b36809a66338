"""The operation layer: ``mt.move``, ``mt.morph``, ``mt.deform`` and ``mt.optimize`` share
one result protocol, one callback convention and one error type for bad arguments, and
no public operation takes more than 12 parameters."""

from __future__ import annotations

import importlib
import inspect
import json

import numpy as np
import pytest
from conftest import grid_mesh

import meshopt_toolkit as mt
from meshopt_toolkit import strict_json
from meshopt_toolkit.errors import MeshoptError, OptionError
from meshopt_toolkit.fem.poisson import PoissonObjective
from meshopt_toolkit.kernels.triangles import signed_areas

#: the most parameters a public operation may take
MAX_PARAMETERS = 12


@pytest.fixture(scope="module")
def mesh():
    return grid_mesh(4, jitter=0.2, seed=3)


def _bent(mesh, amount=0.1):
    P = mesh.points
    bump = np.sin(np.pi * P[:, 0]) * np.sin(np.pi * P[:, 1])
    return mesh.with_points(P + amount * bump[:, None] * np.array([1.0, -0.5]))


def _turned(mesh, degrees=20.0):
    b = mesh.boundary_vertices
    c = mesh.points.mean(axis=0)
    a = np.radians(degrees)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return b, (mesh.points[b] - c) @ R.T + c


def _operations(mesh):
    handles, targets = _turned(mesh)
    V = np.zeros_like(mesh.points)
    V[mesh.boundary_vertices] = 0.05 * (mesh.points[mesh.boundary_vertices] - 0.5)
    return {
        "move": lambda: mt.move(mesh, handles, targets, frames=3),
        "morph": lambda: mt.morph(mesh, _bent(mesh), frames=3),
        "morph complete": lambda: mt.morph(mesh, _bent(mesh), frames=3, metric="complete"),
        "deform": lambda: mt.deform(mesh, V, frames=3),
        "optimize": lambda: mt.optimize(mesh, PoissonObjective(mesh), max_iterations=3,
                                        penalty=None),
    }


def test_morph_is_a_function():
    assert inspect.isfunction(mt.morph)
    assert "metric" in inspect.signature(mt.morph).parameters


@pytest.mark.parametrize("name", ["move", "morph", "morph complete", "deform", "optimize"])
def test_every_operation_returns_the_result_protocol(mesh, name):
    result = _operations(mesh)[name]()
    assert isinstance(result, mt.Result)
    frames = result.frames
    assert isinstance(frames, list) and len(frames) >= 2
    assert all(isinstance(f, mt.TriangleMesh) for f in frames)
    np.testing.assert_allclose(frames[0].points[:, :2], mesh.points[:, :2], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(frames[-1].points, result.mesh.points)
    for f in frames:
        np.testing.assert_array_equal(f.triangles, mesh.triangles)
        assert signed_areas(f.points, f.triangles).min() > 0
    summary = result.summary()
    assert isinstance(summary, dict)
    assert json.loads(strict_json.dumps(summary))["status"] == result.status
    assert isinstance(result.status, str) and result.status
    assert result.seconds > 0


def test_a_plain_object_is_not_a_result():
    from meshopt_toolkit.batch.run import BatchResult

    assert not isinstance(object(), mt.Result)
    assert not isinstance(BatchResult(), mt.Result)  # counts, not a mesh


def test_batch_summary_is_a_dict_and_report_the_line():
    from meshopt_toolkit.batch.run import BatchResult

    res = BatchResult(done=3, skipped=1, failed=1, seconds=2.5)
    summary = res.summary()
    assert summary == {"done": 3, "skipped": 1, "failed": 1, "dry_run": False,
                       "seconds": 2.5, "status": "failed"}
    assert json.loads(strict_json.dumps(summary)) == summary
    assert res.report() == "3 done, 1 skipped, 1 failed in 2.5 s"


#: the public operations on meshes and paths
OPERATIONS = ("move", "morph", "deform", "optimize", "discrete_geodesic", "geodesic", "exp_map")


def _public_calls():
    """Every function of ``mt.__all__`` and every options class (``*Options``)."""
    names = [n for n in mt.__all__ if not n.startswith("_")]
    return {n: getattr(mt, n) for n in names
            if inspect.isfunction(getattr(mt, n)) or n.endswith("Options")}


def test_no_public_operation_takes_more_than_12_parameters():
    calls = _public_calls()
    assert set(OPERATIONS) | {"log_map", "run_batch", "OptimizeOptions"} <= set(calls)
    counts = {n: len(inspect.signature(c).parameters) for n, c in calls.items()}
    assert {n: c for n, c in counts.items() if c > MAX_PARAMETERS} == {}


#: the filters' and the command line's names of the shared settings, and the short
#: names the public calls no longer take
VOCABULARY = {"max_iter": "max_iterations", "tol": "tolerance", "t": "time", "t_end": "time",
              "penalty_beta": "penalty", "ftol": "tolerance", "relax_iter": "relax_iterations"}


def test_public_calls_speak_the_filters_vocabulary():
    short = {n: sorted(set(inspect.signature(c).parameters) & set(VOCABULARY))
             for n, c in _public_calls().items()}
    assert {n: p for n, p in short.items() if p} == {}
    assert "max_iterations" in inspect.signature(mt.optimize).parameters
    assert "time" in inspect.signature(mt.deform).parameters


#: names the issue of one vocabulary retired everywhere, not only in the public calls
RETIRED = ("max_iter", "relax_iter", "ftol", "t_end", "penalty_beta")


def _package_callables():
    """Every public function, class and public method of every module of the package."""
    import pkgutil

    for info in pkgutil.walk_packages(mt.__path__, "meshopt_toolkit."):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != info.name:
                continue
            if inspect.isfunction(obj):
                yield f"{info.name}.{name}", obj
            elif inspect.isclass(obj):
                yield f"{info.name}.{name}", obj
                for attr, member in vars(obj).items():
                    if inspect.isfunction(member) and not attr.startswith("_"):
                        yield f"{info.name}.{name}.{attr}", member


def test_no_public_parameter_anywhere_has_a_retired_name():
    bad = {}
    for where, obj in _package_callables():
        try:
            params = inspect.signature(obj).parameters
        except (TypeError, ValueError):
            continue
        if found := sorted(set(params) & set(RETIRED)):
            bad[where] = found
    assert bad == {}


def test_the_parameter_count_test_sees_a_long_signature():
    def long(a, b, c, d, e, f, g, h, i, j, k, l, m):  # noqa: E741
        pass

    assert len(inspect.signature(long).parameters) > MAX_PARAMETERS


@pytest.mark.parametrize("name, call", [
    ("move frames", lambda m: mt.move(m, m.boundary_vertices, m.points[m.boundary_vertices],
                                      frames=1)),
    ("move steps", lambda m: mt.move(m, m.boundary_vertices, m.points[m.boundary_vertices],
                                     steps=0)),
    ("move weight", lambda m: mt.move(m, m.boundary_vertices, m.points[m.boundary_vertices],
                                      weight=-1.0)),
    ("morph frames", lambda m: mt.morph(m, m, frames=1)),
    ("morph metric", lambda m: mt.morph(m, m, metric="elastic")),
    ("morph max_iterations", lambda m: mt.morph(m, m, max_iterations=0)),
    ("morph weight with complete", lambda m: mt.morph(m, m, metric="complete", weight=2.0)),
    ("morph method", lambda m: mt.morph(m, m, metric=mt.CompleteMorph(method="newton"))),
    ("deform frames", lambda m: mt.deform(m, np.zeros_like(m.points), frames=1)),
    ("deform metric", lambda m: mt.deform(m, np.zeros_like(m.points), metric="elastic")),
    ("deform penalties", lambda m: mt.deform(m, np.zeros_like(m.points), alpha=(1, 0, 1),
                                             penalty=(1, 1, 0, 1))),
    ("optimize variant", lambda m: mt.optimize(m, PoissonObjective(m), variant="newton",
                                               penalty=None)),
    ("optimize method", lambda m: mt.optimize(m, PoissonObjective(m), method="newton",
                                              penalty=None)),
    ("optimize max_iterations", lambda m: mt.optimize(m, PoissonObjective(m), max_iterations=-1,
                                                      penalty=None)),
    ("optimize unknown option", lambda m: mt.optimize(m, PoissonObjective(m),
                                                      options={"step": 1.0}, penalty=None)),
    ("optimize tau", lambda m: mt.optimize(m, PoissonObjective(m), method="steepest",
                                           options={"tau": 2.0}, penalty=None)),
    ("optimize retraction", lambda m: mt.optimize(m, PoissonObjective(m),
                                                  options={"retraction": "cayley"}, penalty=None)),
])
def test_bad_arguments_raise_option_error(mesh, name, call):
    with pytest.raises(OptionError) as info:
        call(mesh)
    assert isinstance(info.value, MeshoptError) and isinstance(info.value, ValueError)


def test_optimize_options_object_and_mapping_agree(mesh):
    obj = PoissonObjective(mesh)
    a = mt.optimize(mesh, obj, max_iterations=4, penalty=None,
                    options=mt.OptimizeOptions(gtol=None, memory=3))
    b = mt.optimize(mesh, obj, max_iterations=4, penalty=None,
                    options={"gtol": None, "memory": 3})
    np.testing.assert_array_equal(a.x, b.x)


def test_callbacks_follow_one_convention(mesh):
    """``callback(record)`` once per iteration (True stops), ``progress(fraction)``."""
    seen, fractions = [], []

    def stop_at_two(record):
        seen.append(record)
        return record.iteration >= 2

    res = mt.optimize(mesh, PoissonObjective(mesh), max_iterations=50, callback=stop_at_two,
                      progress=fractions.append, options={"gtol": None, "tolerance": None},
                      penalty=None)
    assert res.status == "stopped" and res.nit == 2
    assert [r.iteration for r in seen] == [1, 2]
    np.testing.assert_array_equal(seen[-1].points, res.x)
    assert fractions == [1 / 50, 2 / 50]

    records, fractions = [], []
    morph = mt.morph(mesh, _bent(mesh, 0.2), frames=3, max_iterations=40,
                     callback=lambda r: records.append(r) or True, progress=fractions.append)
    assert morph.status == "stopped" and len(records) == 1
    assert isinstance(records[0], mt.PathIteration) and records[0].energy > 0
    assert fractions == [0.0]
    assert all(signed_areas(f.points, f.triangles).min() > 0 for f in morph.frames)


def test_the_operations_stay_calls_after_their_modules_are_imported():
    import importlib
    import subprocess
    import sys

    code = ("import meshopt_toolkit as mt, meshopt_toolkit.optimize, meshopt_toolkit.deform, "
            "meshopt_toolkit.motion.move, meshopt_toolkit.operations\n"
            "from meshopt_toolkit.optimize import OptimizeOptions\n"
            "import inspect\n"
            "assert all(inspect.isfunction(f) for f in (mt.optimize, mt.deform, mt.move, mt.morph))\n")
    subprocess.run([sys.executable, "-c", code], check=True)
    assert inspect.ismodule(importlib.import_module("meshopt_toolkit.deform"))


def test_without_frames_the_path_is_the_input_and_the_result(mesh):
    handles, targets = _turned(mesh, 10.0)
    moved = mt.move(mesh, handles, targets)
    deformed = mt.deform(mesh, np.zeros_like(mesh.points))
    for result in (moved, deformed):
        first, last = result.frames
        assert first.points is mesh.points or np.array_equal(first.points, mesh.points)
        assert np.array_equal(last.points, result.mesh.points)
