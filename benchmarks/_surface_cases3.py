"""``bench_surface.py --unseen3``: a third set of cases defined by coordinate rules before
ours was run on them (and not changed after): the armadillo's head turned, spot's head
nodded, a dome twisted at its top, an L-shaped plate with one arm rolled, a closed
capped cylinder bent and a torus with a segment tilted out of its plane."""

from __future__ import annotations

import numpy as np

from bench_surface import (DATA, Case, disc_surface, largest_component, planar_pivot,
                           read_mesh, region_turn, strip_surface, tube_surface)


def armadillo_head() -> Case:
    """The armadillo's head (z > 0.12, |x| < 0.15, y > 0.05: the part in front of the
    body between the arms) turned 45° about the vertical axis through its boundary; the
    feet fixed (as in the armadillo case)."""
    V, F = read_mesh(DATA / "armadillo.ply.xz")
    head = largest_component(V, F, (V[:, 2] > 0.12) & (np.abs(V[:, 0]) < 0.15)
                             & (V[:, 1] > 0.05))
    return region_turn("armadillo head", V, F, head, V[:, 1] < V[:, 1].min() + 0.06,
                       [0, 1, 0], np.pi / 4)


def spot_nod() -> Case:
    """Spot's head (z < −0.25) nodded 30° down (its front, −z, lowered) about the lateral
    (x) axis through the neck; the hooves (y < −0.65) fixed."""
    V, F = read_mesh(DATA / "spot.obj")
    return region_turn("spot nod", V, F, V[:, 2] < -0.25, V[:, 1] < -0.65,
                       [1, 0, 0], -np.pi / 6)


def dome_surface(rings: int):
    """An open unit hemisphere z ≥ 0: :func:`disc_surface` mapped by radius r ↦ polar
    angle θ = r·π/2 (the rim on the equator, normals out)."""
    D, F = disc_surface(rings)
    theta = np.linalg.norm(D[:, :2], axis=1) * (np.pi / 2)
    phi = np.arctan2(D[:, 1], D[:, 0])
    V = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                         np.cos(theta)])
    return V, F


def dome_twist() -> Case:
    """A unit hemisphere (30 rings, 5.4k triangles): the top cap θ ≤ 30° (disc radius
    ≤ 1/3) twisted 90° about the vertical axis, the rim band θ ≥ 85.5° (disc radius
    ≥ 0.95) fixed."""
    V, F = dome_surface(30)
    theta = np.arccos(np.clip(V[:, 2], -1, 1))
    return region_turn("dome twist", V, F, theta <= np.pi / 6 + 1e-9,
                       theta >= 0.95 * np.pi / 2 - 1e-9, [0, 0, 1], np.pi / 2,
                       np.array([0.0, 0.0, 1.0]))


def l_plate(size: float, arm: float, spacing: float):
    """An open flat L in z = 0: the square [0, size]² without the squares whose centre
    has x > arm and y > arm (arms of width ``arm`` along x and y), unused vertices
    dropped (the others keep their order)."""
    V, F = strip_surface(size, size, spacing)
    n = len(F) // 2  # rows k and k + n of F are the two halves of one square
    mid = 0.5 * (V[F[:n, 0]] + V[F[:n, 2]])
    keep = (mid[:, 0] < arm) | (mid[:, 1] < arm)
    F = np.concatenate([F[:n][keep], F[n:][keep]])
    used = np.zeros(len(V), bool)
    used[F] = True
    return V[used], (np.cumsum(used) - 1)[F]


def l_plate_roll() -> Case:
    """An L-shaped plate (3×3 square less [1, 3]², spacing 0.05): the end band y ≥ 2.9 of
    the arm along y rolled 90° upwards (its end to the end of a quarter circle of length
    2 that starts at y = 1), the end band x ≥ 2.9 of the arm along x fixed."""
    V, F = l_plate(3.0, 1.0, 0.05)
    r = 2.0 / (np.pi / 2)
    pivot = planar_pivot([0.0, 3.0, 0.0], [0.0, 1.0 + r, r], [1, 0, 0], np.pi / 2)
    return region_turn("L plate roll", V, F, V[:, 1] > 2.9 - 1e-9, V[:, 0] > 2.9 - 1e-9,
                       [1, 0, 0], np.pi / 2, pivot)


