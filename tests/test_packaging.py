"""Packaging guards: setuptools finds every package under meshopt_toolkit/, bundled data."""

from __future__ import annotations

import fnmatch
from pathlib import Path

import pytest

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    tomllib = pytest.importorskip("tomli")

from meshopt_toolkit.datasets import available, data_path
from meshopt_toolkit.errors import ReadError

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
SETUPTOOLS = PYPROJECT["tool"]["setuptools"]


def _subpackages(folder: Path, prefix: str) -> set[str]:
    """Dotted names of every folder with an ``__init__.py`` under ``folder`` (itself included)."""
    names = set()
    for init in folder.rglob("__init__.py"):
        rel = init.parent.relative_to(folder)
        if "__pycache__" in rel.parts:
            continue
        names.add(".".join((prefix, *rel.parts)))
    return names


def _found_packages() -> set[str]:
    """What setuptools installs: ``find_packages`` with pyproject's include and exclude."""
    from setuptools import find_packages

    find = SETUPTOOLS["packages"]["find"]
    return set(find_packages(where=str(ROOT / find.get("where", ["."])[0]),
                             include=find.get("include", ["*"]),
                             exclude=find.get("exclude", ())))


def test_packages_are_found_inside_the_package_folder():
    # one folder, no remapping: what is imported in the repository is what is installed
    assert "package-dir" not in SETUPTOOLS
    assert SETUPTOOLS["packages"]["find"]["include"] == ["meshopt_toolkit*"]
    assert not (ROOT / "filters").exists(), "the filters live in meshopt_toolkit/filters"


def test_every_library_subpackage_is_installed():
    found = _subpackages(ROOT / "meshopt_toolkit", "meshopt_toolkit")
    assert {"meshopt_toolkit", "meshopt_toolkit.filters", "meshopt_toolkit.data"} <= found
    assert _found_packages() == found


def test_every_folder_with_modules_is_a_package():
    # a folder of .py files without __init__.py would be left out of the wheel silently
    for py in (ROOT / "meshopt_toolkit").rglob("*.py"):
        assert (py.parent / "__init__.py").is_file(), f"{py.parent} has no __init__.py"


def test_filters_importable_under_the_package_name():
    import meshopt_toolkit.filters as f

    assert f.__name__ == "meshopt_toolkit.filters"
    assert Path(f.__file__).parent == ROOT / "meshopt_toolkit" / "filters"


EXPECTED_MESHES = [
    "square5.msh",
    "square_crossed.msh",
    "disc_25.msh",
    "disc_77.msh",
    "disc_85.msh",
    "disc_146.msh",
]


@pytest.mark.parametrize("name", EXPECTED_MESHES)
def test_bundled_mesh_is_reachable(name):
    path = data_path(name)
    assert path.is_file() and path.name == name
    assert path.read_text().startswith("$MeshFormat\n4.1 0 8\n")
    assert name in available()


def test_bundled_files_are_package_data():
    patterns = PYPROJECT["tool"]["setuptools"]["package-data"]["meshopt_toolkit.data"]
    # plain files only (the repository folder data/surfaces is not shipped)
    files = sorted(p.name for p in (ROOT / "meshopt_toolkit" / "data").glob("*")
                   if p.is_file() and p.name != "__init__.py")
    assert files, "no bundled data files"
    for f in files:
        assert any(fnmatch.fnmatch(f, pat) for pat in patterns), f"{f} not in package-data"
    assert available() == sorted(f for f in files if f.endswith(".msh"))


def test_bundled_meshes_load_with_their_tags():
    from meshopt_toolkit.io import load

    m = load(data_path("disc_146.msh")).as_planar()
    assert (m.n_vertices, m.n_triangles) == (146, 254)
    assert set(m.tag_names) == {"domain", "boundary"}
    assert set(m.tagged_vertices("boundary").tolist()) == set(m.boundary_vertices.tolist())
    sq = load(data_path("square5.msh")).as_planar()
    assert sq.points.tolist() == [[-1, -1], [1, -1], [1, 1], [-1, 1], [0, 0]]
    assert sq.triangles.tolist() == [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]


def test_unknown_bundled_mesh_lists_the_available_ones():
    with pytest.raises(ReadError, match=r"nope\.msh: no such bundled mesh; available: .*disc_146"):
        data_path("nope.msh")


def test_lazy_exports_and_submodules_resolve():
    import meshopt_toolkit as mt

    for name in mt.__all__:
        assert getattr(mt, name) is not None, name
    assert mt.datasets.available()  # a submodule by attribute
    with pytest.raises(AttributeError):
        mt.no_such_thing  # noqa: B018
