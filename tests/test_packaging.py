"""Packaging guards: setuptools package lists, the bare ``filters`` name, bundled data."""

from __future__ import annotations

import fnmatch
import subprocess
import sys
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


def test_package_dir_maps_the_top_level_folders():
    pd = SETUPTOOLS["package-dir"]
    assert pd["meshopt_toolkit"] == "meshopt_toolkit"
    assert pd["meshopt_toolkit.filters"] == "filters"
    assert pd["meshopt_toolkit.data"] == "data"


def test_every_filters_folder_is_listed():
    found = _subpackages(ROOT / "filters", "meshopt_toolkit.filters")
    assert "meshopt_toolkit.filters" in found
    missing = found - set(SETUPTOOLS["packages"])
    assert not missing, f"add to [tool.setuptools] packages in pyproject.toml: {sorted(missing)}"


def test_every_library_subpackage_is_listed():
    found = _subpackages(ROOT / "meshopt_toolkit", "meshopt_toolkit")
    missing = found - set(SETUPTOOLS["packages"])
    assert not missing, f"add to [tool.setuptools] packages in pyproject.toml: {sorted(missing)}"


def test_listed_packages_exist():
    pd = SETUPTOOLS["package-dir"]
    for name in SETUPTOOLS["packages"]:
        # resolve through the longest package-dir prefix
        base = max((k for k in pd if name == k or name.startswith(k + ".")), key=len)
        folder = (
            ROOT / pd[base] / Path(*name[len(base) :].strip(".").split(".") if name != base else ())
        )
        assert (folder / "__init__.py").is_file(), f"{name} -> {folder} has no __init__.py"


def test_bare_filters_import_is_refused():
    code = (
        "import sys\n"
        f"sys.path.insert(0, {str(ROOT)!r})\n"
        "try:\n"
        "    import filters\n"
        "except ImportError as e:\n"
        "    print('refused:', e)\n"
        "    raise SystemExit(0)\n"
        "raise SystemExit('import filters succeeded')\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        check=False,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr or out.stdout
    assert "meshopt_toolkit.filters" in out.stdout


def test_filters_importable_under_the_package_name():
    import meshopt_toolkit.filters as f

    assert f.__name__ == "meshopt_toolkit.filters"


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
    # plain files only: sub-folders (data/surfaces) are repository data, not shipped
    files = sorted(p.name for p in (ROOT / "data").glob("*")
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
