"""The morph of tet meshes against linear interpolation of the vertices (gmsh box with a
spherical hole).

``python benchmarks/bench_tet_morph.py --size 0.12`` (about 23k tets): the source is the
box, the target its image under ``move_tets`` with the sphere turned about z (every
boundary vertex a handle, the outer boundary fixed). Prints, over the frames of each
method, the most inverted tets in a frame and the worst mean ratio, the ends' worst, and
the morph's seconds (iterations, initial path).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from bench_tet_move import box_with_hole, turn_case

from meshopt_toolkit.kernels.tetrahedra import mean_ratios, signed_volumes
from meshopt_toolkit.mesh import TetMesh
from meshopt_toolkit.motion.tets.morph import morph_tets
from meshopt_toolkit.motion.tets.move import move_tets


def frame_quality(frames, tets) -> tuple[int, float]:
    """The most tets not positively oriented in one frame, the worst signed mean ratio."""
    inverted = max(int(np.sum(~(signed_volumes(F, tets) > 0))) for F in frames)
    return inverted, min(float(mean_ratios(F, tets).min()) for F in frames)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", type=float, default=0.12, help="gmsh mesh size")
    ap.add_argument("--frames", type=int, default=9)
    ap.add_argument("--degrees", type=float, nargs="+", default=[90.0, 150.0])
    ap.add_argument("--push", type=float, default=0.0)
    ap.add_argument("--initial", default="auto", choices=("auto", "linear", "continuation"))
    args = ap.parse_args()
    P, T = box_with_hole(args.size)
    print(f"box with hole: {len(T)} tets, {len(P)} vertices; {args.frames} frames")
    print("| turn | method | inverted (worst frame) | worst mean ratio | ends' worse | seconds |")
    print("| --- | --- | --- | --- | --- | --- |")
    for degrees in args.degrees:
        handles, at = turn_case(P, T, degrees, args.push)
        t0 = time.perf_counter()
        Q = move_tets(P, T, handles, at(1.0)).points
        t_move = time.perf_counter() - t0
        ends = min(mean_ratios(P, T).min(), mean_ratios(Q, T).min())
        times = np.linspace(0.0, 1.0, args.frames)
        linear = [(1 - s) * P + s * Q for s in times]
        inv, worst = frame_quality(linear, T)
        print(f"| {degrees:g}° | linear interpolation | {inv} | {worst:.3f} | {ends:.3f} | — |")
        res = morph_tets(TetMesh(P, T), TetMesh(Q, T), args.frames, initial=args.initial)
        inv, worst = frame_quality(res.points, T)
        print(f"| {degrees:g}° | morph_tets ({res.initial_path} start, {res.nit} iterations, "
              f"{res.status}) | {inv} | {worst:.3f} | {ends:.3f} | {res.seconds:.1f} |")
        print(f"|  | (the target by move_tets) |  |  |  | {t_move:.1f} |", flush=True)


if __name__ == "__main__":
    main()
