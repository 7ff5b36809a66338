"""Handle deformation of triangle surfaces in 3D: ours side by side with libigl.

Cases (data/surfaces/README.md names the sources and terms of the meshes):

* knight: libigl tutorial 405 (decimated knight, its handle selection, the tutorial's own
  handle motion at ``anim_t = 1``);
* bunny: the Stanford bunny, one ear turned 90° about a lateral axis at its base, the
  bottom of the body fixed;
* armadillo: the Stanford armadillo (86k triangles), the hand on the +x side raised by
  turning it 90° about a lateral axis through the shoulder, the feet fixed;
* bar: a generated 6×1×1 box surface (5.2k triangles), one end cap turned 180° about the
  long axis, the other fixed;
* ``--unseen`` (cases defined by coordinate rules after the method's defaults were set):
  Keenan Crane's spot (head turned 60°, a leg bent 60°), bob (head turned 90°) and blub
  (tail turned 60°), the bar bent 90° and an open strip rolled 90°;
* ``--unseen2`` (more such cases): the bunny's front ear turned 90°, bob's tail tilted
  60°, the armadillo's tail turned 60°, an open tube twisted 180° and bent 90°, a thin
  plate twisted 90°, the rolled strip with a hole, a flat disc pushed into a bump.

Methods: libigl harmonic (k = 1) and biharmonic (k = 2) extensions of the handle
displacements; libigl ARAP single shot (100 iterations from the biharmonic result) and in
10 increments along the handles' path (50 iterations each, ``--step-iterations``, from the
previous result; the handles' rotations are interpolated in angle, the knight's handles
follow the tutorial's own animation path); ours
(``meshopt_toolkit.motion.surface.move.move_surface``) when it exists.

Printed per case and method: worst relative quality (aspect ratio 2r/R over its rest value,
triangles not wholly handles), folds, max handle error, seconds (and CPU seconds) and the
ARAP energy (``_surface_measures.py``) and the self-intersecting faces by pymeshlab's test.
``--figures DIR`` writes one PNG per case.

* ``--contact``: motions that drive parts of a surface into each other: the bunny's ear
  turned 120° (into its back), the bar folded back onto itself; ``--contact2``
  (``_surface_cases_contact.py``): a hand-like plate's finger curled onto its palm, a strip
  folded in two.

``--every-frame`` also tests each of ours' frames for self-intersections (the largest
count is printed, and every frame that passes through itself with its exact pairs).

Run ``python benchmarks/bench_surface.py [--cases knight,bar] [--unseen] [--unseen2] [--contact]
[--contact2] [--every-frame] [--figures DIR]``.
"""

from __future__ import annotations

import argparse
import lzma
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _surface_measures import (arap_energy, fold_count, normals,  # noqa: E402
                               relative_quality, rigid_pose_faces, self_intersecting_faces,
                               worst_relative_quality)

DATA = Path(__file__).resolve().parent.parent / "data" / "surfaces"
STEPS = 10


@dataclass
class Case:
    """A rest surface, its handle vertices and their path: ``path(t)`` gives the handle
    positions at fraction t ∈ [0, 1] of the motion (t = 1 is the target)."""

    name: str
    V: np.ndarray
    F: np.ndarray
    handles: np.ndarray
    path: Callable[[float], np.ndarray]
    groups: np.ndarray  # a label per handle vertex (for the figure)


