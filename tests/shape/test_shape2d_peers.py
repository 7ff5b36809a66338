"""The 2D shape benchmarks (benchmarks/bench_shape2d.py) on coarse meshes, checked on the
written files by scikit-fem's independent assembly and a least-squares ellipse fit:

- a disc hole of area π/4 in an 8 × 8 plate under the stresses (2, 1, 0) becomes the
  closed-form optimum, the ellipse with a/b = σ1/σ2 = 2 (± 0.2), with less compliance
  than that ellipse meshed by gmsh;
- a disc of area π/4 moved through Stokes flow in a 6 × 4 box ends with less drag than
  the best ellipse of the same area meshed by gmsh in the same box;
- area (and barycenter) kept, the outer boundary untouched, no cell inverted and the
  worst at least 0.3 × the start.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest

from meshopt_toolkit.cli import main
from meshopt_toolkit.kernels.triangles import aspect_ratios, signed_areas
from meshopt_toolkit.shape.cases import ellipse_in_box

pytest.importorskip("skfem")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from _peers2d import compliance_skfem, dissipation_skfem  # noqa: E402

pytestmark = pytest.mark.slow

#: coarse meshes: element size on the body and away from it
NEAR, FAR = 0.15, 1.0


def _ellipse(path, ratio, box, inner):
    a = math.sqrt(ratio / 4)  # area π a b = π/4
    return ellipse_in_box(path, (a, 1 / (4 * a)), box, FAR, refine_near=NEAR, inner=inner)


def _read(path, group):
    m = meshio.read(path)
    tag = m.field_data[group][0]
    lines = np.concatenate([c.data for c in m.cells if c.type == "line"])
    tags = np.concatenate([d for c, d in zip(m.cells, m.cell_data["gmsh:physical"])
                           if c.type == "line"])
    return m.points[:, :2].astype(float), m.cells_dict["triangle"], lines[tags == tag]


def fitted_axes(points):
    """Half axes ``(a, b)``, a ≥ b, of the conic ``x'Ax + b'x + c = 0`` fitted to
    ``points`` by least squares (the singular vector of the design matrix)."""
    x, y = points.T
    D = np.column_stack([x * x, x * y, y * y, x, y, np.ones_like(x)])
    A, B, C, Dx, Ey, F = np.linalg.svd(D)[2][-1]
    M = np.array([[A, B / 2], [B / 2, C]])
    center = np.linalg.solve(2 * M, -np.array([Dx, Ey]))
    k = -(F + 0.5 * np.array([Dx, Ey]) @ center)
    half = 1 / np.sqrt(np.linalg.eigvalsh(M / k))
    return half.max(), half.min()


def _polygon(P, lines):
    """Area and centroid of the region the closed line elements enclose (orientation free)."""
    a, b = P[lines[:, 0]], P[lines[:, 1]]
    c = a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]
    area = c.sum() / 2
    return abs(area), ((a + b) * c[:, None]).sum(axis=0) / (6 * area)


def _kept(P0, P1, T, lines, outer):
    """What every run keeps: the body's area, the outer boundary, every cell positive."""
    assert _polygon(P1, lines)[0] == pytest.approx(_polygon(P0, lines)[0], rel=1e-6)
    fixed = np.unique(outer)
    assert np.array_equal(P1[fixed], P0[fixed])
    assert signed_areas(P1, T).min() > 0
    assert aspect_ratios(P1, T).min() >= 0.3 * aspect_ratios(P0, T).min()


def test_hole_under_stresses_2_1_becomes_the_ellipse_of_axis_ratio_2(tmp_path):
    plate = _ellipse(tmp_path / "plate.msh", 1.0, (8, 8), "hole")
    out = tmp_path / "out"
    assert main(["optimize", str(plate), "--pde", "elasticity", "--stress", "outer=2,1,0",
                 "--objective", "compliance", "--move", "hole", "--keep-area", "--no-plots",
                 "-o", str(out)]) == 0
    P0, T, hole = _read(plate, "hole")
    P1, T1, _ = _read(out / "optimized.msh", "hole")
    assert np.array_equal(T, T1)
    a, b = fitted_axes(P1[np.unique(hole)])
    assert a / b == pytest.approx(2.0, abs=0.2)
    # the long axis along x, the larger stress
    assert np.ptp(P1[np.unique(hole), 0]) > np.ptp(P1[np.unique(hole), 1])
    # as good as the closed-form optimum meshed by gmsh (a hole held back from it is not)
    optimum = _ellipse(tmp_path / "ellipse.msh", 2.0, (8, 8), "hole")
    assert compliance_skfem(out / "optimized.msh", "outer", (2, 1, 0)) < \
        compliance_skfem(optimum, "outer", (2, 1, 0))
    _kept(P0, P1, T, hole, _read(plate, "outer")[2])


def test_stokes_body_drags_less_than_the_best_ellipse(tmp_path):
    body = _ellipse(tmp_path / "body.msh", 1.0, (6, 4), "body")
    out = tmp_path / "out"
    assert main(["optimize", str(body), "--pde", "stokes", "--dirichlet", "body=1,0",
                 "--dirichlet", "outer=0,0", "--objective", "dissipation", "--move", "body",
                 "--keep-volume", "--keep-barycenter", "--no-plots", "-o", str(out)]) == 0
    ellipses = [dissipation_skfem(_ellipse(tmp_path / f"e{r}.msh", r, (6, 4), "body"), "body")
                for r in (2.0, 2.5, 3.0, 3.5, 4.0)]
    best = min(ellipses)
    assert best < min(ellipses[0], ellipses[-1])  # the scan brackets the best ellipse
    assert dissipation_skfem(out / "optimized.msh", "body") < best
    P0, T, lines = _read(body, "body")
    P1 = _read(out / "optimized.msh", "body")[0]
    c0, c1 = _polygon(P0, lines)[1], _polygon(P1, lines)[1]
    assert np.linalg.norm(c1 - c0) <= 1e-6 * math.sqrt(math.pi / 4)
    _kept(P0, P1, T, lines, _read(body, "outer")[2])
