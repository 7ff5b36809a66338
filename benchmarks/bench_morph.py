"""Benchmark of the morph: frame quality against the ends and the alternatives,
and cost against one linear elasticity solve.

1. Pairs (source, target of the same connectivity): an annulus (r 0.3–1) and its copy with
   the inner circle turned 90° by a log-radius twist; the annulus and ``move``'s result for a
   180° turn; the 146- and 2198-vertex discs and their 225° twist; the channel and ``move``'s
   result for the cylinder pushed down 0.2; the 146-vertex disc and a copy turned 90° and
   scaled 1.5 (a similarity: every frame must be a similar copy). Columns: the worse end's
   min aspect ratio, the worst frame of ours (``mt.morph``, 9 frames) and its ratio
   to the worse end (≥ 0.9 wanted), the worst frame of linear and of
   as-rigid-as-possible interpolation (with inverted triangles), optionally the worst frame
   of the complete metric of f2 (``--with-scalar``: ``metric="complete"``, slow), time and
   Levenberg–Marquardt status.
2. ``--growth``: the 225° twist of disc_2198 (4.2k triangles), disc_13586 (27k) and its
   refinement (107k) up to ``--max-triangles``: seconds, seconds per elasticity solve (same
   mesh, same process), iterations (per level: the 107k pair is the refinement of the 27k
   one, so it is morphed coarse-to-fine, the 27k level's iterations + the 107k level's;
   ``--single-level`` turns that off), worst frame of ours, linear and ARAP.
``--more`` runs seven more pairs instead: each source with ``move``'s result for the
motions of ``bench_move.py --more``.
3. ``--figures DIR``: the strip and quality plot of docs/benchmarks.md of the 90° annulus pair.

Usage: ``python benchmarks/bench_morph.py [--growth [--single-level]] [--max-triangles 30000]
[--with-scalar] [--more] [--figures DIR]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _anchors import elasticity_motion
from _common import best_of

import meshopt_toolkit as mt
from meshopt_toolkit.generate import (annulus, channel_with_cylinder, log_twist,
                                      rotate_inner_boundary, shift_hole)
from meshopt_toolkit.kernels.triangles import aspect_ratios
from meshopt_toolkit.motion.planar.morph import distortion_morph
from meshopt_toolkit.generate import twisted


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


def more_pairs():
    """``--more``: each source with ``move``'s result for the seven motions of
    ``bench_move.py --more`` (shear, ellipse, star, hole scaled/shifted, cylinder moved)."""
    from bench_move import more_cases

    for name, mesh, handles, targets in more_cases(0.05):
        yield f"{name} (move)"[:30], mesh, mt.move(mesh, handles, targets).mesh


def _worst(stats) -> str:
    inv = int(stats.inverted.max())
    return f"{'inverts ' + str(inv):>12}" if inv else f"{np.nanmin(stats.min_aspect_ratio):12.4f}"


def table(with_scalar: bool, more: bool = False) -> None:
    print(f"{'pair':<31}{'tri':>6}{'worse end':>10}{'ours':>9}{'/end':>6}{'linear':>12}"
          f"{'ARAP':>12}{'scalar f2':>11}{'s':>7}  status")
    for name, src, tgt in (more_pairs if more else pairs)():
        tri = src.triangles
        end = min(_min_ar(src.points, tri), _min_ar(tgt.points, tri))
        t0 = time.perf_counter()
        res = mt.morph(src, tgt, frames=9)
        sec = time.perf_counter() - t0
        ours = float(np.min(res.stats.min_aspect_ratio))
        scalar = ""
        if with_scalar:
            old = mt.morph(src, tgt, frames=9, metric="complete")
            scalar = f"{min(_min_ar(p, tri) for p in old.discrete.points):11.1e}"
        print(f"{name:<31}{len(tri):>6}{end:10.4f}{ours:9.4f}{ours / end:6.2f}{_worst(res.linear)}"
              f"{_worst(res.rigid)}{scalar:>11}{sec:7.1f}  {res.status} ({res.nit} its, "
              f"start {res.initial_path})", flush=True)


def growth(max_triangles: int, single_level: bool = False) -> None:
    print("\ngrowth: the 225° twist of the bundled discs and their refinements, 9 frames")
    print(f"{'triangles':>10}{'seconds':>9}{'elast. s':>10}{'ratio':>8}{'its':>8}"
          f"{'ours':>9}{'linear':>12}{'ARAP':>12}")
    meshes = [mt.load(mt.data_path(n)).as_planar() for n in ("disc_2198.msh", "disc_13586.msh")]
    meshes.append(meshes[-1].refine())
    for src in meshes:
        if src.n_triangles > max_triangles:
            break
        tgt = twisted(src)
        b = src.boundary_vertices
        # the fastest of three solves: a conservative cost unit on a busy machine
        unit, _ = best_of(lambda: elasticity_motion(src.points, src.triangles, b,
                                                    tgt.points[b]), 3)
        t0 = time.perf_counter()
        res = distortion_morph(src, tgt, frames=9,
                               **({"coarse_min_triangles": 10**9} if single_level else {}))
        sec = time.perf_counter() - t0
        its = "+".join(str(level["iterations"]) for level in res.details["levels"])
        print(f"{src.n_triangles:>10}{sec:9.1f}{unit:10.3f}{sec / unit:8.0f}{its:>8}"
              f"{np.min(res.stats.min_aspect_ratio):9.4f}{_worst(res.linear)}{_worst(res.rigid)}",
              flush=True)


def figures(outdir: str) -> None:
    """The pictures of docs/benchmarks.md: strip and per-frame quality of the 90° annulus pair."""
    from pathlib import Path

    from meshopt_toolkit.plotting import save_morph_figures

    ring = annulus(0.05)
    res = mt.morph(ring, log_twist(ring, 90), frames=9)
    out = Path(outdir)
    for path in save_morph_figures(res, out / "morph_annulus_90_strip.png",
                                   out / "morph_annulus_90_quality.png", max_panels=5):
        print(f"wrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--growth", action="store_true")
    ap.add_argument("--max-triangles", type=int, default=30_000,
                    help="largest growth mesh (the 107k-triangle twist: 110000, minutes)")
    ap.add_argument("--single-level", action="store_true",
                    help="--growth without the coarse-to-fine start of refined pairs")
    ap.add_argument("--figures", metavar="DIR", help="only write the morph pictures of docs/benchmarks.md")
    ap.add_argument("--with-scalar", action="store_true",
                    help="also the complete metric of f2 (metric='complete'; minutes)")
    ap.add_argument("--more", action="store_true",
                    help="the seven motions of bench_move.py --more as pairs instead")
    args = ap.parse_args()
    if args.figures:
        figures(args.figures)
        return
    table(args.with_scalar, more=args.more)
    if args.growth:
        growth(args.max_triangles, args.single_level)


if __name__ == "__main__":
    main()