def rotation(axis, angle: float) -> np.ndarray:
    """Rotation matrix about the unit ``axis`` by ``angle`` (Rodrigues)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def turning(points, pivot, axis, angle):
    """Path of ``points`` turned about ``axis`` through ``pivot``, the angle interpolated."""
    return lambda t: (points - pivot) @ rotation(axis, t * angle).T + pivot


def read_mesh(path: Path):
    """Vertices and triangles of a mesh file, vertex order kept (``.xz`` decompressed)."""
    import trimesh

    if path.suffix == ".xz":
        with lzma.open(path) as f:
            m = trimesh.load(f, file_type=Path(path.stem).suffix[1:], process=False)
    else:
        m = trimesh.load(path, process=False)
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def read_dmat(path: Path) -> np.ndarray:
    """A one-column ASCII DMAT file (libigl) as an int array."""
    values = path.read_text().split()
    cols, rows = int(values[0]), int(values[1])
    return np.array(values[2:2 + cols * rows], float).astype(int)


def components(V, F, mask):
    """Connected components of the vertices in ``mask`` through triangles wholly inside it:
    a label per vertex (−1 outside the mask)."""
    Fm = F[mask[F].all(axis=1)]
    A = sp.coo_matrix((np.ones(Fm.size), (Fm.ravel(), Fm[:, [1, 2, 0]].ravel())),
                      shape=(len(V), len(V)))
    labels = connected_components(A, directed=False)[1]
    return np.where(mask, labels, -1)


def knight() -> Case:
    """libigl tutorial 405 at anim_t = 1, its handle path for anim_t ∈ [0, 1]."""
    V, F = read_mesh(DATA / "decimated-knight.off")
    S = read_dmat(DATA / "decimated-knight-selection.dmat")
    b = np.flatnonzero(S >= 0)
    mid = 0.5 * (V.max(0) + V.min(0))
    r0, r1 = 0.25 * mid[0], 0.15 * mid[1]

    def path(t):
        bc = V[b].copy()
        s = S[b]
        ang = np.pi * t
        bc[s == 0, 0] += r0 * np.sin(ang)
        bc[s == 0, 1] -= r0 + r0 * np.cos(np.pi + ang)
        bc[s == 1, 1] += r1 + r1 * np.cos(np.pi + 0.3 * ang)
        bc[s == 1, 2] -= r1 * np.sin(0.3 * ang)
        bc[s == 2, 2] += r1 + r1 * np.cos(np.pi + 0.7 * ang)
        bc[s == 2, 0] += r1 * np.sin(0.7 * ang)
        return bc

    return Case("knight", V, F, b, path, S[b])


def bunny() -> Case:
    """The ear nearer the tail (x > −0.05): its tip (y > 0.165) turned 90° backwards about
    a lateral (z) axis through the ear's base (0.14 < y < 0.15); the bottom fixed."""
    V, F = read_mesh(DATA / "bunny.off")
    labels = components(V, F, (V[:, 0] > -0.05) & (V[:, 1] > 0.14))
    ids, counts = np.unique(labels[labels >= 0], return_counts=True)
    ear = labels == ids[np.argmax(counts)]
    tip = np.flatnonzero(ear & (V[:, 1] > 0.165))
    pivot = V[ear & (V[:, 1] < 0.15)].mean(0)
    bottom = np.flatnonzero(V[:, 1] < V[:, 1].min() + 0.02 * np.ptp(V[:, 1]))
    b = np.concatenate([tip, bottom])
    moved = turning(V[tip], pivot, [0, 0, 1], -np.pi / 2)
    return Case("bunny", V, F, b, lambda t: np.concatenate([moved(t), V[bottom]]),
                np.r_[np.ones(len(tip)), np.zeros(len(bottom))])


def bunny_ear_120() -> Case:
    """The bunny case with the ear's tip turned 120° instead of 90° (into the back)."""
    case = bunny()
    V = case.V
    tip = case.handles[case.groups == 1]
    bottom = case.handles[case.groups == 0]
    labels = components(V, case.F, (V[:, 0] > -0.05) & (V[:, 1] > 0.14))
    ids, counts = np.unique(labels[labels >= 0], return_counts=True)
    pivot = V[(labels == ids[np.argmax(counts)]) & (V[:, 1] < 0.15)].mean(0)
    moved = turning(V[tip], pivot, [0, 0, 1], -2.0 * np.pi / 3.0)
    return Case("bunny ear 120", V, case.F, case.handles,
                lambda t: np.concatenate([moved(t), V[bottom]]), case.groups)


def bar_folded() -> Case:
    """The 6×1×1 bar folded back on itself in the x–y plane: the cap x = 6 turned 180°
    about z so that its centre lands at (3, 1.7, 0.5), 0.2 above the bar's top face (the
    turned half driven against the fixed one); the cap x = 0 fixed."""
    V, F = box_surface([6.0, 1.0, 1.0], 0.1)
    pivot = planar_pivot([6.0, 0.5, 0.5], [3.0, 1.7, 0.5], [0, 0, 1], np.pi)
    return region_turn("bar folded", V, F, V[:, 0] > 6.0 - 1e-9, V[:, 0] < 1e-9,
                       [0, 0, 1], np.pi, pivot)


def armadillo() -> Case:
    """The hand on the +x side (arm: x > 0.15, y > 0; hand: z > 0.25) raised, turned −90°
    about the lateral (x) axis through the shoulder; the feet fixed."""
    V, F = read_mesh(DATA / "armadillo.ply.xz")
    labels = components(V, F, (V[:, 0] > 0.15) & (V[:, 1] > 0.0))
    ids, counts = np.unique(labels[labels >= 0], return_counts=True)
    arm = labels == ids[np.argmax(counts)]
    hand = np.flatnonzero(arm & (V[:, 2] > 0.25))
    pivot = V[arm & (V[:, 0] < 0.18)].mean(0)
    feet = np.flatnonzero(V[:, 1] < V[:, 1].min() + 0.06)
    b = np.concatenate([hand, feet])
    moved = turning(V[hand], pivot, [1, 0, 0], -np.pi / 2)
    return Case("armadillo", V, F, b, lambda t: np.concatenate([moved(t), V[feet]]),
                np.r_[np.ones(len(hand)), np.zeros(len(feet))])


