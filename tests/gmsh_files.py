"""Tet files as gmsh users hold them, for the tests: one generator, the fixtures add their
own point data."""

from __future__ import annotations

from pathlib import Path


def box_with_hole_msh(path: Path, *, radius: float, size: float,
                      size_min: float | None = None) -> Path:
    """gmsh tets of [-1, 1]³ minus a ball of ``radius`` at the origin, written to ``path``
    with the physical groups ``hole`` and ``walls`` (surfaces) and ``solid`` (volume)."""
    from meshopt_toolkit.gmsh_session import gmsh_session

    with gmsh_session() as gmsh:
        gmsh.model.add("box_with_hole")
        box = gmsh.model.occ.addBox(-1, -1, -1, 2, 2, 2)
        ball = gmsh.model.occ.addSphere(0, 0, 0, radius)
        vols, _ = gmsh.model.occ.cut([(3, box)], [(3, ball)])
        gmsh.model.occ.synchronize()
        hole, walls = [], []
        for dim, tag in gmsh.model.getBoundary(vols, oriented=False):
            box_of = gmsh.model.getBoundingBox(dim, tag)
            (hole if max(map(abs, box_of)) < radius + 1e-6 else walls).append(tag)
        gmsh.model.addPhysicalGroup(2, hole, name="hole")
        gmsh.model.addPhysicalGroup(2, walls, name="walls")
        gmsh.model.addPhysicalGroup(3, [t for _, t in vols], name="solid")
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        if size_min is not None:
            gmsh.option.setNumber("Mesh.MeshSizeMin", size_min)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    return path


def assert_same_but_points(a, b, *, point_data: set, groups: set) -> None:
    """``b`` holds every block, tag, name and datum of ``a`` (points aside): the cell
    blocks, every cell datum (``gmsh:physical`` among them), the point data ``point_data``
    and the physical names ``groups``, each equal."""
    import numpy as np

    assert [t for t, _ in a.cells] == [t for t, _ in b.cells]
    for (_, ca), (_, cb) in zip(a.cells, b.cells):
        np.testing.assert_array_equal(ca, cb)
    assert set(a.cell_data) == set(b.cell_data) and "gmsh:physical" in a.cell_data
    for key in a.cell_data:
        for u, v in zip(a.cell_data[key], b.cell_data[key]):
            np.testing.assert_array_equal(u, v)
    assert set(a.point_data) == set(b.point_data) == point_data
    for key in point_data:
        np.testing.assert_array_equal(a.point_data[key], b.point_data[key])
    assert set(a.field_data) == set(b.field_data) == groups
    for key in groups:
        np.testing.assert_array_equal(a.field_data[key], b.field_data[key])
    assert a.points.shape == b.points.shape
