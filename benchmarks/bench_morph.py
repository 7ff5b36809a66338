"""Benchmark of the geodesic morph (issue #7).

1. The 225° twist of the 146-vertex disc (interior rotated by θ(r) = 225°·(1 − r)², boundary
   fixed): time of ``geodesic_morph`` (discrete geodesic, 9 frames / 16 segments) against
   the time of ONE ``exp_map`` of the same metric along the morph's own initial velocity,
   measured side by side in this process: the issue asks for at most 100 exp_map calls.
2. Growth with mesh size: the same twist on the bundled discs and uniform refinements up to
   ``--max-triangles`` triangles; time, Newton iterations and why they stopped, penalty
   calls, the time of one ``value_and_gradient`` (ms/call, the unit of work), the morph's
   time per penalty call in those units (s/call), and the smallest aspect ratio of the
   geodesic's nodes. The 100k-triangle row takes tens of minutes: cap it with
   ``--max-iter`` and run it alone with ``--skip-twist --min-triangles 100000``.

Usage: ``python benchmarks/bench_morph.py [--max-triangles 110000] [--repeat 3]
[--max-iter 500] [--min-triangles 0] [--skip-twist]``
"""

from __future__ import annotations

import argparse

from _common import best_of

from meshopt_toolkit.datasets import data_path
from meshopt_toolkit.geodesics import exp_map
from meshopt_toolkit.io import load
from meshopt_toolkit.morph import DEFAULT_BETA, geodesic_morph, morph_metric, twisted
from meshopt_toolkit.penalties import QualityPenalty


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-triangles", type=int, default=110_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--max-iter", type=int, default=500, help="Newton cap of the growth runs")
    ap.add_argument("--min-triangles", type=int, default=0, help="skip smaller growth runs")
    ap.add_argument("--skip-twist", action="store_true", help="only the growth table")
    args = ap.parse_args()
    if not args.skip_twist:
        twist_against_exp_map(args.repeat)
    growth(args.min_triangles, args.max_triangles, args.max_iter)


def twist_against_exp_map(repeat: int) -> None:
    disc = load(data_path("disc_146.msh")).as_planar()
    target = twisted(disc)
    t_morph, res = best_of(lambda: geodesic_morph(disc, target, frames=9), repeat)
    metric = morph_metric(disc)  # the morph's own metric (√N·f2)
    V = res.discrete.initial_velocity()
    t_exp, _ = best_of(lambda: exp_map(metric, disc.points, V, on_violation="ignore"), repeat)
    print("225° twist, disc_146 (146 vertices, 254 triangles), 9 frames / 16 segments")
    print(f"  geodesic_morph   {t_morph:8.3f} s  (Newton its {res.discrete.nit}, "
          f"{res.discrete.status}, penalty calls "
          f"{res.discrete.n_evaluations}, admissible {bool(res.admissible.all())}, "
          f"linear min area {res.linear_min_area_dense:.2e})")
    print(f"  one exp_map      {t_exp:8.3f} s  (default rtol, same metric, V = morph's γ'(0))")
    print(f"  ratio            {t_morph / t_exp:8.1f} exp_map calls  (issue #7 asks <= 100)")


def growth(min_triangles: int, max_triangles: int, max_iter: int) -> None:
    from meshopt_toolkit.geometry import aspect_ratios
    from meshopt_toolkit.mesh import check_mesh

    print(f"\ngrowth with mesh size (same twist, 5 frames / 16 segments, best of 1, "
          f"at most {max_iter} Newton iterations)")
    print(f"{'triangles':>10} {'vertices':>9} {'seconds':>9} {'its':>5} {'status':>10} "
          f"{'calls':>7} {'ms/call':>8} {'s/call':>7} {'admissible':>10} {'min AR':>8} "
          f"{'lin. inverts':>12}", flush=True)
    meshes = [load(data_path(n)).as_planar() for n in
              ("disc_146.msh", "disc_541.msh", "disc_2198.msh", "disc_13586.msh")]
    while meshes[-1].n_triangles * 4 <= max_triangles:
        meshes.append(meshes[-1].refine())
    for mesh in meshes:
        if mesh.n_triangles > max_triangles:
            break
        if mesh.n_triangles < min_triangles:
            continue
        tgt = twisted(mesh).points
        if not check_mesh(mesh.with_points(tgt)).admissible:
            print(f"{mesh.n_triangles:>10} {mesh.n_vertices:>9}   twisted target not admissible")
            continue
        t, r = best_of(lambda m=mesh, g=tgt: geodesic_morph(m, m.with_points(g), frames=5,
                                                            max_iter=max_iter), 1)
        pen = QualityPenalty(mesh, beta=DEFAULT_BETA)
        t_call, _ = best_of(lambda p=pen, m=mesh: p.value_and_gradient(m.points), 3)
        d = r.discrete
        min_ar = min(aspect_ratios(p, mesh.triangles).min() for p in d.points)
        print(f"{mesh.n_triangles:>10} {mesh.n_vertices:>9} {t:>9.2f} {d.nit:>5} {d.status:>10} "
              f"{d.n_evaluations:>7} {1e3 * t_call:>8.2f} {t / d.n_evaluations / t_call:>7.2f} "
              f"{bool(r.admissible.all())!s:>10} {min_ar:>8.1e} "
              f"{r.linear_min_area_dense < 0!s:>12}", flush=True)


if __name__ == "__main__":
    main()