def box_surface(size, spacing):
    """Triangulated surface of the box [0, a]×[0, b]×[0, c]: each face a grid of squares
    of side ≈ ``spacing`` cut into two triangles, duplicate vertices merged, normals out."""
    import trimesh

    parts = []
    size = np.asarray(size, float)
    for axis in range(3):
        u, v = [k for k in range(3) if k != axis]
        nu, nv = (np.round(size[[u, v]] / spacing).astype(int))
        s, r = np.meshgrid(np.linspace(0, size[u], nu + 1), np.linspace(0, size[v], nv + 1),
                           indexing="ij")
        idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
        a, b_ = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
        c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
        tri = np.concatenate([np.stack([a, b_, c], 1), np.stack([a, c, d], 1)])
        for side in (0.0, size[axis]):
            P = np.zeros((s.size, 3))
            P[:, u], P[:, v], P[:, axis] = s.ravel(), r.ravel(), side
            parts.append(trimesh.Trimesh(P, tri, process=False))
    m = trimesh.util.concatenate(parts)
    m.merge_vertices()
    V, F = np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
    # a convex box: a face is outward when its normal points away from the centre
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    inward = np.einsum("ij,ij->i", n, V[F].mean(axis=1) - size / 2) < 0
    F[inward] = F[inward, ::-1]
    return V, F


def bar() -> Case:
    """A 6×1×1 box, the cap x = 6 turned 180° about the long axis, the cap x = 0 fixed."""
    V, F = box_surface([6.0, 1.0, 1.0], 0.1)
    fixed = np.flatnonzero(V[:, 0] < 1e-9)
    end = np.flatnonzero(V[:, 0] > 6.0 - 1e-9)
    moved = turning(V[end], np.array([6.0, 0.5, 0.5]), [1, 0, 0], np.pi)
    b = np.concatenate([end, fixed])
    return Case("bar", V, F, b, lambda t: np.concatenate([moved(t), V[fixed]]),
                np.r_[np.ones(len(end)), np.zeros(len(fixed))])


def boundary_pivot(V, F, moving):
    """Centroid of the moving region's boundary: its vertices with a neighbour outside."""
    inside = moving[F]
    mixed = F[inside.any(axis=1) & ~inside.all(axis=1)]
    ring = np.unique(mixed[moving[mixed]])
    return V[ring].mean(axis=0)


def region_turn(name, V, F, moving, fixed, axis, angle, pivot=None) -> Case:
    """Case: the vertices in the mask ``moving`` turned by ``angle`` about ``axis`` through
    ``pivot`` (default: the centroid of the moving region's boundary), those in ``fixed``
    kept, the angle interpolated along the path."""
    m = np.flatnonzero(moving)
    f = np.flatnonzero(fixed & ~moving)
    if pivot is None:
        pivot = boundary_pivot(V, F, moving)
    moved = turning(V[m], pivot, axis, angle)
    return Case(name, V, F, np.concatenate([m, f]),
                lambda t: np.concatenate([moved(t), V[f]]),
                np.r_[np.ones(len(m)), np.zeros(len(f))])


def planar_pivot(a, b, axis, angle):
    """The point about which the turn by ``angle`` about ``axis`` maps ``a`` onto ``b``
    (both in one plane normal to ``axis``)."""
    R = rotation(axis, angle)
    p, *_ = np.linalg.lstsq(np.eye(3) - R, np.asarray(b) - R @ np.asarray(a), rcond=None)
    return p


# Cases not used while the method was developed: real meshes of data/surfaces (Keenan
# Crane's spot, bob and blub, public domain) and generated ones; the handles are chosen by
# coordinate predicates, one region fixed, one turned about an axis through its boundary.

def spot_head() -> Case:
    """Spot (y up, head towards −z): the head (z < −0.25) turned 60° sideways about the
    vertical axis through the neck; the hooves (y < −0.65) fixed."""
    V, F = read_mesh(DATA / "spot.obj")
    return region_turn("spot head", V, F, V[:, 2] < -0.25, V[:, 1] < -0.65,
                       [0, 1, 0], np.pi / 3)


def spot_leg() -> Case:
    """Spot's front leg on the +x side below y = −0.6 bent 60° backwards about a lateral
    axis through its boundary; the other three hooves (y < −0.65) fixed."""
    V, F = read_mesh(DATA / "spot.obj")
    leg = (V[:, 0] > 0) & (V[:, 2] < 0.3) & (V[:, 1] < -0.6)
    return region_turn("spot leg", V, F, leg, V[:, 1] < -0.65, [1, 0, 0], -np.pi / 3)


def bob_head() -> Case:
    """Bob (y up, head towards −x): the head (y > 0.1, x < −0.2) turned 90° about the
    vertical axis through the neck; the bottom (lowest 5 % of the height) fixed."""
    V, F = read_mesh(DATA / "bob.obj")
    bottom = V[:, 1] < V[:, 1].min() + 0.05 * np.ptp(V[:, 1])
    return region_turn("bob head", V, F, (V[:, 1] > 0.1) & (V[:, 0] < -0.2), bottom,
                       [0, 1, 0], np.pi / 2)


def blub_tail() -> Case:
    """Blub (a fish along x, head towards +x): the tail fin (x < −0.35) turned 60°
    sideways about the vertical axis through its boundary; the head (x > 0.25) fixed."""
    V, F = read_mesh(DATA / "blub.obj")
    return region_turn("blub tail", V, F, V[:, 0] < -0.35, V[:, 0] > 0.25, [0, 1, 0],
                       np.pi / 3)


