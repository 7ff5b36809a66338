"""What a move reports is the written mesh's quality over all its cells, the cells the
targets alone place included; a mirror image is refused before any work."""

from __future__ import annotations

import re

import meshio
import numpy as np
import pytest
from test_tet_move import cube_tets

import meshopt_toolkit as mt
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.mesh import PlanarMesh, SurfaceMesh, TetMesh


def _icosphere():
    import trimesh

    m = trimesh.creation.icosphere(1)
    return np.array(m.vertices), np.array(m.faces)


ICO_V, ICO_F = _icosphere()
CUBE_P, CUBE_T = cube_tets(1)  # 8 vertices, all on the boundary


def _heron_aspect(points, triangles):
    """2r/R from the side lengths alone (Heron's area), in any dimension."""
    p = points[triangles]
    a, b, c = (np.linalg.norm(p[:, i] - p[:, j], axis=1) for i, j in ((1, 2), (2, 0), (0, 1)))
    s = 0.5 * (a + b + c)
    area = np.sqrt(np.maximum(s * (s - a) * (s - b) * (s - c), 0.0))
    return 2.0 * (area / s) / (a * b * c / (4.0 * area))


def _mean_ratio(points, tets):
    """12 (3|V|)^(2/3) / Σ ℓ² from the determinant and the six pairwise distances."""
    p = points[tets]
    vol = np.linalg.det(p[:, 1:] - p[:, :1]) / 6.0
    sq = sum(np.sum((p[:, i] - p[:, j]) ** 2, axis=1)
             for i in range(4) for j in range(i + 1, 4))
    return 12.0 * np.sign(vol) * np.abs(3.0 * vol) ** (2.0 / 3.0) / sq


def _write_obj(path, V, F):
    with open(path, "w") as f:
        f.writelines(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F.tolist())


ALL = np.arange(len(ICO_V))


def test_a_surface_move_of_handles_only_reports_its_true_worst_triangle():
    target = ICO_V * [1.0, 1.0, 0.001]  # every vertex a handle: no free triangle
    result = mt.move(SurfaceMesh(ICO_V, ICO_F), ALL, target)
    worst = float((_heron_aspect(target, ICO_F) / _heron_aspect(ICO_V, ICO_F)).min())
    assert worst < 0.01
    assert result.summary()["worst_relative_quality"] == pytest.approx(worst, rel=1e-9)


def test_the_cli_line_is_the_library_summary(tmp_path, capsys):
    _write_obj(tmp_path / "ico.obj", ICO_V, ICO_F)
    main(["move", str(tmp_path / "ico.obj"), "-o", str(tmp_path / "f.obj"),
          "--map", "x; y; 0.001*z"])
    line = capsys.readouterr().out
    summary = mt.move(SurfaceMesh(ICO_V, ICO_F), ALL, ICO_V * [1.0, 1.0, 0.001]).summary()
    assert f"folds {summary['folds']}," in line
    assert f"worst relative quality {summary['worst_relative_quality']:.4f}" in line
    assert float(re.search(r"worst relative quality ([0-9.]+)", line).group(1)) < 0.01


def test_a_mirrored_closed_surface_is_refused_and_nothing_written(tmp_path, capsys):
    with pytest.raises(InvalidMeshError, match="inside out"):
        mt.move(SurfaceMesh(ICO_V, ICO_F), ALL, ICO_V * [1.0, 1.0, -1.0])
    _write_obj(tmp_path / "ico.obj", ICO_V, ICO_F)
    out = tmp_path / "g.obj"
    assert main(["move", str(tmp_path / "ico.obj"), "-o", str(out), "--map", "x; y; -z"]) != 0
    err = capsys.readouterr().err.strip()
    assert "inside out" in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_surface_targets_that_flatten_a_triangle_of_handles_are_refused():
    corners = ICO_F[0]
    target = ICO_V[corners].copy()
    target[2] = 0.5 * (target[0] + target[1])  # triangle 0 flattened onto its edge
    with pytest.raises(InvalidMeshError, match="degenerate"):
        mt.move(SurfaceMesh(ICO_V, ICO_F), corners, target)


def test_a_tet_move_of_handles_only_reports_its_true_worst_tet(tmp_path, capsys):
    target = CUBE_P * [1.0, 1.0, 0.01]
    result = mt.move(TetMesh(CUBE_P, CUBE_T), np.arange(8), target)
    worst = float(_mean_ratio(target, CUBE_T).min())
    assert result.summary()["min_mean_ratio"] == pytest.approx(worst, rel=1e-9)
    meshio.write(tmp_path / "cube.vtu", meshio.Mesh(CUBE_P, [("tetra", CUBE_T)]))
    main(["move", str(tmp_path / "cube.vtu"), "-o", str(tmp_path / "t.vtu"),
          "--map", "x; y; 0.01*z"])
    assert f"-> {result.summary()['min_mean_ratio']:.4f}" in capsys.readouterr().out


def test_a_mirrored_tet_mesh_is_refused_before_any_work(tmp_path, capsys):
    with pytest.raises(InvalidMeshError, match="every tet over"):
        mt.move(TetMesh(CUBE_P, CUBE_T), np.arange(8), CUBE_P * [1.0, 1.0, -1.0])
    meshio.write(tmp_path / "cube.vtu", meshio.Mesh(CUBE_P, [("tetra", CUBE_T)]))
    out = tmp_path / "t.vtu"
    assert main(["move", str(tmp_path / "cube.vtu"), "-o", str(out), "--map", "x; y; -z"]) != 0
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert not out.exists()


def _grid(n: int = 3) -> PlanarMesh:
    """[0, 1]² in n × n squares, two triangles each, counter-clockwise."""
    x = np.linspace(0.0, 1.0, n + 1)
    P = np.stack(np.meshgrid(x, x, indexing="xy"), -1).reshape(-1, 2)
    k = np.arange(n * (n + 1)).reshape(n, n + 1)[:, :-1].ravel()
    T = np.concatenate([np.stack([k, k + 1, k + n + 2], 1), np.stack([k, k + n + 2, k + n + 1], 1)])
    return PlanarMesh(P, T)


def test_a_planar_move_of_handles_only_reports_its_true_worst_triangle():
    mesh = _grid()
    target = mesh.points * [1.0, 0.01]
    result = mt.move(mesh, np.arange(mesh.n_vertices), target)
    worst = float(_heron_aspect(target, mesh.triangles).min())
    assert result.summary()["min_aspect_ratio"] == pytest.approx(worst, rel=1e-9)


def test_planar_targets_that_turn_triangles_of_handles_over_are_refused():
    mesh = _grid()
    P = mesh.points
    inner = np.flatnonzero(((P > 0) & (P < 1)).all(axis=1))  # the four inner vertices
    handles = np.concatenate([mesh.boundary_vertices, inner])
    target = P[handles].copy()
    centre = P[inner].mean(axis=0)
    target[-len(inner):, 0] = 2 * centre[0] - P[inner, 0]  # the inner square mirrored
    with pytest.raises(InvalidMeshError, match=r"turn \d+ triangles over"):
        mt.move(mesh, handles, target)
