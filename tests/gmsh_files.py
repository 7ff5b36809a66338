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
