"""The layering of ARCHITECTURE.md: no import cycle among the package's modules, lazy
imports inside functions included (a cycle makes import order matter and hides which
layer owns a concept; a lazy import only hides the cycle)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import meshopt_toolkit

ROOT = Path(meshopt_toolkit.__file__).parent
PACKAGE = ROOT.name


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in ROOT.rglob("*.py")}


def _targets(module: str, node: ast.ImportFrom, is_package: bool) -> set[str]:
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    out = set()
    for alias in node.names:
        if f"{target}.{alias.name}" in MODULES:
            out.add(f"{target}.{alias.name}")
        elif target in MODULES:
            out.add(target)
    return out


def module_level_imports(any_depth: bool = False) -> dict[str, set[str]]:
    """For every module of the package, the package modules its top-level code imports
    (``any_depth``: also the imports inside functions — a lazy import is still a
    dependency)."""
    graph = {}
    for module, path in MODULES.items():
        out: set[str] = set()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in (ast.walk(tree) if any_depth else tree.body):
            if isinstance(node, ast.ImportFrom):
                out |= _targets(module, node, path.name == "__init__.py")
            elif isinstance(node, ast.Import):
                out |= {a.name for a in node.names if a.name in MODULES}
        graph[module] = out - {module}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


@pytest.mark.parametrize("any_depth", [False, True], ids=["module-level", "lazy-included"])
def test_no_import_cycle(any_depth):
    assert find_cycle(module_level_imports(any_depth)) is None


def test_the_cycle_finder_finds_cycles():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_the_graph_sees_relative_imports():
    graph = module_level_imports()
    assert f"{PACKAGE}.mesh" in graph[f"{PACKAGE}.motion.move"]
    assert f"{PACKAGE}.motion.planar.distortion" in graph[f"{PACKAGE}.motion.planar.metric"]


def test_every_relative_import_resolves():
    """Every ``from .x import y`` of the package, lazy ones inside functions included,
    names a module that exists and a name it has: a lazy import on a rarely taken path
    (the large-boundary certificate of the geodesic field) broke silently when modules
    moved."""
    import importlib

    broken = []
    for module, path in sorted(MODULES.items()):
        is_package = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(node, ast.ImportFrom) and node.level):
                continue
            base = module.split(".") if is_package else module.split(".")[:-1]
            base = base[: len(base) - (node.level - 1)]
            target = ".".join(base + ([node.module] if node.module else []))
            try:
                imported = importlib.import_module(target)
            except ImportError:
                broken.append(f"{path.name}:{node.lineno} {target}")
                continue
            for alias in node.names:
                if alias.name != "*" and not hasattr(imported, alias.name) \
                        and f"{target}.{alias.name}" not in MODULES:
                    broken.append(f"{path.name}:{node.lineno} {target}.{alias.name}")
    assert broken == []
