"""Shared tiny meshes and a seeded RNG."""

from __future__ import annotations

import os
import sys
from pathlib import Path

# one BLAS thread per test worker: the workers already take every core
if "PYTEST_XDIST_WORKER" in os.environ:
    for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

import numpy as np  # noqa: E402
import pytest
from hypothesis import settings

from meshopt_toolkit.mesh import PlanarMesh

# hypothesis draws the same examples on every run (seeded by each test), so a run's
# outcome is the same on every machine; HYPOTHESIS_PROFILE=explore draws new ones
settings.register_profile("deterministic", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))

# tests/ and each of its test folders (tests/<package>/) on sys.path: the helper modules
# (gmsh_files, motion_helpers, ...) and the builders other test files share import by
# their bare name from any folder, so a test file's name is unique across tests/
_HERE = Path(__file__).resolve().parent
for _folder in [_HERE, *sorted({p.parent for p in _HERE.glob("*/test_*.py")})]:
    if str(_folder) not in sys.path:
        sys.path.insert(0, str(_folder))


def pytest_collection_modifyitems(config, items):
    """The files with slow tests first, each file's tests in their order: a file runs on
    one worker (``--dist loadfile``), so the long ones start early and the short ones
    even out the workers' ends."""
    slow = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


def square5() -> PlanarMesh:
    """The 5-vertex square [-1, 1]² with a centre vertex (SPEC §6)."""
    pts = [[-1, -1], [1, -1], [1, 1], [-1, 1], [0, 0]]
    tri = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]
    return PlanarMesh(pts, tri)


def grid_mesh(n: int = 4, jitter: float = 0.0, seed: int = 0) -> PlanarMesh:
    """Structured triangulation of [0, 1]² with n×n squares, optionally jittered inside."""
    x = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(x, x, indexing="xy")
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    if jitter:
        r = np.random.default_rng(seed)
        inner = (pts > 0).all(1) & (pts < 1).all(1)
        pts[inner] += jitter / n * r.uniform(-1, 1, (inner.sum(), 2))
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tri = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return PlanarMesh(pts, tri)


@pytest.fixture
def square() -> PlanarMesh:
    return square5()


@pytest.fixture
def grid() -> PlanarMesh:
    return grid_mesh(4, jitter=0.3)


@pytest.fixture(scope="module")
def disc():
    """A jittered 6 × 6 grid of the unit square (tests of the motion package)."""
    return grid_mesh(6, jitter=0.3)


@pytest.fixture(scope="module")
def annulus():
    """gmsh's annulus of element size 0.1 (tests of move and morph)."""
    pytest.importorskip("gmsh")
    from meshopt_toolkit.generate import annulus as make

    return make(0.1)
