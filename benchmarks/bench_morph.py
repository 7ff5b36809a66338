"""Benchmark of the morph (issue #15): frame quality against the ends and the alternatives,
and cost against one linear elasticity solve.

1. Pairs (source, target of the same connectivity): an annulus (r 0.3–1) and its copy with
   the inner circle turned 90° by a log-radius twist; the annulus and ``move``'s result for a
   180° turn; the 146- and 2198-vertex discs and their 225° twist; the channel and ``move``'s
   result for the cylinder pushed down 0.2; the 146-vertex disc and a copy turned 90° and
   scaled 1.5 (a similarity: every frame must be a similar copy). Columns: the worse end's
   min aspect ratio, the worst frame of ours (``distortion_morph``, 9 frames) and its ratio
   to the worse end (the issue asks ≥ 0.9), the worst frame of linear and of
   as-rigid-as-possible interpolation (with inverted triangles), optionally the worst frame
   of the complete metric of f2 (``--with-scalar``: ``geodesic_morph``, slow), time and
   Levenberg–Marquardt status.
2. ``--growth``: the 90° annulus twist on finer meshes up to ``--max-triangles``: seconds,
   seconds per elasticity solve (same mesh, same process), iterations, worst frame.

Usage: ``python benchmarks/bench_morph.py [--growth] [--max-triangles 50000] [--with-scalar]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _anchors import elasticity_motion

import meshopt_toolkit as mt
from meshopt_toolkit.generate import (annulus, channel_with_cylinder, log_twist,
                                      rotate_inner_boundary, shift_hole)
from meshopt_toolkit.geometry import aspect_ratios
from meshopt_toolkit.morph import twisted


def _min_ar(points, triangles) -> float:
    return float(aspect_ratios(points, triangles).min())


def pairs():
    ring = annulus(0.05)
    yield "annulus, 90° log twist", ring, log_twist(ring, 90)
    yield "annulus, 180° turn (move)", ring, mt.move(ring, *rotate_inner_boundary(ring, 180)).mesh
    for name in ("disc_146.msh", "disc_2198.msh"):
        disc = mt.load(mt.data_path(name)).as_planar()
        yield f"{name[:-4]}, 225° twist", disc, twisted(disc)
    channel = channel_with_cylinder(0.05)
    yield "channel, cylinder −0.2 (move)", channel, mt.move(channel, *shift_hole(channel, (0, -0.2))).mesh
    disc = mt.load(mt.data_path("disc_146.msh")).as_planar()
    c, s = np.cos(np.pi / 2), np.sin(np.pi / 2)
    yield "disc_146, turned 90° ×1.5", disc, disc.with_points(1.5 * disc.points @ [[c, s], [-s, c]])


def _worst(stats) -> str:
    inv = int(stats.inverted.max())
    return f"{'inverts ' + str(inv):>12}" if inv else f"{np.nanmin(stats.min_aspect_ratio):12.4f}"


def table(with_scalar: bool) -> None:
    print(f"{'pair':<31}{'tri':>6}{'worse end':>10}{'ours':>9}{'/end':>6}{'linear':>12}"
          f"{'ARAP':>12}{'scalar f2':>11}{'s':>7}  status")
    for name, src, tgt in pairs():
        tri = src.triangles
        end = min(_min_ar(src.points, tri), _min_ar(tgt.points, tri))
        t0 = time.perf_counter()
        res = mt.distortion_morph(src, tgt, frames=9)
        sec = time.perf_counter() - t0
        ours = float(np.min(res.stats.min_aspect_ratio))
        scalar = ""
        if with_scalar:
            old = mt.geodesic_morph(src, tgt, frames=9)
            scalar = f"{min(_min_ar(p, tri) for p in old.discrete.points):11.1e}"
        print(f"{name:<31}{len(tri):>6}{end:10.4f}{ours:9.4f}{ours / end:6.2f}{_worst(res.linear)}"
              f"{_worst(res.rigid)}{scalar:>11}{sec:7.1f}  {res.status} ({res.nit} its, "
              f"start {res.initial_path})", flush=True)


def growth(max_triangles: int) -> None:
    print("\ngrowth: annulus, 90° log twist, 9 frames")
    print(f"{'triangles':>10}{'seconds':>9}{'elast. s':>10}{'ratio':>8}{'its':>5}{'worst frame':>12}")
    size = 0.05
    while True:
        src = annulus(size)
        if src.n_triangles > max_triangles:
            break
        tgt = log_twist(src, 90)
        b = np.unique(src.boundary_edges)
        t0 = time.perf_counter()
        elasticity_motion(src.points, src.triangles, b, tgt.points[b])
        unit = time.perf_counter() - t0
        t0 = time.perf_counter()
        res = mt.distortion_morph(src, tgt, frames=9)
        sec = time.perf_counter() - t0
        print(f"{src.n_triangles:>10}{sec:9.1f}{unit:10.3f}{sec / unit:8.0f}{res.nit:5d}"
              f"{np.min(res.stats.min_aspect_ratio):12.4f}", flush=True)
        size /= 2


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--growth", action="store_true")
    ap.add_argument("--max-triangles", type=int, default=50_000)
    ap.add_argument("--with-scalar", action="store_true",
                    help="also the complete metric of f2 (geodesic_morph; minutes)")
    args = ap.parse_args()
    table(args.with_scalar)
    if args.growth:
        growth(args.max_triangles)


if __name__ == "__main__":
    main()
