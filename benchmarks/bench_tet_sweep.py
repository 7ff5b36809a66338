"""Unseen cases of tet-mesh motion: ours beside the careful optimizer and 1/V elasticity.

Cases not used to tune ``move_tets`` (gmsh meshes; every boundary vertex a handle, the
outer boundary fixed, each obstacle's surface following its own motion):

- box [-1, 1]³ with an ellipsoidal hole (semi-axes 0.45, 0.3, 0.2) turned 120° about the
  tilted axis (1, 2, 3)/√14;
- box [-1, 1]³ with two spheres r 0.25 at (±0.5, 0, 0) pushed 0.2 each towards the other
  (the gap 0.5 → 0.1);
- channel [0, 3] × [0, 1]² with a cylinder r 0.15, axis z, z ∈ [0.3, 0.7] at x = 1,
  y = 0.5, moved 0.8 along the channel;
- channel [0, 3] × [0, 1]² with a sphere r 0.2 at (1.5, 0.5, 0.5) pushed 0.25 towards the
  wall y = 0 (ending 0.05 from it).

Columns as in ``bench_move3d.py``: worst mean ratio η, inverted tets, largest handle
error, seconds, seconds per one 1/V elasticity solve; the last column is ours over the
careful optimizer's worst η (the requirement: ≥ 0.5).

Usage: ``python benchmarks/bench_tet_sweep.py [--size 0.11] [--cases WORD ...]
[--skip METHOD ...] [--careful-seconds 1200]``
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np
from _anchors3d import elasticity_motion
from _careful3d import careful_motion
from _meshes3d import generate_tets
from scipy.spatial.transform import Rotation

from meshopt_toolkit.gmsh_session import gmsh_session
from meshopt_toolkit.kernels.tetrahedra import mean_ratios as tet_mean_ratios
from meshopt_toolkit.motion.tets.move import move_tets


@dataclass
class Domain:
    points: np.ndarray
    tets: np.ndarray
    outer: np.ndarray  # vertices of the outer boundary
    obstacles: list[np.ndarray]  # vertices of each obstacle's surface


def mesh(outer_box, make_obstacles, size: float) -> Domain:
    """The box ``(x0, y0, z0, dx, dy, dz)`` minus the solids ``make_obstacles(occ)``
    returns (a list of volume tags), meshed by gmsh with edge length ``size``; an obstacle's
    faces are the boundary faces inside its bounding box."""
    with gmsh_session() as gmsh:
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add("sweep")
        occ = gmsh.model.occ
        box = occ.addBox(*outer_box)
        solids = make_obstacles(occ)
        occ.synchronize()
        boxes = [np.array(gmsh.model.getBoundingBox(3, t)) for t in solids]
        volume, _ = occ.cut([(3, box)], [(3, t) for t in solids])
        occ.synchronize()
        faces = [t for _, t in gmsh.model.getBoundary(volume, oriented=False)]

        def owner(tag):
            bb = np.array(gmsh.model.getBoundingBox(2, tag))
            for k, ob in enumerate(boxes):
                pad = 0.01 * (ob[3:] - ob[:3]).max()
                if np.all(bb[:3] >= ob[:3] - pad) and np.all(bb[3:] <= ob[3:] + pad):
                    return k
            return -1

        gmsh.model.addPhysicalGroup(3, [t for _, t in volume], 1)
        for k in range(-1, len(solids)):
            gmsh.model.addPhysicalGroup(2, [t for t in faces if owner(t) == k], 10 + k + 1)
        points, tets, (outer, *obstacles) = generate_tets(
            gmsh, size, [10 + k + 1 for k in range(-1, len(solids))])
    outer = np.setdiff1d(outer, np.concatenate(obstacles))
    return Domain(points, tets, outer, obstacles)


def rigid_path(domain: Domain, motions):
    """Handles (outer, then each obstacle's) and their path: obstacle ``k`` turns by
    ``t · angle`` about ``axis`` through ``centre`` and moves by ``t · shift``
    (``motions[k] = (centre, axis, angle in degrees, shift)``)."""
    handles = np.concatenate([domain.outer, *domain.obstacles])
    rest = domain.points[handles]
    spans = np.cumsum([len(domain.outer)] + [len(o) for o in domain.obstacles])

    def path(t: float) -> np.ndarray:
        out = rest.copy()
        for k, (centre, axis, angle, shift) in enumerate(motions):
            sl = slice(spans[k], spans[k + 1])
            axis = np.asarray(axis, float) / np.linalg.norm(axis)
            R = Rotation.from_rotvec(np.radians(angle) * t * axis).as_matrix()
            out[sl] = (np.asarray(centre) + t * np.asarray(shift, float)
                       + (rest[sl] - centre) @ R.T)
        return out

    return handles, path


def cases(size: float, only: list[str]):
    z = np.zeros(3)

    def ellipsoid(occ):
        tag = occ.addSphere(0, 0, 0, 1.0)
        occ.dilate([(3, tag)], 0, 0, 0, 0.45, 0.3, 0.2)
        return [tag]

    def two_balls(occ):
        return [occ.addSphere(-0.5, 0, 0, 0.25), occ.addSphere(0.5, 0, 0, 0.25)]

    def cylinder(occ):
        return [occ.addCylinder(1.0, 0.5, 0.3, 0, 0, 0.4, 0.15)]

    def ball(occ):
        return [occ.addSphere(1.5, 0.5, 0.5, 0.2)]

    box, channel = (-1, -1, -1, 2, 2, 2), (0, 0, 0, 3, 1, 1)
    table = [
        ("box, ellipsoidal hole turned 120° about a tilted axis", box, ellipsoid,
         [(z, (1, 2, 3), 120.0, z)], 1.0),
        ("box, two spheres pushed towards each other (gap 0.5 → 0.1)", box, two_balls,
         [((-0.5, 0, 0), (0, 0, 1), 0.0, (0.2, 0, 0)),
          ((0.5, 0, 0), (0, 0, 1), 0.0, (-0.2, 0, 0))], 1.0),
        ("channel, cylinder moved 0.8 along", channel, cylinder,
         [((1.0, 0.5, 0.5), (0, 0, 1), 0.0, (0.8, 0, 0))], 0.75),
        ("channel, sphere pushed 0.25 towards a side wall (0.05 from it)", channel, ball,
         [((1.5, 0.5, 0.5), (0, 0, 1), 0.0, (0, -0.25, 0))], 0.75),
    ]
    for name, outer, make, motions, scale in table:
        if only and not any(o in name for o in only):
            continue
        domain = mesh(outer, make, size * scale)
        yield name, domain, *rigid_path(domain, motions)


def ours(points, tets, handles, path):
    return np.asarray(move_tets(points, tets, handles, path(1.0)).points)


METHODS = {"elasticity 1/V": elasticity_motion, "ours": ours,
           "careful optimizer": careful_motion}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.11,
                    help="gmsh edge length on the box (the channel's is ¾ of it)")
    ap.add_argument("--cases", nargs="*", default=[], help="only cases whose name has WORD")
    ap.add_argument("--skip", nargs="*", default=[], help="leave out methods whose name has WORD")
    ap.add_argument("--careful-seconds", type=float, default=1200.0,
                    help="the careful optimizer's time limit per case")
    args = ap.parse_args()
    for name, domain, handles, path in cases(args.size, args.cases):
        src = tet_mean_ratios(domain.points, domain.tets).min()
        print(f"\n{name}: {len(domain.tets)} tets, {len(domain.points)} vertices, "
              f"{len(handles)} handles, source worst η {src:.3f}\n")
        print("| method | worst η | inverted | handle err | seconds | × elast. |")
        print("|---|---:|---:|---:|---:|---:|", flush=True)
        unit = None
        for method, fn in METHODS.items():
            if any(s in method for s in args.skip):
                continue
            if method == "careful optimizer":
                fn = lambda *a: careful_motion(*a, max_seconds=args.careful_seconds)  # noqa
            t0 = time.perf_counter()
            try:
                x = fn(domain.points, domain.tets, handles, path)
            except Exception as exc:  # a method failing is a result, not a crash
                print(f"| {method} | failed: {type(exc).__name__}: {str(exc)[:70]} | | | | |",
                      flush=True)
                continue
            sec = time.perf_counter() - t0
            unit = sec if method == "elasticity 1/V" else unit
            eta = tet_mean_ratios(x, domain.tets)
            err = float(np.abs(x[handles] - path(1.0)).max())
            ratio = f"{sec / unit:.1f}" if unit else ""
            print(f"| {method} | {np.nanmin(eta):.3f} | {int((~(eta > 0)).sum())} | "
                  f"{err:.1e} | {sec:.2f} | {ratio} |", flush=True)


if __name__ == "__main__":
    main()
