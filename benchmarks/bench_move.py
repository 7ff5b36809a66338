"""Benchmark of ``move`` against what users would otherwise use.

Cases (all boundary vertices are handles; only their end positions are prescribed):
  annulus r 0.3–1 whose inner circle turns by 45°, 90°, 180°; a channel [0,3]×[0,1] whose
  cylinder (r 0.15 at (1, 0.5)) is pushed down by 0.2 and 0.3 (ending 0.15 and 0.05 from
  the wall).
Methods: ``move`` (ours), linear elasticity with E = 1/area (one solve: the cost unit),
harmonic and biharmonic extension, ARAP and SLIM (libigl), TMOP (mfem: worst-case untangler
then shape metric 2). Columns: min aspect ratio 2r/R over the triangles (0 when any is
inverted), mean Λ = mean 1/ψ (6.25; 1 when all are equilateral), inverted triangles, max
handle error, seconds and seconds per elasticity solve, all run side by side in this
process.

``--more`` runs seven more motions instead (disc boundary sheared, made an ellipse or a
star; annulus hole scaled or shifted; channel cylinder moved along or 0.01 from the wall).

``--growth`` adds the cost of ``move`` against one elasticity solve on refined annuli (90°)
up to ``--max-triangles``.

``--figure PNG`` draws the 90° annulus (source, harmonic, elasticity, TMOP, ours) instead;
the picture in docs/benchmarks.md is ``--figure examples/results/move_annulus_90.png``.

Usage: ``python benchmarks/bench_move.py [--size 0.05] [--growth] [--max-triangles 110000]
[--skip METHOD ...] [--more] [--figure PNG]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _anchors import (arap_motion, elasticity_motion, harmonic_motion, slim_motion,
                      tmop_motion)
from _common import best_of

import meshopt_toolkit as mt
from meshopt_toolkit.generate import annulus, channel_with_cylinder, rotate_inner_boundary, shift_hole
from meshopt_toolkit.kernels.triangles import aspect_ratios, inverse_shape_quality


def ours(points, triangles, handles, targets):
    mesh = mt.PlanarMesh(points, triangles)
    return mt.move(mesh, handles, targets).mesh.points


METHODS = {
    "elasticity 1/A": elasticity_motion,
    "move (ours)": ours,
    "harmonic": harmonic_motion,
    "biharmonic": lambda *a: harmonic_motion(*a, order=2),
    "ARAP (libigl)": arap_motion,
    "SLIM (libigl)": slim_motion,
    "TMOP (mfem)": tmop_motion,
}


def cases(size: float):
    ring = annulus(size)
    for degrees in (45, 90, 180):
        yield f"annulus, inner circle turned {degrees}°", ring, *rotate_inner_boundary(ring, degrees)
    channel = channel_with_cylinder(size)
    for drop in (0.2, 0.3):
        yield f"channel, cylinder pushed down {drop}", channel, *shift_hole(channel, (0.0, -drop))


def measure(fn, mesh, handles, targets):
    t0 = time.perf_counter()
    try:
        Q = fn(mesh.points, mesh.triangles, handles, targets)
    except ImportError as exc:
        return None, f"unavailable ({exc.name} not installed: pip install meshopt-toolkit[bench])"
    except Exception as exc:  # a reference method failing is a result, not a crash
        return None, f"failed: {type(exc).__name__}: {str(exc)[:60]}"
    seconds = time.perf_counter() - t0
    ar = aspect_ratios(Q, mesh.triangles)
    inverted = int((ar <= 0).sum())
    err = float(np.abs(Q[handles] - targets).max())
    mean_q = float(np.mean(inverse_shape_quality(Q, mesh.triangles))) if not inverted else np.nan
    return (0.0 if inverted else float(ar.min()), mean_q, inverted, err, seconds, Q), None


def more_cases(size: float):
    """Motions beyond the five main cases (``--more``): what a user would try next."""
    import meshopt_toolkit as mt

    disc = mt.load(mt.data_path("disc_2198.msh")).as_planar()
    b = np.unique(disc.boundary_edges)
    P = disc.points[b]
    angle = np.arctan2(P[:, 1], P[:, 0])
    yield "disc, boundary sheared x += 0.5 y", disc, b, P + np.c_[0.5 * P[:, 1], 0 * P[:, 0]]
    yield "disc, boundary to a 4 × 0.25 ellipse", disc, b, P * [4.0, 0.25]
    yield "disc, boundary to a star r = 1 + 0.3 cos 5θ", disc, b, P * (1 + 0.3 * np.cos(5 * angle))[:, None]
    ring = annulus(size)
    h = np.unique(ring.boundary_edges)
    inner = (np.linalg.norm(ring.points[h], axis=1) < 0.5)[:, None]
    yield "annulus, hole scaled 2.5×", ring, h, np.where(inner, 2.5 * ring.points[h], ring.points[h])
    yield "annulus, hole shifted 0.4", ring, h, ring.points[h] + np.where(inner, [0.4, 0.0], [0.0, 0.0])
    channel = channel_with_cylinder(size)
    yield "channel, cylinder moved along 1.5", channel, *shift_hole(channel, (1.5, 0.0))
    yield "channel, cylinder 0.01 from the wall", channel, *shift_hole(channel, (0.0, 0.34))


def table(size: float, skip: set[str], more: bool = False) -> None:
    for name, mesh, handles, targets in (more_cases if more else cases)(size):
        src = aspect_ratios(mesh.points, mesh.triangles).min()
        print(f"\n{name}: {mesh.n_triangles} triangles, {len(handles)} handles, "
              f"source min AR {src:.3f}")
        print(f"  {'method':<16}{'min AR':>9}{'mean Λ':>8}{'inverted':>10}{'handle err':>12}"
              f"{'seconds':>9}{'× elast.':>10}")
        unit = None
        for method, fn in METHODS.items():
            if method in skip:
                continue
            row, why = measure(fn, mesh, handles, targets)
            if row is None:
                print(f"  {method:<16}{why}")
                continue
            ar, lam, inv, err, sec, _ = row
            if method.startswith("elasticity"):
                unit = sec
            ratio = f"{sec / unit:10.1f}" if unit else f"{'':>10}"
            shown = f"{ar:9.4f}" if ar == 0 or ar >= 1e-3 else f"{ar:9.1e}"
            print(f"  {method:<16}{shown}{lam:8.3f}{inv:10d}{err:12.1e}{sec:9.2f}{ratio}")


def growth(size: float, max_triangles: int) -> None:
    print("\ngrowth: annulus, inner circle turned 90°; move vs one elasticity solve")
    print(f"  {'triangles':>10}{'move s':>9}{'elast. s':>10}{'ratio':>8}{'min AR':>9}")
    for factor in (1, 2, 4, 6.33):  # 2.7k, 10.8k, 42.6k, 107k triangles at size 0.05
        mesh = annulus(size / factor)
        if mesh.n_triangles > max_triangles:
            break
        handles, targets = rotate_inner_boundary(mesh, 90)
        # the fastest of three solves: a conservative cost unit on a busy machine
        unit, _ = best_of(lambda: elasticity_motion(mesh.points, mesh.triangles, handles,
                                                    targets), 3)
        t0 = time.perf_counter()
        res = mt.move(mesh, handles, targets)
        sec = time.perf_counter() - t0
        print(f"  {mesh.n_triangles:>10}{sec:9.1f}{unit:10.2f}{sec / unit:8.0f}"
              f"{res.min_aspect_ratio[-1]:9.4f}", flush=True)


def figure(path: str, size: float) -> None:
    """Source, harmonic, elasticity 1/A, TMOP and ours on the 90° annulus turn (inverted in red)."""
    from meshopt_toolkit.plotting import _figure, _save, draw_mesh

    mesh = annulus(size)
    handles, targets = rotate_inner_boundary(mesh, 90)
    panels = [("source", lambda *a: mesh.points)]
    panels += [(m, METHODS[m]) for m in ("harmonic", "elasticity 1/A", "TMOP (mfem)", "move (ours)")]
    fig = _figure(4 * len(panels), 4.3, 110)
    for k, (name, fn) in enumerate(panels, start=1):
        row, why = measure(fn, mesh, handles, targets)
        ax = fig.add_subplot(1, len(panels), k)
        ax.set_axis_off()
        if row is None:
            ax.set_title(f"{name}: {why[:30]}", fontsize=9)
            continue
        ar, _, inv, _, sec, Q = row
        draw_mesh(ax, Q, mesh.triangles, linewidth=0.3)
        label = f"{inv} inverted" if inv else f"min AR {ar:.3f}"
        ax.set_title(f"{name}\n{label}, {sec:.1f} s", fontsize=10)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.02, top=0.86, wspace=0.05)
    print(f"wrote {_save(fig, path, tight=False)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.05, help="gmsh element size (0.05: ~2.7k)")
    ap.add_argument("--growth", action="store_true")
    ap.add_argument("--max-triangles", type=int, default=110_000)
    ap.add_argument("--skip", nargs="*", default=[], help="method names to leave out")
    ap.add_argument("--figure", metavar="PNG", help="only draw the 90° annulus figure")
    ap.add_argument("--more", action="store_true",
                    help="seven more motions (shear, ellipse, star, hole scaled/shifted, ...)")
    args = ap.parse_args()
    if args.figure:
        figure(args.figure, args.size)
        return
    table(args.size, set(args.skip), more=args.more)
    if args.growth:
        growth(args.size, args.max_triangles)


if __name__ == "__main__":
    main()
