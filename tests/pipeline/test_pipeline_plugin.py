"""Entry-point plugins: discovered lazily, broken ones warn, plugin filters run in pipelines."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import square5
from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load, save
from meshopt_toolkit.pipeline import Document, FilterRegistry, PluginWarning

HERE = Path(__file__).parents[1]


def make_plugin_dir(tmp_path: Path, broken: bool = True) -> Path:
    """The demo plugin plus a hand-written dist-info, as pip would install it."""
    site = tmp_path / "site"
    shutil.copytree(HERE / "plugin_pkg" / "meshopt_demo_plugin", site / "meshopt_demo_plugin")
    info = site / "meshopt_demo_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: meshopt-demo-plugin\nVersion: 0.1\n")
    lines = ["[meshopt_toolkit.filters]",
             "demo_scale = meshopt_demo_plugin:DemoScale",
             "demo_crash = meshopt_demo_plugin:DemoCrash"]
    if broken:
        lines += ["demo_missing = meshopt_demo_plugin:NoSuchClass",
                  "demo_import = meshopt_no_such_module:Thing"]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return site


@pytest.fixture
def plugin_path(tmp_path, monkeypatch):
    site = make_plugin_dir(tmp_path)
    monkeypatch.syspath_prepend(str(site))
    yield site
    for mod in [m for m in sys.modules if m.startswith("meshopt_demo_plugin")]:
        del sys.modules[mod]


def test_plugin_discovered_lazily_and_broken_ones_warn(plugin_path):
    reg = FilterRegistry(builtin_package=None)
    assert reg._plugins_loaded is False  # nothing loaded at construction
    with pytest.warns(PluginWarning) as record:
        cls = reg.get("demo_scale")
    messages = " ".join(str(w.message) for w in record)
    assert "demo_missing" in messages and "demo_import" in messages
    assert cls.origin == "meshopt-demo-plugin"
    assert set(reg.names()) == {"demo_scale", "demo_crash"}
    assert reg.get("Demo Scale (plugin)") is cls
    doc = Document([square5()])
    assert cls()(doc, factor=3.0) == {"factor": 3.0}
    np.testing.assert_array_equal(doc.mesh.points, 3 * square5().points)


@pytest.fixture
def global_plugins(tmp_path, monkeypatch):
    """The process-wide registry re-reads entry points with the demo plugin on the path;
    PYTHONPATH carries it into worker processes."""
    from meshopt_toolkit.pipeline import registry

    site = make_plugin_dir(tmp_path, broken=False)
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.setattr(registry, "_plugins_loaded", False)
    monkeypatch.chdir(tmp_path)
    yield site
    for name in ("demo_scale", "demo_crash"):
        registry.unregister(name)
    for mod in [m for m in sys.modules if m.startswith("meshopt_demo_plugin")]:
        del sys.modules[mod]


def test_plugin_filter_runs_in_meshopt_run_and_is_listed(tmp_path, global_plugins, capsys):
    save(square5(), tmp_path / "a.msh")
    (tmp_path / "p.json").write_text(json.dumps({"filters": [
        {"name": "demo_scale", "params": {"factor": 0.5}},
        {"name": "meshing_uniform_refinement"}]}))
    assert main(["run", "p.json", "a.msh", "-o", "out", "--isolate", "never"]) == 0
    out = load(tmp_path / "out" / "a.msh")
    assert out == square5().with_points(0.5 * square5().points).refine()
    capsys.readouterr()
    assert main(["filters", "--json"]) == 0
    specs = {s["name"]: s for s in json.loads(capsys.readouterr().out)}
    assert specs["demo_scale"]["origin"] == "meshopt-demo-plugin"
    assert specs["demo_scale"]["parameters"][0]["name"] == "factor"


def test_a_crashing_step_does_not_take_the_batch_down(tmp_path, global_plugins, capsys):
    """A step that aborts the process (like a GPU filter headless) fails only its file.

    Plugin steps run in a worker process by default (``--isolate auto``).
    """
    for name in ("a_ok", "b_bad", "c_ok"):
        save(square5(), tmp_path / f"{name}.msh")
    (tmp_path / "p.json").write_text(json.dumps({"filters": [
        {"name": "demo_crash", "params": {"marker": "bad"}},
        {"name": "meshing_uniform_refinement"},
        {"name": "Laplacian Smooth", "params": {"stepsmoothnum": 1, "boundary": False}}]}))
    assert main(["run", "p.json", "a_ok.msh", "b_bad.msh", "c_ok.msh", "-o", "out"]) == 1
    err = capsys.readouterr().err
    assert "b_bad.msh" in err and "crashed" in err
    assert "2 done, 0 skipped, 1 failed in " in err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()
                  if p.name != ".meshopt-journal.db") == ["a_ok.msh", "c_ok.msh"]
    out = load(tmp_path / "out" / "a_ok.msh")  # the MeshLab step ran in the worker
    fine = square5().refine()
    assert out.n_vertices == fine.n_vertices
    assert not np.array_equal(out.points, fine.points)