def bar_bent() -> Case:
    """The 6×1×1 bar bent 90° in the x–y plane: the cap x = 6 turned to the end of a
    quarter circle of length 6 (the turn's pivot from the cap's centre), the cap x = 0
    fixed."""
    V, F = box_surface([6.0, 1.0, 1.0], 0.1)
    r = 6.0 / (np.pi / 2)
    pivot = planar_pivot([6.0, 0.5, 0.5], [r, 0.5 + r, 0.5], [0, 0, 1], np.pi / 2)
    return region_turn("bar bent", V, F, V[:, 0] > 6.0 - 1e-9, V[:, 0] < 1e-9,
                       [0, 0, 1], np.pi / 2, pivot)


def strip_surface(length: float, width: float, spacing: float):
    """An open flat strip [0, length]×[0, width] in z = 0, squares cut into two triangles."""
    nu, nv = int(round(length / spacing)), int(round(width / spacing))
    s, r = np.meshgrid(np.linspace(0, length, nu + 1), np.linspace(0, width, nv + 1),
                       indexing="ij")
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return np.stack([s.ravel(), r.ravel(), np.zeros(s.size)], 1), F.astype(np.int64)


def plate_bent() -> Case:
    """An open 4×1 strip (spacing 0.05) rolled 90° upwards: the band x ≥ 3.9 turned to the
    end of a quarter circle of length 4 about a lateral (y) axis, the band x ≤ 0.1 fixed."""
    V, F = strip_surface(4.0, 1.0, 0.05)
    r = 4.0 / (np.pi / 2)
    pivot = planar_pivot([4.0, 0.0, 0.0], [r, 0.0, r], [0, -1, 0], np.pi / 2)
    return region_turn("plate bent", V, F, V[:, 0] > 3.9 - 1e-9, V[:, 0] < 0.1 + 1e-9,
                       [0, -1, 0], np.pi / 2, pivot)


# ``--unseen2``: more cases defined by coordinate rules before ours was run on them: the
# other ear, tails, and generated open tubes, a thin plate, a holed strip and a disc.

def largest_component(V, F, mask):
    """The largest connected component of ``mask`` (see :func:`components`) as a mask."""
    labels = components(V, F, mask)
    ids, counts = np.unique(labels[labels >= 0], return_counts=True)
    return labels == ids[np.argmax(counts)]


def bunny_front_ear() -> Case:
    """The bunny's front ear (z < −0.035, y > 0.14): its tip (y > 0.165) turned 90°
    outwards (to −z) about the long (x) axis through the ear's base (y < 0.155); the
    bottom (lowest 2 % of the height) fixed."""
    V, F = read_mesh(DATA / "bunny.off")
    ear = largest_component(V, F, (V[:, 2] < -0.035) & (V[:, 1] > 0.14))
    bottom = V[:, 1] < V[:, 1].min() + 0.02 * np.ptp(V[:, 1])
    return region_turn("bunny front ear", V, F, ear & (V[:, 1] > 0.165), bottom,
                       [1, 0, 0], -np.pi / 2, V[ear & (V[:, 1] < 0.155)].mean(0))


def bob_tail() -> Case:
    """Bob's tail (x > 0.6, y > 0.03) tilted 60° sideways (to +z) about the long (x)
    axis through its boundary; the bottom (lowest 5 % of the height) fixed."""
    V, F = read_mesh(DATA / "bob.obj")
    bottom = V[:, 1] < V[:, 1].min() + 0.05 * np.ptp(V[:, 1])
    tail = largest_component(V, F, (V[:, 0] > 0.6) & (V[:, 1] > 0.03))
    return region_turn("bob tail", V, F, tail, bottom, [1, 0, 0], np.pi / 3)


def armadillo_tail() -> Case:
    """The armadillo's tail (z < −0.2, y < −0.1) turned 60° sideways about the vertical
    axis through its boundary; the feet fixed (as in the armadillo case)."""
    V, F = read_mesh(DATA / "armadillo.ply.xz")
    tail = largest_component(V, F, (V[:, 2] < -0.2) & (V[:, 1] < -0.1))
    return region_turn("armadillo tail", V, F, tail, V[:, 1] < V[:, 1].min() + 0.06,
                       [0, 1, 0], np.pi / 3)


def tube_surface(length: float, radius: float, spacing: float):
    """An open circular tube about the x axis, x ∈ [0, length]: rings of ≈ ``spacing``
    apart, squares cut into two triangles, normals out."""
    nu = int(round(length / spacing))
    nv = int(round(2 * np.pi * radius / spacing))
    x, a = np.meshgrid(np.linspace(0, length, nu + 1), np.arange(nv) * (2 * np.pi / nv),
                       indexing="ij")
    idx = np.arange((nu + 1) * nv).reshape(nu + 1, nv)
    nxt = np.roll(idx, -1, axis=1)
    a0, b0, c0, d0 = idx[:-1].ravel(), idx[1:].ravel(), nxt[1:].ravel(), nxt[:-1].ravel()
    # ordered so that the normals point away from the axis
    F = np.concatenate([np.stack([a0, c0, b0], 1), np.stack([a0, d0, c0], 1)])
    V = np.stack([x.ravel(), radius * np.cos(a.ravel()), radius * np.sin(a.ravel())], 1)
    return V, F.astype(np.int64)