def capped_cylinder(length: float, radius: float, rings: int):
    """A closed cylinder about the x axis, x ∈ [0, length]: :func:`tube_surface` with
    ``6·rings`` points per ring (``rings`` even) closed by two caps of
    :func:`disc_surface` (``rings`` rings), duplicate vertices merged, normals out."""
    import trimesh

    nv = 6 * rings
    spacing = 2 * np.pi * radius / nv
    T, FT = tube_surface(length, radius, spacing)
    D, FD = disc_surface(rings)
    parts = [trimesh.Trimesh(T, FT, process=False)]
    for x, flip in ((0.0, False), (length, True)):
        C = np.column_stack([np.full(len(D), x), radius * D[:, 0], radius * D[:, 1]])
        # the disc's +z normal is +x here: the cap x = 0 is turned round to face −x
        parts.append(trimesh.Trimesh(C, FD if flip else FD[:, ::-1], process=False))
    m = trimesh.util.concatenate(parts)
    m.merge_vertices()
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def cylinder_bent() -> Case:
    """A closed cylinder (length 4, radius 0.5, 48 points per ring, 8-ring caps) bent
    60° in the x–y plane: the cap x = 4 turned so that its centre goes to the end of an
    arc of 60° and length 4, the cap x = 0 fixed."""
    V, F = capped_cylinder(4.0, 0.5, 8)
    r = 4.0 / (np.pi / 3)
    end = [r * np.sin(np.pi / 3), r * (1 - np.cos(np.pi / 3)), 0.0]
    pivot = planar_pivot([4.0, 0.0, 0.0], end, [0, 0, 1], np.pi / 3)
    return region_turn("cylinder bent", V, F, V[:, 0] > 4.0 - 1e-9, V[:, 0] < 1e-9,
                       [0, 0, 1], np.pi / 3, pivot)


def torus_surface(R: float, r: float, spacing: float):
    """A torus about the z axis (centre-line radius ``R``, tube radius ``r``): a grid of
    ≈ ``spacing`` along both circles, squares cut into two triangles, normals out."""
    nu, nv = int(round(2 * np.pi * R / spacing)), int(round(2 * np.pi * r / spacing))
    u, v = np.meshgrid(np.arange(nu) * (2 * np.pi / nu), np.arange(nv) * (2 * np.pi / nv),
                       indexing="ij")
    idx = np.arange(nu * nv).reshape(nu, nv)
    nu_, nv_ = np.roll(idx, -1, axis=0), np.roll(idx, -1, axis=1)
    nuv = np.roll(nu_, -1, axis=1)
    a, b, c, d = idx.ravel(), nu_.ravel(), nuv.ravel(), nv_.ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    w = R + r * np.cos(v.ravel())
    V = np.column_stack([w * np.cos(u.ravel()), w * np.sin(u.ravel()), r * np.sin(v.ravel())])
    return V, F.astype(np.int64)


def torus_tilt() -> Case:
    """A torus (R = 1, r = 0.3, spacing ≈ 0.05, 9.6k triangles): the segment within 10°
    of the −x direction turned 60° about the radial (x) axis through its centre-line
    point (−1, 0, 0), the segment within 10° of +x fixed."""
    V, F = torus_surface(1.0, 0.3, 0.05)
    u = np.arctan2(V[:, 1], V[:, 0])
    near = np.radians(10) + 1e-9
    return region_turn("torus tilt", V, F, np.abs(u) >= np.pi - near, np.abs(u) <= near,
                       [1, 0, 0], np.pi / 3, np.array([-1.0, 0.0, 0.0]))


#: ``--unseen3``: a third set of cases, defined before ours was run on them
UNSEEN3 = {"armadillo-head": armadillo_head, "spot-nod": spot_nod, "dome-twist": dome_twist,
           "l-plate-roll": l_plate_roll, "cylinder-bent": cylinder_bent,
           "torus-tilt": torus_tilt}
