"""Cost against size: seconds per optimization iteration of each variant, the
exponential map, and peak memory, on disc_13586 and its uniform refinements
(27k, 107k, 429k, 1.7M triangles, up to ``--max-triangles``).

Each size runs in its own process (so that its peak RSS is its own); inside it the four
variants run side by side, a few steepest-descent iterations each with table 6.4's
parameter set 2 (``bench_optimize.run``: no early stop, the time per iteration), then
one ``exp_map`` of the smooth velocity of ``bench_geodesics`` part 2, one penalty pass
(value and gradient) and one Riesz map of the complete metric (its ∇f cached). Printed per
size: seconds per iteration per variant, their ratios
(complete-complete / complete-euclidean ≤ 1.5; elasticity-euclidean / complete-euclidean
≤ 2, over all iterations and, "later", over those after the first, which holds the
elasticity metric's first factorization; Riesz map / penalty pass ≤ 2), exp_map seconds
per triangle (its growth from one size to the next ≤ 1.3), the exp_map's penalty
evaluations, and the peak RSS (1.7M triangles, all variants: under 8 GB).

``--plot PNG`` draws seconds per iteration against N on log–log axes, one line per
variant, and the exponential map's seconds against N.

``--rows JSONL`` keeps the measured sizes (one JSON object per line): sizes found there
are not measured again, so the 1.7M size (13–25 minutes on 2 cores) is measured once
and the table and the plot are drawn from all sizes.

Usage: ``python benchmarks/bench_scale.py [--max-triangles 110000] [--iterations 3]
[--rows examples/results/scale_rows.jsonl] [--plot examples/results/scale.png]``
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

VARIANTS = ("euclidean-euclidean", "complete-euclidean", "elasticity-euclidean",
            "complete-complete")
REFINEMENTS = (0, 1, 2, 3)  # disc_13586: 27k, 107k, 429k, 1.7M triangles


def measure(refinements: int, iterations: int) -> dict:
    """One size, in this process: per-iteration seconds per variant, exp_map, RSS."""
    from bench_optimize import run

    import meshopt_toolkit as mt
    from meshopt_toolkit.riemannian.geodesics import geodesic
    from meshopt_toolkit.riemannian.metrics import CompleteMetric
    from meshopt_toolkit.penalties import QualityPenalty

    mesh = mt.load(mt.data_path("disc_13586.msh")).as_planar()
    for _ in range(refinements):
        mesh = mesh.refine()
    out = {"triangles": mesh.n_triangles, "vertices": mesh.n_vertices, "per_iteration": {},
           "after_first": {}}
    for variant in VARIANTS:
        seconds, res = run(mesh, variant, iterations)
        out["per_iteration"][variant] = seconds
        # the iterations after the first, which holds the one-time setup (the elasticity
        # metric's first factorization); later refactorizations stay in
        later = [sum(r.seconds.values()) for r in res.history if r.iteration >= 2]
        out["after_first"][variant] = float(np.mean(later)) if later else float("nan")
        _progress(f"{mesh.n_triangles} triangles, {variant}: {seconds:.2f} s per iteration")
    pen = QualityPenalty(mesh, beta=(10, 1, 0, 0.001 * mesh.n_vertices))
    Q = mesh.points
    V = 0.3 * np.stack([np.sin(np.pi * Q[:, 1]), np.cos(np.pi * Q[:, 0])], axis=1)
    t0 = time.perf_counter()
    pen.value_and_gradient(Q)
    out["penalty_pass"] = time.perf_counter() - t0
    metric = CompleteMetric(pen)
    metric.riesz(Q, V)  # fills the metric's cache of ∇f at Q
    t0 = time.perf_counter()
    metric.riesz(Q, V)
    out["riesz"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = geodesic(CompleteMetric(pen), Q, V, 1.0)
    out["exp_map"] = time.perf_counter() - t0
    _progress(f"{mesh.n_triangles} triangles, exp_map: {out['exp_map']:.1f} s")
    out["exp_evaluations"] = int(res.n_evaluations)
    out["peak_rss_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    return out


def _progress(line: str) -> None:
    """One line on stderr per finished part, with the peak memory so far (long sizes)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    print(f"  {line} (peak RSS {peak:.2f} GB)", file=sys.stderr, flush=True)


