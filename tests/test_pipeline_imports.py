"""The pipeline package has no import cycle (issue 13): runner ↛ json_format / mlx."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import meshopt_toolkit.pipeline as pkg

PKG = "meshopt_toolkit.pipeline"
ROOT = Path(pkg.__file__).parent


def _imports(path: Path, module: str) -> set[str]:
    """Every module of the package that ``module`` imports, at any depth of its code
    (function-level imports included: a lazy import is still a dependency)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = set()
    base = module.rsplit(".", 1)[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                parent = base.rsplit(".", node.level - 1)[0] if node.level > 1 else base
                target = f"{parent}.{node.module}" if node.module else parent
            else:
                target = node.module or ""
            if target == PKG:  # from . import meshlab
                out.update(f"{PKG}.{a.name}" for a in node.names)
            else:
                out.add(target)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return {m for m in out if m.startswith(PKG + ".") and (ROOT / (m.split(".")[-1] + ".py")).exists()}


def _graph() -> dict[str, set[str]]:
    return {f"{PKG}.{p.stem}": _imports(p, f"{PKG}.{p.stem}")
            for p in sorted(ROOT.glob("*.py")) if p.stem != "__init__"}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state:
                found = visit(m)
                if found:
                    return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state:
            found = visit(n)
            if found:
                return found
    return None


def test_module_graph_has_no_cycle():
    graph = _graph()
    assert f"{PKG}.runner" in graph and f"{PKG}.json_format" in graph
    assert f"{PKG}.runner" in graph[f"{PKG}.json_format"]  # the edge that must stay one-way
    assert not graph[f"{PKG}.runner"] & {f"{PKG}.json_format", f"{PKG}.mlx", f"{PKG}.files"}
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


def test_cycle_finder_finds_a_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None


def test_each_order_imports_in_a_fresh_interpreter():
    mods = ["runner", "json_format", "mlx", "files"]
    for order in (mods, mods[::-1]):
        code = ("import importlib; " + "; ".join(
            f"importlib.import_module('{PKG}.{m}')" for m in order)
            + f"; from {PKG} import load_pipeline, save_pipeline, Pipeline")
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 0, proc.stderr
