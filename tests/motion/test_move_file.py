"""``MovedFile``: what ``meshopt move`` and the move filter hand ``mt.move``. The kind is
the one decider's, a file's cells come back with only their points changed (a planar
file's on any plane: unmoved vertices bit for bit, moved ones in the plane), and a
pipeline's mesh comes back of the type it was given."""

from __future__ import annotations

import numpy as np
import pytest
from cell_meshes import planar, rotation, surface, tets

from meshopt_toolkit.cells.registry import KINDS
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.mesh import TetMesh, TriangleMesh
from meshopt_toolkit.mesh.kinds import PLANAR, SURFACE, TETS, cells_kind
from meshopt_toolkit.motion.moved_file import MovedFile


def _files(seed: int) -> dict:
    """A tilted planar file, a surface and a tet file, each with a point datum and a
    physical group."""
    P, T = planar()
    R = rotation(KINDS[TETS], seed)
    tilted = np.column_stack([P, np.zeros(len(P))]) @ R.T + [1.0, -2.0, 3.0]
    S, F = surface()
    X, C = tets()
    out = {}
    for name, points, block in (("planar", tilted, ("triangle", T)),
                                ("surface", S, ("triangle", F)), ("tets", X, ("tetra", C))):
        out[name] = CellMesh(points, [block], point_data={"t": points[:, 0] ** 2},
                             cell_data={"gmsh:physical": [np.full(len(block[1]), 7)]},
                             field_data={"part": np.array([7, 2 if name != "tets" else 3])})
    return out


@pytest.mark.parametrize("seed", range(3))
def test_the_kind_is_the_deciders_and_the_file_comes_back_with_new_points_only(seed):
    rng = np.random.default_rng(seed)
    for name, cells in _files(seed).items():
        moving = MovedFile.of_cells(cells)
        assert moving.kind == cells_kind(cells) == {"planar": PLANAR, "surface": SURFACE,
                                                    "tets": TETS}[name]
        assert moving.mesh.points.shape[1] == (2 if name == "planar" else 3)
        same = moving.moved(moving.mesh).cells
        np.testing.assert_array_equal(same.points, cells.points)  # bit for bit
        Q = np.array(moving.mesh.points)
        v = int(rng.integers(len(Q)))
        Q[v] += 1e-3
        back = moving.moved(moving.mesh.with_points(Q)).cells
        changed = np.flatnonzero(np.any(back.points != cells.points, axis=1))
        assert changed.tolist() == [v]
        if name == "planar":  # in the plane, 1e-3 away along it
            step = back.points[v] - cells.points[v]
            normal = np.cross(*(cells.points[cells.cells[0][1][0, 1:]]
                                - cells.points[cells.cells[0][1][0, 0]]))
            assert abs(step @ normal) < 1e-12 * np.linalg.norm(normal)
            assert np.linalg.norm(step) == pytest.approx(np.sqrt(2) * 1e-3, rel=1e-9)
        for key in ("point_data", "cell_data", "field_data"):
            assert getattr(back, key).keys() == getattr(cells, key).keys()
        np.testing.assert_array_equal(back.point_data["t"], cells.point_data["t"])
        assert [t for t, _ in back.cells] == [t for t, _ in cells.cells]


def test_a_pipelines_mesh_comes_back_of_its_type_with_its_tags():
    X, C = tets()
    tet = TetMesh(X, C)
    moving = MovedFile.of_mesh(tet, lambda: pytest.fail("a tet mesh has no plane"))
    Q = np.array(X) * 1.5
    back = moving.moved(tet.with_points(Q)).file_mesh
    assert isinstance(back, TetMesh) and np.array_equal(back.points, Q)
    assert moving.summary(_Summary(), np.array([3, 1, 3])) == {"handles": 2, "x": 1}

    S, F = surface()
    bump = TriangleMesh(S, F, triangle_tags=np.full(len(F), 4), tag_names={"skin": (4, 2)})
    moving = MovedFile.of_mesh(bump, lambda: None)
    assert moving.kind == SURFACE
    back = moving.moved(moving.mesh.with_points(S + 1.0)).file_mesh
    assert type(back) is TriangleMesh and np.array_equal(back.points, S + 1.0)
    assert back.tag_names == {"skin": (4, 2)} and np.all(back.triangle_tags == 4)


class _Summary:
    def summary(self) -> dict:
        return {"x": 1}