def _later_ratio(row: dict) -> float:
    """elasticity-euclidean / complete-euclidean over the iterations after the first."""
    later = row.get("after_first", {})
    return later.get("elasticity-euclidean", np.nan) / later.get("complete-euclidean", np.nan)


def _measure_in_subprocess(refinements: int, iterations: int) -> dict | None:
    proc = subprocess.run([sys.executable, __file__, "--one", str(refinements),
                           "--iterations", str(iterations)],
                          stdout=subprocess.PIPE, stderr=None, text=True,
                          cwd=Path(__file__).parent)
    if proc.returncode != 0:
        return None
    row = json.loads(proc.stdout.strip().splitlines()[-1])
    row["iterations"] = iterations
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-triangles", type=int, default=110_000,
                    help="largest size (1.7M: 1800000, 13-25 more minutes)")
    ap.add_argument("--iterations", type=int, default=3)
    ap.add_argument("--plot", metavar="PNG")
    ap.add_argument("--rows", metavar="JSONL",
                    help="sizes already in this file are read from it instead of measured; "
                         "every size measured is appended to it (a long size, e.g. 1.7M, "
                         "can then be measured once and the table and plot redrawn)")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # internal: one size
    args = ap.parse_args()
    if args.one is not None:
        print(json.dumps(measure(args.one, args.iterations)))
        return
    kept = {}
    if args.rows and Path(args.rows).exists():
        for line in Path(args.rows).read_text().splitlines():
            if line.strip():
                row = json.loads(line)
                kept[row["triangles"]] = row
    rows = []
    print(f"{'triangles':>10}" + "".join(f"{v:>22}" for v in VARIANTS)
          + f"{'cc/ce':>7}{'ee/ce':>7}{'later':>7}{'riesz/f':>8}{'exp s':>8}{'exp µs/T':>10}"
          f"{'growth':>8}{'evals':>7}{'RSS GB':>8}")
    for refinements, triangles in zip(REFINEMENTS, (26_794, 107_176, 428_704, 1_714_816)):
        if triangles > args.max_triangles:
            break
        row = kept.get(triangles) or _measure_in_subprocess(refinements, args.iterations)
        if row is None:
            print(f"{triangles:>10}  failed (its error is above)")
            break
        if args.rows and triangles not in kept:
            with open(args.rows, "a", encoding="utf-8") as f:
                f.write(json.dumps(row) + "\n")
        per = row["per_iteration"]
        exp_per_t = 1e6 * row["exp_map"] / row["triangles"]
        growth = f"{exp_per_t / rows[-1][1]:8.2f}" if rows else f"{'':>8}"
        rows.append((row, exp_per_t))
        print(f"{row['triangles']:>10}" + "".join(f"{per[v]:22.3f}" for v in VARIANTS)
              + f"{per['complete-complete'] / per['complete-euclidean']:7.2f}"
              f"{per['elasticity-euclidean'] / per['complete-euclidean']:7.2f}"
              f"{_later_ratio(row):7.2f}"
              f"{row['riesz'] / row['penalty_pass']:8.2f}"
              f"{row['exp_map']:8.2f}{exp_per_t:10.2f}{growth}{row['exp_evaluations']:7d}"
              f"{row['peak_rss_gb']:8.2f}", flush=True)
    if args.plot and rows:
        from meshopt_toolkit.plotting import _figure, _save

        fig = _figure(9.0, 3.8, 120)
        left, right = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
        n = np.array([r["triangles"] for r, _ in rows], float)
        for v in VARIANTS:
            left.loglog(n, [r["per_iteration"][v] for r, _ in rows], "o-", label=v)
        left.loglog(n, rows[0][0]["per_iteration"]["complete-euclidean"] * n / n[0], "k:",
                    label="∝ N")
        left.set_title("seconds per optimization iteration", fontsize=9)
        exp_s = np.array([r["exp_map"] for r, _ in rows])
        right.loglog(n, exp_s, "o-", color="tab:purple", label="exp_map (complete metric)")
        right.loglog(n, exp_s[0] * n / n[0], "k:", label="∝ N")
        right.set_title("exponential map, t = 1 (seconds)", fontsize=9)
        for ax in (left, right):
            ax.set_xlabel("triangles")
            ax.legend(fontsize=7)
        _save(fig, args.plot)
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
