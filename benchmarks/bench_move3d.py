"""Benchmark of tetrahedral mesh motion: ours side by side with what users would otherwise use.

Cases (gmsh volume meshes; every boundary vertex is a handle, the outer boundary stays,
the obstacle's surface follows the motion; only the handles' path is prescribed):
  box [-1, 1]³ with a spherical hole r 0.35 whose sphere turns 90° and 180° about z, or
  grows to r 0.63 (0.37 from the walls); channel [0, 3] × [0, 1]² with a sphere r 0.15 at
  (1, 0.5, 0.5) pushed down 0.3 (ending 0.05 from the floor) or moved 1.5 along the channel.
Methods: ours (``move_tets``, where it is installed), harmonic extension (P1 Laplacian),
linear elasticity with E = 1/V (one solve: the cost unit) and the same in 10 increments,
ARAP (libigl), TMOP (mfem, shape metric 303 from the 10-step elasticity result, valid
starts only), and a careful optimizer (continuation with an exponential AMIPS energy,
L-BFGS refusing every inverted trial: the quality reference). Columns: worst mean ratio
η = 12(3V)^{2/3}/Σℓ² (1 for the regular tet, negative when inverted), inverted tets, max
handle error, seconds and seconds per elasticity solve, all run in this process.

``--growth`` prints the cost of the elasticity solve (assembly + sparse Cholesky + solve)
on the box at ~25k and ~200k tets (sizes 0.115 and 0.057; size 0.0285 gives ~1.6M).

Usage: ``python benchmarks/bench_move3d.py [--box-size 0.115] [--channel-size 0.06]
[--cases WORD ...] [--skip METHOD ...] [--growth]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _anchors3d import (arap_motion, elasticity_motion, harmonic_motion,
                        incremental_elasticity_motion, tmop_motion)
from _careful3d import careful_motion
from _common import best_of
from _meshes3d import box_with_ball, channel_with_ball, obstacle_path

from meshopt_toolkit.kernels.tetrahedra import mean_ratios as tet_mean_ratios

try:
    from meshopt_toolkit.motion.tets.move import move_tets
except ImportError:
    move_tets = None


CAREFUL_SECONDS = 1200.0  # the careful optimizer's time limit per case


def ours(points, tets, handles, path):
    return np.asarray(move_tets(points, tets, handles, path(1.0)).points)


METHODS = {
    "elasticity 1/V": elasticity_motion,
    "ours": ours,
    "harmonic": harmonic_motion,
    "elasticity 1/V ×10": incremental_elasticity_motion,
    "ARAP (libigl)": arap_motion,
    "TMOP (mfem)": tmop_motion,
    "careful optimizer": lambda *a: careful_motion(*a, max_seconds=CAREFUL_SECONDS),
}


def cases(box_size: float, channel_size: float, only: list[str]):
    wanted = [
        ("box, sphere turned 90°", "box", dict(turn=90.0)),
        ("box, sphere turned 180°", "box", dict(turn=180.0)),
        ("box, hole grown r 0.35 → 0.63", "box", dict(scale=1.8)),
        ("channel, sphere pushed down 0.3 (0.05 from the floor)", "channel",
         dict(shift=(0.0, 0.0, -0.3))),
        ("channel, sphere moved 1.5 along", "channel", dict(shift=(1.5, 0.0, 0.0))),
    ]
    wanted = [w for w in wanted if not only or any(o in w[0] for o in only)]
    meshes = {}
    for name, which, motion in wanted:
        if which not in meshes:
            meshes[which] = (box_with_ball(box_size) if which == "box"
                             else channel_with_ball(channel_size))
        domain = meshes[which]
        yield name, domain, *obstacle_path(domain, **motion)


def measure(fn, domain, handles, path):
    """``(worst η, inverted, handle error, seconds)``, or ``None`` and why."""
    t0 = time.perf_counter()
    try:
        x = fn(domain.points, domain.tets, handles, path)
    except ImportError as exc:
        return None, f"unavailable ({exc.name} not installed: pip install meshopt-toolkit[bench])"
    except Exception as exc:  # a reference method failing is a result, not a crash
        return None, f"failed: {type(exc).__name__}: {str(exc)[:70]}"
    seconds = time.perf_counter() - t0
    eta = tet_mean_ratios(x, domain.tets)
    err = float(np.abs(x[handles] - path(1.0)).max())
    return (float(np.nanmin(eta)), int((~(eta > 0)).sum()), err, seconds), None


def table(box_size: float, channel_size: float, only: list[str], skip: set[str]) -> None:
    for name, domain, handles, path in cases(box_size, channel_size, only):
        src = tet_mean_ratios(domain.points, domain.tets).min()
        print(f"\n{name}: {len(domain.tets)} tets, {len(domain.points)} vertices, "
              f"{len(handles)} handles, source worst η {src:.3f}\n")
        print("| method | worst η | inverted | handle err | seconds | × elast. |")
        print("|---|---:|---:|---:|---:|---:|")
        unit = None
        for method, fn in METHODS.items():
            if any(s in method for s in skip):
                continue
            if method == "ours" and move_tets is None:
                print("| ours | not available | | | | |", flush=True)
                continue
            row, why = measure(fn, domain, handles, path)
            if row is None:
                print(f"| {method} | {why} | | | | |", flush=True)
                continue
            eta, inv, err, sec = row
            if method == "elasticity 1/V":
                unit = sec
            ratio = f"{sec / unit:.1f}" if unit else ""
            print(f"| {method} | {eta:.3f} | {inv} | {err:.1e} | {sec:.2f} | {ratio} |",
                  flush=True)


def growth() -> None:
    """Cost of one elasticity solve (the unit) on the box turned 90° at ~25k and ~200k."""
    print("\ngrowth of one elasticity 1/V solve (assembly + sparse Cholesky + solve), "
          "box, sphere turned 90°\n")
    print("| tets | vertices | seconds (best of 3) |")
    print("|---:|---:|---:|")
    rows = []
    for size in (0.115, 0.057):
        domain = box_with_ball(size)
        handles, path = obstacle_path(domain, turn=90.0)
        sec, _ = best_of(lambda: elasticity_motion(domain.points, domain.tets, handles,
                                                   path), 3)
        rows.append((len(domain.tets), sec))
        print(f"| {len(domain.tets)} | {len(domain.points)} | {sec:.2f} |", flush=True)
    (n1, t1), (n2, t2) = rows
    k = np.log(t2 / t1) / np.log(n2 / n1)
    print(f"\n{n1} → {n2} tets: time × {t2 / t1:.1f}, i.e. ∝ tets^{k:.2f}; at that rate "
          f"1.6M tets (size 0.0285) would take ~{t2 * (1.6e6 / n2) ** k:.0f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--box-size", type=float, default=0.115, help="gmsh size (0.115: ~25k tets)")
    ap.add_argument("--channel-size", type=float, default=0.06,
                    help="gmsh size (0.06: ~65k tets)")
    ap.add_argument("--cases", nargs="*", default=[], help="only cases whose name has WORD")
    ap.add_argument("--skip", nargs="*", default=[], help="leave out the methods whose name has WORD")
    ap.add_argument("--growth", action="store_true", help="only the elasticity cost growth")
    args = ap.parse_args()
    if args.growth:
        growth()
        return
    if move_tets is None:
        print("ours: not available (meshopt_toolkit.motion.tets.move.move_tets not installed)")
    table(args.box_size, args.channel_size, args.cases, set(args.skip))


if __name__ == "__main__":
    main()