def tube_twist() -> Case:
    """An open tube (length 4, radius 0.5, spacing ≈ 0.0625): the band x ≥ 3.9 turned
    180° about the tube's axis, the band x ≤ 0.1 fixed."""
    V, F = tube_surface(4.0, 0.5, 0.0625)
    return region_turn("tube twist", V, F, V[:, 0] > 3.9 - 1e-9, V[:, 0] < 0.1 + 1e-9,
                       [1, 0, 0], np.pi, np.array([4.0, 0.0, 0.0]))


def tube_bent() -> Case:
    """The open tube of :func:`tube_twist` bent 90° in the x–y plane: the band x ≥ 3.9
    turned so that the end ring's centre goes to the end of a quarter circle of length 4,
    the band x ≤ 0.1 fixed."""
    V, F = tube_surface(4.0, 0.5, 0.0625)
    r = 4.0 / (np.pi / 2)
    pivot = planar_pivot([4.0, 0.0, 0.0], [r, r, 0.0], [0, 0, 1], np.pi / 2)
    return region_turn("tube bent", V, F, V[:, 0] > 3.9 - 1e-9, V[:, 0] < 0.1 + 1e-9,
                       [0, 0, 1], np.pi / 2, pivot)


def plate_twist() -> Case:
    """A thin 4×1×0.1 box (spacing 0.05): the cap x = 4 turned 90° about the long axis
    through its centre, the cap x = 0 fixed."""
    V, F = box_surface([4.0, 1.0, 0.1], 0.05)
    return region_turn("plate twist", V, F, V[:, 0] > 4.0 - 1e-9, V[:, 0] < 1e-9,
                       [1, 0, 0], np.pi / 2, np.array([4.0, 0.5, 0.05]))


def holed_strip(length: float, width: float, spacing: float, centre, radius: float):
    """:func:`strip_surface` without the squares whose centre is within ``radius`` of
    ``centre`` (x, y), unused vertices dropped (the others keep their order)."""
    V, F = strip_surface(length, width, spacing)
    # each square is two consecutive halves: rows k and k + n of F (a, b, c) / (a, c, d)
    n = len(F) // 2
    mid = 0.5 * (V[F[:n, 0]] + V[F[:n, 2]])
    keep = np.linalg.norm(mid[:, :2] - np.asarray(centre), axis=1) >= radius
    F = np.concatenate([F[:n][keep], F[n:][keep]])
    used = np.zeros(len(V), bool)
    used[F] = True
    new = np.cumsum(used) - 1
    return V[used], new[F]


def strip_hole() -> Case:
    """The rolled strip of :func:`plate_bent` with a hole (the squares whose centre is
    within 0.25 of its middle (2, 0.5) removed)."""
    V, F = holed_strip(4.0, 1.0, 0.05, [2.0, 0.5], 0.25)
    r = 4.0 / (np.pi / 2)
    pivot = planar_pivot([4.0, 0.0, 0.0], [r, 0.0, r], [0, -1, 0], np.pi / 2)
    return region_turn("strip hole", V, F, V[:, 0] > 3.9 - 1e-9, V[:, 0] < 0.1 + 1e-9,
                       [0, -1, 0], np.pi / 2, pivot)


def disc_surface(rings: int):
    """A flat unit disc in z = 0: the centre and ``rings`` rings (ring k of radius
    k/rings with 6k points, alternate rings turned half a step), Delaunay triangles
    oriented with normals +z."""
    from scipy.spatial import Delaunay

    pts = [np.zeros((1, 2))]
    for k in range(1, rings + 1):
        a = (np.arange(6 * k) + 0.5 * (k % 2)) * (2 * np.pi / (6 * k))
        pts.append(k / rings * np.stack([np.cos(a), np.sin(a)], 1))
    P = np.concatenate(pts)
    F = Delaunay(P).simplices.astype(np.int64)
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    F[cw] = F[cw, ::-1]
    return np.column_stack([P, np.zeros(len(P))]), F


def disc_bump() -> Case:
    """A flat unit disc (30 rings, 5.4k triangles): the middle (r ≤ 0.2) raised by 0.4
    into a bump, the rim band (r ≥ 0.95) fixed."""
    V, F = disc_surface(30)
    r = np.linalg.norm(V[:, :2], axis=1)
    m, f = np.flatnonzero(r <= 0.2 + 1e-9), np.flatnonzero(r >= 0.95 - 1e-9)
    lift = np.array([0.0, 0.0, 0.4])
    return Case("disc bump", V, F, np.concatenate([m, f]),
                lambda t: np.concatenate([V[m] + t * lift, V[f]]),
                np.r_[np.ones(len(m)), np.zeros(len(f))])


CASES = {"knight": knight, "bunny": bunny, "armadillo": armadillo, "bar": bar}
#: ``--contact``: motions that drive parts of a surface into each other
CONTACT = {"bunny-ear-120": bunny_ear_120, "bar-folded": bar_folded}
#: ``--unseen``: cases defined by simple rules after the method's defaults were fixed
UNSEEN = {"spot-head": spot_head, "spot-leg": spot_leg, "bob-head": bob_head,
          "blub-tail": blub_tail, "bar-bent": bar_bent, "plate-bent": plate_bent}
