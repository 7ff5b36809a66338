"""The layout of ARCHITECTURE.md: layers import only downwards at any depth
(lazy imports included), the concept packages are small, and no module only re-exports."""

from __future__ import annotations

import ast
import importlib
import importlib.util

from test_architecture import PACKAGE, ROOT, find_cycle, module_level_imports

# the layers, lowest first: a module may import its own layer and the layers below
LAYERS = {
    "foundations": ["_typing", "_linalg", "_lazy", "errors", "bounds", "progress", "scaling",
                    "diagnostics", "_cholmod", "solvers", "strict_json", "results", "_options",
                    "descent", "least_squares"],
    "kernels": ["kernels"],
    "mesh": ["mesh", "orientation", "generate", "gmsh_session"],
    "numerics": ["penalties", "fem", "ode", "riemannian", "expressions"],
}
HIGHER = ["deform", "operations", "motion", "cells", "optimize", "shape", "io", "pipeline", "batch",
          "cli",
          "filters", "plotting", "conversions", "datasets"]

#: no module of the package is longer than this (one job per module)
MAX_LINES = 500


def _top(module: str) -> str:
    return module.split(".")[1] if module.count(".") else ""


def _layer_of(module: str) -> int | None:
    for i, tops in enumerate(LAYERS.values()):
        if _top(module) in tops:
            return i
    return None


def test_layers_import_only_downwards_at_any_depth():
    bad = []
    for module, targets in module_level_imports(any_depth=True).items():
        mine = _layer_of(module)
        if mine is None:
            continue
        for t in targets:
            theirs = _layer_of(t)
            if theirs is None or theirs > mine:
                bad.append(f"{module} -> {t}")
    assert not bad, bad


def test_the_layer_test_sees_an_upward_import():
    assert _layer_of(f"{PACKAGE}.kernels.triangles") < _layer_of(f"{PACKAGE}.penalties.terms")
    assert _layer_of(f"{PACKAGE}.deform") is None
    assert all(t not in sum(LAYERS.values(), []) for t in HIGHER)


def test_no_import_cycle_within_a_concept_package_at_any_depth():
    graph = module_level_imports(any_depth=True)
    for pkg in ("kernels", "penalties", "riemannian", "fem"):
        sub = {m: {t for t in ts if _top(t) == pkg} for m, ts in graph.items() if _top(m) == pkg}
        assert find_cycle(sub) is None, pkg


def test_every_module_is_small():
    long = []
    for path in sorted(ROOT.rglob("*.py")):
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > MAX_LINES:
            long.append(f"{path.relative_to(ROOT)}: {n} lines")
    assert not long


def _only_re_exports(tree) -> bool:
    """Whether a module body is nothing but a docstring, imports and ``__all__``/
    ``sys.modules`` assignments (an alias or a re-export shim)."""
    for node in tree.body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            continue
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            continue
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if all(ast.unparse(t) == "__all__" or ast.unparse(t).startswith("sys.modules")
                   for t in targets):
                continue
        return False
    return True


def test_no_module_only_re_exports():
    shims = [str(path.relative_to(ROOT)) for path in sorted(ROOT.rglob("*.py"))
             if path.name != "__init__.py"
             and _only_re_exports(ast.parse(path.read_text(encoding="utf-8")))]
    assert not shims


def test_the_shim_test_sees_a_shim():
    alias = "import sys\nfrom .kernels import triangles as _m\nsys.modules[__name__] = _m\n"
    assert _only_re_exports(ast.parse(alias))
    assert not _only_re_exports(ast.parse("import numpy as np\ndef f():\n    return 1\n"))


def test_public_api_resolves():
    import meshopt_toolkit as mt

    for name in mt.__all__:
        assert getattr(mt, name) is not None, name


def test_every_package_folder_is_installed():
    # pyproject finds the packages (include "meshopt_toolkit*"): every folder needs __init__.py
    text = (ROOT.parent / "pyproject.toml").read_text(encoding="utf-8")
    assert 'include = ["meshopt_toolkit*"]' in text and "package-dir" not in text
    for py in ROOT.rglob("*.py"):
        assert (py.parent / "__init__.py").is_file(), py.parent


def _mirror_script():
    """``scripts/mirror_tests.py``, the one owner of where a test file goes."""
    path = ROOT.parent / "scripts" / "mirror_tests.py"
    spec = importlib.util.spec_from_file_location("mirror_tests", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_tests_mirror_the_package():
    # tests/ holds only the whole-package tests; the others live in tests/<package>/
    mirror = _mirror_script()
    tests = ROOT.parent / "tests"
    stray = sorted(p.name for p in tests.glob("test_*.py") if p.name not in mirror.TOP_LEVEL)
    assert not stray, f"run python scripts/mirror_tests.py: {stray}"
    folders = {p.parent.name for p in tests.glob("*/test_*.py")}
    allowed = {f for _, f in mirror.RULES} | {p.parent.name for p in ROOT.glob("*/__init__.py")}
    assert folders <= allowed, folders - allowed


def test_test_file_names_are_unique():
    # tests/conftest.py puts every test folder on sys.path: a name may live in one folder only
    names = [p.name for p in (ROOT.parent / "tests").rglob("*.py")
             if "plugin_pkg" not in p.parts and p.name not in {"__init__.py", "conftest.py"}]
    assert sorted(n for n in set(names) if names.count(n) > 1) == []


def test_the_mirror_rules_place_by_name_and_by_import(tmp_path):
    mirror = _mirror_script()
    (tmp_path / "test_batch_new.py").write_text("")
    (tmp_path / "test_unnamed.py").write_text("from meshopt_toolkit.riemannian import x\n"
                                               "from meshopt_toolkit.errors import y\n")
    (tmp_path / "test_elsewhere.py").write_text("from meshopt_toolkit.errors import y\n")
    assert [mirror.folder_for(tmp_path / n) for n in
            ("test_batch_new.py", "test_unnamed.py", "test_elsewhere.py", "test_docs.py")] == [
        "batch", "riemannian", None, None]
    assert mirror.deepen("Path(__file__).resolve().parent.parent / 'a'") == (
        "Path(__file__).resolve().parents[2] / 'a'")
    assert mirror.deepen("Path(__file__).parents[1], Path(__file__).name") == (
        "Path(__file__).parents[2], Path(__file__).name")
