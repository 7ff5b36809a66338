"""The layout of ARCHITECTURE.md (issue 13): layers import only downwards at any depth
(lazy imports included), the concept packages are small, and the old import paths keep
working as aliases of the new modules."""

from __future__ import annotations

import importlib

import pytest
from test_architecture import PACKAGE, ROOT, find_cycle, module_level_imports

# the layers, lowest first: a module may import its own layer and the layers below
LAYERS = {
    "foundations": ["_typing", "_linalg", "_lazy", "errors", "bounds", "progress", "scaling",
                    "diagnostics", "_cholmod", "solvers", "strict_json"],
    "kernels": ["kernels"],
    "mesh": ["mesh", "orientation", "generate", "gmsh_session"],
    "numerics": ["penalties", "fem", "ode", "riemannian", "expressions"],
}
HIGHER = ["deform", "morph", "motion", "optimize", "shape", "io", "pipeline", "cli",
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


# old path -> new module (the alias is the module itself)
MOVED = {
    "geometry": "kernels.triangles",
    "distance": "kernels.distance",
    "metrics": "riemannian.metrics",
    "geodesics": "riemannian.geodesics",
    "poisson": "fem.poisson",
    "elasticity": "fem.elasticity",
    "interpolation": "fem.interpolation",
    "taylor": "diagnostics",
}


@pytest.mark.parametrize("old, new", sorted(MOVED.items()))
def test_old_module_paths_are_the_new_modules(old, new):
    assert importlib.import_module(f"{PACKAGE}.{old}") is importlib.import_module(
        f"{PACKAGE}.{new}"
    )


@pytest.mark.parametrize("module, names", [
    ("mesh", ["TriangleMesh", "PlanarMesh", "MeshReport", "check_mesh", "require_admissible",
              "boundary_self_intersections", "_fans_per_vertex"]),
    ("penalties", ["Penalty", "HeightPenalty", "QualityPenalty", "cutoff", "DEFAULT_MU",
                   "BLOCK", "PAIR_CHUNK", "PAIR_CACHE", "SIMPLE_BOUNDARY_CACHE"]),
    ("fem", ["PoissonSolver", "p1_stiffness", "element_stiffness", "lumped_load",
             "nodal_mass_weights", "centroids", "poisson_shape_derivative", "AMG_THRESHOLD"]),
    ("integrators", ["GeodesicField", "BoundaryGuard", "IntegrationOutput", "runge_kutta",
                     "stormer_verlet", "dopri5", "dop853", "bs3", "rk_pair", "energy",
                     "DOPRI5_TABLEAU", "BS3_TABLEAU", "PAIRS"]),
    ("morph", ["geodesic_morph", "log_map", "discrete_geodesic", "MorphResult", "twisted"]),
])
def test_old_import_paths_keep_their_names(module, names):
    mod = importlib.import_module(f"{PACKAGE}.{module}")
    missing = [n for n in names if not hasattr(mod, n)]
    assert not missing


def test_integrators_alias_re_exports_the_same_objects():
    from meshopt_toolkit import integrators, ode
    from meshopt_toolkit.riemannian import field

    assert integrators.runge_kutta is ode.runge_kutta
    assert integrators.GeodesicField is field.GeodesicField
    assert set(ode.__all__) <= set(integrators.__all__)


def test_code_imports_the_new_paths_not_the_aliases():
    """The aliases are for users' old code: the package, its filters, tests, benchmarks and
    examples import the modules where they live."""
    import ast

    repo = ROOT.parent
    old = {f"{PACKAGE}.{name}" for name in [*MOVED, "integrators"]}
    found = []
    for folder in (PACKAGE, "filters", "tests", "benchmarks", "examples", "scripts"):
        for path in sorted((repo / folder).rglob("*.py")):
            module = ".".join(path.relative_to(repo).with_suffix("").parts)
            if module in old or path.name == "test_layout.py":
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.ImportFrom):
                    base = module.split(".")[: -1 if path.name != "__init__.py" else None]
                    target = (".".join(base[: len(base) - node.level + 1]
                                       + ([node.module] if node.module else []))
                              if node.level else node.module or "")
                    names = {target} | {f"{target}.{a.name}" for a in node.names}
                elif isinstance(node, ast.Import):
                    names = {a.name for a in node.names}
                else:
                    continue
                found += [f"{path.relative_to(repo)}:{node.lineno} {n}" for n in names & old]
    assert not found


def test_public_api_resolves():
    import meshopt_toolkit as mt

    for name in mt.__all__:
        assert getattr(mt, name) is not None, name


def test_every_package_folder_is_listed_in_pyproject():
    text = (ROOT.parent / "pyproject.toml").read_text(encoding="utf-8")
    for init in ROOT.rglob("__init__.py"):
        pkg = ".".join([PACKAGE, *init.parent.relative_to(ROOT).parts])
        assert f'"{pkg}"' in text, pkg