#: ``--unseen2``: more such cases, defined before ours was run on them
UNSEEN2 = {"bunny-front-ear": bunny_front_ear, "bob-tail": bob_tail,
           "armadillo-tail": armadillo_tail, "tube-twist": tube_twist, "tube-bent": tube_bent,
           "plate-twist": plate_twist, "strip-hole": strip_hole, "disc-bump": disc_bump}
#: the knight's files are not committed (no licence is stated for the model): its case runs
#: where they have been copied from the libigl tutorial data into data/surfaces
KNIGHT_FILES = ("decimated-knight.off", "decimated-knight-selection.dmat")
if not all((DATA / name).exists() for name in KNIGHT_FILES):
    del CASES["knight"]


def harmonic(case: Case, k: int, t: float = 1.0) -> np.ndarray:
    """libigl's k-harmonic extension of the handle displacements."""
    import igl

    bc = case.path(t) - case.V[case.handles]
    return case.V + igl.harmonic(case.V, case.F, case.handles.astype(np.int64), bc, k)


def _arap_data(case: Case, iterations: int):
    import igl

    data = igl.ARAPData()
    data.max_iter = iterations
    igl.arap_precomputation(case.V, case.F, 3, case.handles.astype(np.int32), data)
    return data


def arap_single(case: Case) -> np.ndarray:
    """libigl ARAP, 100 iterations from the biharmonic extension."""
    import igl

    data = _arap_data(case, 100)
    return np.asarray(igl.arap_solve(case.path(1.0), data, harmonic(case, 2)))


STEP_ITERATIONS = [50]  # ARAP iterations per increment (--step-iterations)


def arap_incremental(case: Case, steps: int = STEPS) -> np.ndarray:
    """libigl ARAP in ``steps`` increments along the handles' path, ``STEP_ITERATIONS``
    iterations each (libigl runs exactly that many), each started from the previous result."""
    import igl

    data = _arap_data(case, STEP_ITERATIONS[0])
    U = case.V.copy()
    for k in range(1, steps + 1):
        U = np.asarray(igl.arap_solve(case.path(k / steps), data, U))
    return U


OURS_FRAMES: list = []  # ours' frames of the last run (the rest first, the result last)


def ours(case: Case) -> np.ndarray:
    """``meshopt_toolkit.motion.surface.move.move_surface`` (ImportError when absent)."""
    from meshopt_toolkit.motion.surface.move import move_surface

    result = move_surface(case.V, case.F, case.handles, case.path(1.0))
    OURS_FRAMES[:] = [np.asarray(X) for X in result.frames]
    return np.asarray(result.points)


def frame_intersections(case: Case, frames: list) -> list:
    """``(frame index, pymeshlab's self-intersecting faces, exact intersecting pairs)`` of
    every frame whose surface passes through itself (``kernels/intersections3d.py``)."""
    from meshopt_toolkit.kernels.intersections3d import self_intersections

    out = []
    for k, X in enumerate(frames):
        faces = self_intersecting_faces(X, case.F)
        pairs = self_intersections(X, case.F)
        if faces or len(pairs):
            out.append((k, faces, pairs))
    return out


METHODS = {
    "ours": ours,
    "harmonic": lambda c: harmonic(c, 1),
    "biharmonic": lambda c: harmonic(c, 2),
    "ARAP": arap_single,
    f"ARAP {STEPS} steps": arap_incremental,
}


def measure(case: Case, U: np.ndarray, seconds: float) -> dict:
    """The printed measures of one result."""
    from meshopt_toolkit.kernels.intersections3d import self_intersections

    return {
        "quality": worst_relative_quality(case.V, U, case.F, case.handles),
        "folds": fold_count(case.V, U, case.F, case.handles),
        "handle error": float(np.abs(U[case.handles] - case.path(1.0)).max()),
        "seconds": seconds,
        "ARAP energy": arap_energy(case.V, U, case.F),
        "self-intersecting": self_intersecting_faces(U, case.F),
        "exact pairs": len(self_intersections(U, case.F)),
    }


