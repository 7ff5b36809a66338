"""Benchmark: the default exponential map against the thesis' Störmer–Verlet (1024 steps).

Part 1 (one process, side by side): on the bundled 85-vertex unit disc with f2,
β = (10, 1, 0, 0.001·N) (β4 unscaled), velocity V = 0.3·standard normal (seeded), compute
exp_Q(V) = γ(1) with

- a tight independent reference: scipy's DOP853 at rtol = atol = 1e-12,
- the default ``exp_map`` (own stepping with the DOP853 pair, rtol = 1e-6) and our
  Dormand–Prince 5(4) (rtol = 1e-7),
- the thesis' Störmer–Verlet with 1024 steps (fixed point tol 1e-8, ≤ 10 iterations); on
  this stiff case its fixed point stops converging near t ≈ 0.9, so the step count is
  doubled until it succeeds (the time of the 1024-step attempt is still reported: a lower
  bound of its cost),
- scipy's DOP853 at the default's tolerance (to show the cost of solve_ivp's overhead),

and print times, penalty calls and errors ``max|γ(1) − γ_ref(1)| / max|V|``, and the
speed-up ratios.

Part 2: cost against mesh size from ~1e3 to ~1e6 triangles (uniform refinements of the
bundled discs), with a smooth velocity ``0.3·(sin πy, cos πx)`` so that the step count
reflects the geometry rather than per-vertex noise: time per penalty evaluation (value,
gradient_and_curvature) and per ``exp_map`` (t = 1, default tolerance).

Part 3: the line-search retraction (``method="line-search"``, the default of
complete-complete optimization) against the default ``exp_map`` on the first step of a
thesis §6.4 optimization (disc_146/541/2198): time, penalty calls, and the distance from a
tight solution at t = 1 and over the 23 backtracking times.

Run: ``python benchmarks/bench_geodesics.py [--max-triangles 2000000] [--quick] [--part N]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import best_of

from meshopt_toolkit import data_path, load
from meshopt_toolkit.errors import IntegrationError
from meshopt_toolkit.riemannian.geodesics import exp_map, geodesic
from meshopt_toolkit.riemannian.metrics import CompleteMetric
from meshopt_toolkit.penalties import QualityPenalty


def part1(repeat: int) -> None:
    mesh = load(data_path("disc_85.msh")).as_planar()
    N = mesh.n_vertices
    pen = QualityPenalty(mesh, beta=(10, 1, 0, 0.001 * N))
    metric = CompleteMetric(pen)
    Q = mesh.points
    V = 0.3 * np.random.default_rng(0).standard_normal((N, 2))
    vmax = np.abs(V).max()
    print(f"# part 1: disc_85 (N = {N}, T = {mesh.n_triangles}), f2 beta = (10, 1, 0, {0.001 * N:g}),"
          " V = 0.3 N(0, 1), t = 1")
    t_ref, ref = best_of(lambda: geodesic(metric, Q, V, 1.0, method="scipy", rtol=1e-12, atol=1e-12), 1)
    print(f"reference  scipy DOP853 rtol=atol=1e-12   {t_ref:8.3f} s  {ref.n_evaluations:6d} calls")

    rows = {}
    t_fast, fast = best_of(lambda: geodesic(metric, Q, V, 1.0), repeat)
    rows["default exp_map (dop853, rtol 1e-6)"] = (t_fast, fast)
    t_dp5, dp5 = best_of(lambda: geodesic(metric, Q, V, 1.0, method="dopri5"), repeat)
    rows["dopri5 (rtol 1e-7)"] = (t_dp5, dp5)
    t_sp, sp = best_of(lambda: geodesic(metric, Q, V, 1.0, method="scipy", rtol=1e-7,
                                        atol=1e-7 * max(np.abs(Q).max(), vmax)), repeat)
    rows["scipy DOP853 (rtol 1e-7)"] = (t_sp, sp)
    t_sv1024 = None
    sv = None
    for steps in (1024, 2048, 4096, 8192, 16384):
        t0 = time.perf_counter()
        try:
            sv = geodesic(metric, Q, V, 1.0, method="stormer-verlet", steps=steps)
        except IntegrationError as exc:
            dt = time.perf_counter() - t0
            print(f"Stormer-Verlet {steps:5d} steps FAILED after {dt:7.2f} s: {exc}")
            t_sv1024 = dt if t_sv1024 is None else t_sv1024
            continue
        t_sv = time.perf_counter() - t0
        t_sv1024 = t_sv if t_sv1024 is None else t_sv1024
        rows[f"Stormer-Verlet {steps} steps"] = (t_sv, sv)
        break
    check = exp_map(metric, Q, V)
    assert np.array_equal(check, fast.final)
    for label, (t, r) in rows.items():
        err = np.abs(r.final - ref.final).max() / vmax
        print(f"{label:40s} {t:8.3f} s  {r.n_evaluations:6d} calls  error/max|V| = {err:.2e}  "
              f"energy drift {r.max_energy_drift:.1e}")
    print(f"ratio  Stormer-Verlet 1024 steps (time spent, even if it failed) / default = "
          f"{t_sv1024 / t_fast:7.1f}x  (target >= 30x)")
    if sv is not None:
        print(f"ratio  first converging Stormer-Verlet / default = {t_sv / t_fast:7.1f}x")
    print(f"ratio  scipy DOP853 / default exp_map     = {t_sp / t_fast:7.2f}x")
    err = np.abs(fast.final - ref.final).max() / vmax
    print(f"default error {err:.2e} (target <= 1e-6): {'OK' if err <= 1e-6 else 'MISSED'}")


def part2(max_triangles: int, quick: bool) -> None:
    print("\n# part 2: cost against size (f2 beta = (10, 1, 0, 0.001 N), V = 0.3 (sin pi y, cos pi x))")
    print(f"{'T':>9s} {'N':>9s} {'value [ms]':>11s} {'grad+curv [ms]':>15s} "
          f"{'exp_map [s]':>12s} {'calls':>6s} {'exp/eval':>9s}")
    bases = [("disc_541.msh", 0), ("disc_2198.msh", 0), ("disc_2198.msh", 1),
             ("disc_13586.msh", 0), ("disc_13586.msh", 1), ("disc_13586.msh", 2),
             ("disc_13586.msh", 3)]
    for name, nref in bases:
        mesh = load(data_path(name)).as_planar()
        for _ in range(nref):
            mesh = mesh.refine()
        T = mesh.n_triangles
        if T > max_triangles:
            break
        N = mesh.n_vertices
        pen = QualityPenalty(mesh, beta=(10, 1, 0, 0.001 * N))
        Q = mesh.points
        V = 0.3 * np.stack([np.sin(np.pi * Q[:, 1]), np.cos(np.pi * Q[:, 0])], axis=1)
        reps = 3 if T < 2e5 else 1
        t_val, _ = best_of(lambda pen=pen, Q=Q: pen.value(Q), reps)
        t_gc, _ = best_of(lambda pen=pen, Q=Q, V=V: pen.gradient_and_curvature(Q, V), reps)
        if quick and T > 3e5:
            print(f"{T:9d} {N:9d} {1e3 * t_val:11.2f} {1e3 * t_gc:15.2f} {'(skipped)':>12s}")
            continue
        t_exp, res = best_of(lambda pen=pen, Q=Q, V=V: geodesic(CompleteMetric(pen), Q, V, 1.0), 1)
        print(f"{T:9d} {N:9d} {1e3 * t_val:11.2f} {1e3 * t_gc:15.2f} {t_exp:12.2f} "
              f"{res.n_evaluations:6d} {t_exp / t_gc:9.0f}")


def part3(repeat: int) -> None:
    """The line-search retraction of complete-complete optimization against the default
    exponential map, on the first step of an optimization (thesis §6.4 set-up)."""
    from meshopt_toolkit.optimize import default_metric_beta, thesis_penalty_beta
    from meshopt_toolkit.fem.poisson import PoissonObjective

    print("\n# part 3: line-search retraction vs exp_map on an optimization step "
          "(V = s d, s = 1/|d|_g, 23 backtracking times 2^-k)")
    print(f"{'mesh':>14s} {'method':>12s} {'time [ms]':>10s} {'calls':>6s} "
          f"{'err(1)/max|V|':>14s} {'max err/max|V|':>15s} {'speed-up':>9s}")
    for name in ("disc_146.msh", "disc_541.msh", "disc_2198.msh"):
        mesh = load(data_path(name)).as_planar()
        N = mesh.n_vertices
        metric = CompleteMetric(QualityPenalty(mesh, beta=default_metric_beta(N)))
        penalty = QualityPenalty(mesh, beta=thesis_penalty_beta(2, N))
        Q = mesh.points
        d = -metric.riesz(Q, PoissonObjective(mesh).derivative(Q) + penalty.gradient(Q))
        V = d / metric.norm(Q, d)
        times = 0.5 ** np.arange(23)[::-1]
        ref = geodesic(metric, Q, V, 1.0, times=times, rtol=1e-10, on_violation="ignore")
        vmax = np.abs(V).max()
        base = None
        for method in ("auto", "line-search"):
            t, r = best_of(lambda m=method, g=metric, Q=Q, V=V, ts=times: geodesic(
                g, Q, V, 1.0, times=ts, method=m, on_violation="ignore"), repeat)
            base = base or t
            err = np.abs(r.points - ref.points).max(axis=(1, 2)) / vmax
            print(f"{name:>14s} {method:>12s} {1e3 * t:10.1f} {r.n_evaluations:6d} "
                  f"{err[-1]:14.1e} {err.max():15.1e} {base / t:9.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-triangles", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="skip exp_map above 3e5 triangles")
    ap.add_argument("--part", type=int, choices=(1, 2, 3))
    args = ap.parse_args()
    if args.part in (None, 1):
        part1(args.repeat)
    if args.part in (None, 2):
        part2(args.max_triangles, args.quick)
    if args.part in (None, 3):
        part3(args.repeat)


if __name__ == "__main__":
    main()
