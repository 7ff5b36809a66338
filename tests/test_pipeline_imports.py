"""The pipeline package has no import cycle: runner ↛ json_format / mlx."""

from __future__ import annotations

import subprocess
import sys

from test_architecture import find_cycle, module_level_imports

PKG = "meshopt_toolkit.pipeline"


def _graph() -> dict[str, set[str]]:
    """The pipeline modules and the pipeline modules each imports, at any depth (function-
    level imports included), the package ``__init__`` left out."""
    graph = module_level_imports(any_depth=True)
    return {m: {d for d in deps if d.startswith(PKG + ".")}
            for m, deps in graph.items() if m.startswith(PKG + ".")}


def test_module_graph_has_no_cycle():
    graph = _graph()
    assert f"{PKG}.runner" in graph and f"{PKG}.json_format" in graph
    assert f"{PKG}.runner" in graph[f"{PKG}.json_format"]  # the edge that must stay one-way
    assert not graph[f"{PKG}.runner"] & {f"{PKG}.json_format", f"{PKG}.mlx", f"{PKG}.files"}
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph))


def test_each_order_imports_in_a_fresh_interpreter():
    mods = ["runner", "json_format", "mlx", "files"]
    for order in (mods, mods[::-1]):
        code = ("import importlib; " + "; ".join(
            f"importlib.import_module('{PKG}.{m}')" for m in order)
            + f"; from {PKG} import load_pipeline, save_pipeline, Pipeline")
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 0, proc.stderr