def figure(case: Case, results: dict, path: Path) -> None:
    """Rest (handles coloured by group), then each result coloured by relative quality."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    shown = [m for m in ("ours", "ARAP", f"ARAP {STEPS} steps", "biharmonic") if m in results]
    fig = plt.figure(figsize=(4.2 * (1 + len(shown)), 4.6))
    cmap = plt.get_cmap("viridis")
    grey = np.array([0.8, 0.8, 0.8, 1.0])
    colours = plt.get_cmap("tab10")
    is_handle = np.zeros(len(case.V), bool)
    is_handle[case.handles] = True
    group = np.zeros(len(case.V))
    group[case.handles] = case.groups
    rest_face = np.where(is_handle[case.F].all(1)[:, None],
                         colours(group[case.F[:, 0]].astype(int) % 10), grey)
    up = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0.0]])  # y-up data shown z-up
    panels = [("rest, handles", case.V @ up.T, rest_face)]
    for m in shown:
        U = results[m]
        rq = np.clip(relative_quality(case.V, U, case.F), 0, 1)
        panels.append((m, U @ up.T, cmap(rq)))
    lo = np.min([P.min(0) for _, P, _ in panels], axis=0)
    hi = np.max([P.max(0) for _, P, _ in panels], axis=0)
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    for i, (title, P, fc) in enumerate(panels):
        n = normals(P, case.F)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        fc = np.array(fc, float)
        fc[:, :3] *= (0.45 + 0.55 * np.abs(n @ light))[:, None]  # two-sided diffuse shading
        ax = fig.add_subplot(1, len(panels), i + 1, projection="3d")
        ax.add_collection3d(Poly3DCollection(P[case.F], facecolors=fc, edgecolors="none"))
        ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(lo[2], hi[2])
        ax.set_box_aspect(hi - lo)
        ax.view_init(elev=15, azim=-60)
        ax.set_title(title)
        ax.set_axis_off()
    fig.colorbar(plt.cm.ScalarMappable(cmap=cmap), ax=fig.axes, shrink=0.6,
                 label="aspect ratio / rest aspect ratio")
    fig.suptitle(f"{case.name}: {len(case.F)} triangles")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_case(case: Case, methods) -> dict:
    """Run the methods on a case, print one row each; return the results that ran."""
    print(f"\n{case.name}: {len(case.V)} vertices, {len(case.F)} triangles, "
          f"{len(case.handles)} handle vertices")
    print(f"  {'method':<14} {'worst rel. q':>12} {'folds':>6} {'handle err':>11} "
          f"{'seconds':>8} {'ARAP energy':>12} {'self-int. faces':>15} {'exact pairs':>11}")
    results, rows = {}, {}
    for name in methods:
        try:
            t0, c0 = time.perf_counter(), time.process_time()
            U = METHODS[name](case)
            seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
        except ImportError as err:
            print(f"  {name:<14} not available ({err})")
            continue
        except Exception as err:  # a method that gives up is a row, not the end of the run
            print(f"  {name:<14} failed: {type(err).__name__}: {err}")
            continue
        results[name] = U
        r = rows[name] = measure(case, U, seconds)
        r["CPU seconds"] = cpu
        print(f"  {name:<14} {r['quality']:>12.3f} {r['folds']:>6d} {r['handle error']:>11.1e} "
              f"{r['seconds']:>8.2f} {r['ARAP energy']:>12.4g} {r['self-intersecting']:>15d}"
              f" {r['exact pairs']:>11d}  ({cpu:.2f} CPU s)", flush=True)
        if name == "ours" and EVERY_FRAME[0]:
            bad = frame_intersections(case, OURS_FRAMES)
            r["every frame"] = max((faces for _, faces, _ in bad), default=0)
            print(f"  ours' {len(OURS_FRAMES)} frames: largest self-intersecting face count "
                  f"{r['every frame']}" + "".join(
                      f"; frame {k}: {faces} faces, {len(pairs)} exact pairs "
                      f"{pairs[:8].tolist()}" for k, faces, pairs in bad), flush=True)
    arap = [rows[m] for m in ("ARAP", f"ARAP {STEPS} steps") if m in rows]
    if "ours" in rows and arap:
        o = rows["ours"]
        best_q = max(r["quality"] for r in arap)
        best_e = min(r["ARAP energy"] for r in arap)
        print(f"  ours / best libigl ARAP: quality {o['quality'] / best_q:.2f}×, "
              f"ARAP energy {o['ARAP energy'] / best_e:.2f}× (want ≤ 1.5×)")
        if f"ARAP {STEPS} steps" in rows:
            ratio = o["seconds"] / rows[f"ARAP {STEPS} steps"]["seconds"]
            print(f"  ours / ARAP {STEPS} steps: time {ratio:.2f}× (want ≤ 5×)")
    o = rows.get("ours")
    if o and o["self-intersecting"] > 0 and o["exact pairs"] == 0:
        o["rigid-pose faces"] = rigid_pose_faces(case.V, case.F)
    verdict = check(rows)
    if verdict:
        print("  " + verdict)
    if MARKDOWN[0]:
        print(markdown(case.name, rows, verdict))
    return results


MARKDOWN = [False]  # --markdown
EVERY_FRAME = [False]  # --every-frame


def markdown(name: str, rows: dict, verdict: str) -> str:
    """The case's rows as docs/benchmarks-surface.md's table rows (the best quality and the
    lowest energy in bold) and the verdict of :func:`check` as a last column of ours."""
    if not rows:
        return ""
    best_q = max(r["quality"] for r in rows.values())
    best_e = min(r["ARAP energy"] for r in rows.values())
    out = []
    for i, (m, r) in enumerate(rows.items()):
        q, e = f"{r['quality']:.3f}", f"{r['ARAP energy']:.4g}"
        q = f"**{q}**" if r["quality"] == best_q else q
        e = f"**{e}**" if r["ARAP energy"] == best_e else e
        err = "0" if r["handle error"] == 0 else f"{r['handle error']:.1e}"
        extra = verdict.split(": ", 1)[-1] if m == "ours" and verdict else ""
        faces = str(r["self-intersecting"])
        if "every frame" in r:
            faces += f" ({r['every frame']} over every frame)"
        out.append(f"| {name if i == 0 else ''} | {m} | {q} | {r['folds']} | {err} | "
                   f"{r['seconds']:.2f} ({r['CPU seconds']:.2f} CPU) | {e} | {faces} | {extra} |")
    return "\n".join(out)


def check(rows: dict) -> str:
    """Ours against the best fold-free libigl method by worst relative quality: handles
    exact, no fold, no self-intersecting face (pymeshlab's test), quality ≥ that method's
    (to the printed three decimals) and ≥ 0.1, ARAP energy ≤ 1.5× that method's ("" where
    ours or every libigl method is missing)."""
    libigl = {m: r for m, r in rows.items() if m != "ours" and r["folds"] == 0}
    if "ours" not in rows or not libigl:
        return ""
    o = rows["ours"]
    best = max(libigl, key=lambda m: libigl[m]["quality"])
    q, e = o["quality"] / libigl[best]["quality"], o["ARAP energy"] / libigl[best]["ARAP energy"]
    # qualities compared as printed (three decimals): a tie at 1.000 is not a loss
    ok = (o["handle error"] == 0.0 and o["folds"] == 0 and o["quality"] >= 0.1 and e <= 1.5
          and o["self-intersecting"] <= 0
          and round(o["quality"], 3) >= round(libigl[best]["quality"], 3))
    why = ""
    if "rigid-pose faces" in o:  # pymeshlab's faces only, no exact pair
        why = (f" (pymeshlab's faces only, no exact pair; it selects "
               f"{o['rigid-pose faces']} on the rest turned rigidly)")
    return (f"ours / best fold-free libigl ({best}): quality {q:.3f}×, ARAP energy "
            f"{e:.2f}× — {'pass' if ok else 'FAIL'}{why}")


def main(argv=None) -> int:
    from _surface_cases3 import UNSEEN3  # imports this module's helpers
    from _surface_cases_contact import CONTACT2

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", help="comma-separated: "
                    + ", ".join({**CASES, **UNSEEN, **UNSEEN2, **UNSEEN3, **CONTACT,
                                 **CONTACT2})
                    + " (default: " + ", ".join(CASES) + ")")
    ap.add_argument("--unseen", action="store_true",
                    help="the cases defined after the method: " + ", ".join(UNSEEN))
    ap.add_argument("--unseen2", action="store_true",
                    help="more cases defined after the method: " + ", ".join(UNSEEN2))
    ap.add_argument("--unseen3", action="store_true",
                    help="a third such set (_surface_cases3.py): " + ", ".join(UNSEEN3))
    ap.add_argument("--contact", action="store_true",
                    help="motions that drive parts of a surface into each other: "
                    + ", ".join(CONTACT))
    ap.add_argument("--contact2", action="store_true",
                    help="two such motions defined before ours was run on them "
                    "(_surface_cases_contact.py): " + ", ".join(CONTACT2))
    ap.add_argument("--methods", default=",".join(METHODS),
                    help="comma-separated: " + ", ".join(METHODS))
    ap.add_argument("--figures", type=Path, help="write one PNG per case into this folder")
    ap.add_argument("--step-iterations", type=int, default=STEP_ITERATIONS[0],
                    help="ARAP iterations per increment (default %(default)s; libigl's own "
                         "default is 10)")
    ap.add_argument("--markdown", action="store_true",
                    help="also print each case's rows as the doc's table rows")
    ap.add_argument("--every-frame", action="store_true",
                    help="also test every frame of ours for self-intersections (pymeshlab's "
                         "faces and the exact kernel's pairs)")
    args = ap.parse_args(argv)
    MARKDOWN[0] = args.markdown
    EVERY_FRAME[0] = args.every_frame
    STEP_ITERATIONS[0] = args.step_iterations
    every = {**CASES, **UNSEEN, **UNSEEN2, **UNSEEN3, **CONTACT, **CONTACT2}
    default = {**(UNSEEN if args.unseen else {}), **(UNSEEN2 if args.unseen2 else {}),
               **(UNSEEN3 if args.unseen3 else {}),
               **(CONTACT if args.contact else {}),
               **(CONTACT2 if args.contact2 else {})} or CASES
    names = [c for c in (args.cases or ",".join(default)).split(",") if c]
    methods = [m for m in args.methods.split(",") if m]
    unknown = [c for c in names if c not in every] + [m for m in methods if m not in METHODS]
    if unknown:
        print(f"bench_surface: unknown case or method {unknown[0]!r}", file=sys.stderr)
        return 2
    if args.figures:
        args.figures.mkdir(parents=True, exist_ok=True)
    for name in names:
        case = every[name]()
        results = run_case(case, methods)
        if args.figures:
            out = args.figures / f"surface_{name}.png"
            figure(case, results, out)
            print(f"  figure: {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
