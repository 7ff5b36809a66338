"""The pipeline and batch packages have no import cycle: runner ↛ formats / mlx, and
pipeline ↛ batch (a batch runs pipelines, never the other way round)."""

from __future__ import annotations

import subprocess
import sys

from test_architecture import find_cycle, module_level_imports

PKG = "meshopt_toolkit.pipeline"
BATCH = "meshopt_toolkit.batch"


def _graph(prefixes=(PKG,)) -> dict[str, set[str]]:
    """The modules under ``prefixes`` and the ones of them each imports, at any depth
    (function-level imports included)."""
    graph = module_level_imports(any_depth=True)
    inside = tuple(p + "." for p in prefixes)
    return {m: {d for d in deps if d.startswith(inside)}
            for m, deps in graph.items() if m.startswith(inside)}


def test_module_graph_has_no_cycle():
    graph = _graph()
    assert f"{PKG}.runner" in graph and f"{PKG}.formats" in graph
    assert f"{PKG}.runner" in graph[f"{PKG}.formats"]  # the edge that must stay one-way
    assert f"{PKG}.mlx" in graph[f"{PKG}.formats"]
    assert not graph[f"{PKG}.runner"] & {f"{PKG}.formats", f"{PKG}.mlx"}
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph))


def test_batch_sits_above_pipeline():
    graph = _graph((PKG, BATCH))
    assert f"{PKG}.runner" in graph[f"{BATCH}.run"]  # the graph sees the downward edge
    upward = [(m, d) for m, deps in graph.items() if m.startswith(PKG + ".")
              for d in deps if d.startswith(BATCH)]
    assert not upward
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph))


def test_each_order_imports_in_a_fresh_interpreter():
    mods = [f"{PKG}.runner", f"{PKG}.formats", f"{PKG}.mlx", f"{PKG}.meshlab_values",
            f"{PKG}.params", f"{BATCH}.tasks", f"{BATCH}.run"]
    for order in (mods, mods[::-1]):
        code = ("import importlib; " + "; ".join(
            f"importlib.import_module('{m}')" for m in order)
            + f"; from {PKG} import load_pipeline, save_pipeline, Pipeline"
            + f"; from {BATCH} import run_batch")
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 0, proc.stderr
