"""``bench_surface.py --contact2``: two generated motions that drive parts of a surface
towards each other, defined before ours was run on them (and not changed after): the
finger of a hand-like plate curled back onto its palm, and a strip folded in two, its
turned half brought down over its fixed half."""

from __future__ import annotations

import numpy as np

from bench_surface import Case, planar_pivot, region_turn, strip_surface


def hand_surface(size: float = 0.1):
    """A closed hand-like plate (gmsh, OpenCASCADE): the palm [0, 2]×[0, 2]×[0, 0.3] fused
    with one finger [0.7, 1.3]×[2, 4]×[0, 0.3], its surface meshed at ``size``, normals
    out."""
    from meshopt_toolkit.gmsh_session import gmsh_session

    with gmsh_session() as gmsh:
        gmsh.model.add("hand")
        palm = gmsh.model.occ.addBox(0.0, 0.0, 0.0, 2.0, 2.0, 0.3)
        finger = gmsh.model.occ.addBox(0.7, 2.0, 0.0, 0.6, 2.0, 0.3)
        gmsh.model.occ.fuse([(3, palm)], [(3, finger)])
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, _, nodes = gmsh.model.mesh.getElements(2)
    V = np.asarray(coords, float).reshape(-1, 3)
    index = np.zeros(int(tags.max()) + 1, np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    F = index[np.concatenate(nodes).astype(np.int64).reshape(-1, 3)]
    used = np.unique(F)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    V, F = V[used], remap[F]
    # outward: the signed volume of the closed surface positive
    P = V[F]
    if np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() < 0:
        F = F[:, ::-1]
    return V, F


def hand_finger() -> Case:
    """The finger's tip (y ≥ 3.8) curled 180° back over the palm about the lateral (x)
    axis through (·, 2.15, 0.45): it lands 0.3 above the palm's top face (y in [0.3, 0.5]);
    the palm's bottom band (y ≤ 0.2) fixed."""
    V, F = hand_surface()
    pivot = np.array([1.0, 2.15, 0.45])
    return region_turn("hand, finger curled onto the palm", V, F, V[:, 1] >= 3.8 - 1e-9,
                       V[:, 1] <= 0.2 + 1e-9, [1, 0, 0], np.pi, pivot)


def sheet_fold(spacing: float = 0.05) -> Case:
    """An open 4×1 strip (grid ``spacing``) folded in two: the band x ≥ 3.9 turned 180°
    upwards about the lateral (y) axis through (2, ·, 0.05), landing 0.1 above the fixed
    band x ≤ 0.1 (the turned half pressed down onto the fixed one)."""
    V, F = strip_surface(4.0, 1.0, spacing)
    pivot = planar_pivot([4.0, 0.0, 0.0], [0.0, 0.0, 0.1], [0, -1, 0], np.pi)
    return region_turn("sheet folded in two", V, F, V[:, 0] > 3.9 - 1e-9,
                       V[:, 0] < 0.1 + 1e-9, [0, -1, 0], np.pi, pivot)


CONTACT2 = {"hand-finger": hand_finger, "sheet-fold": sheet_fold}
