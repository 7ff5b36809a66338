"""Time per optimization iteration of each variant on the bundled discs (like thesis
table 6.6), side by side in one process with the runs interleaved (the machine is shared
and noisy), and the ratio complete-complete / complete-euclidean (target ≤ 3 on the
~541-vertex disc; the thesis: about 2000).

complete-complete uses the default retraction (the geodesic's line-search mode,
``optimize.EXP_DEFAULTS``); ``--exact`` adds a row with the 1e-6-accurate exponential map
(``exp_options={"method": "auto"}``) for comparison.

Usage: python benchmarks/bench_optimize.py [--iterations 10] [--repeats 3]
       [--max-vertices 14000] [--exact]
"""

from __future__ import annotations

import argparse

import numpy as np

import meshopt_toolkit as mt
from meshopt_toolkit import datasets
from meshopt_toolkit.optimize import VARIANTS, default_metric_beta, optimize, thesis_penalty_beta
from meshopt_toolkit.poisson import PoissonObjective


def run(mesh, variant, iterations, exp_options=None):
    """(wall time / iteration, result) of a run with penalty parameter set 2 and the
    default metric β, no early stop."""
    res = optimize(mesh, PoissonObjective(mesh), variant=variant,
                   penalty_beta=thesis_penalty_beta(2, mesh.n_vertices),
                   metric_beta=default_metric_beta(mesh.n_vertices),
                   max_iter=iterations, tol=None, exp_options=exp_options)
    return res.seconds / max(res.nit, 1), res


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--iterations", type=int, default=10)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--max-vertices", type=int, default=14000)
    p.add_argument("--exact", action="store_true",
                   help="also time complete-complete with the exact (1e-6) exponential map")
    args = p.parse_args(argv)
    names = sorted((n for n in datasets.available() if n.startswith("disc_")),
                   key=lambda s: int(s[5:-4]))
    print(f"{'N_V':>6} {'variant':<28} {'s/iter':>10} {'/ complete-euclidean':>22}  phases (s/iter)")
    for name in names:
        nv = int(name[5:-4])
        if nv > args.max_vertices or nv < 70:
            continue
        mesh = mt.load(mt.data_path(name)).as_planar()
        rows = {v: (v, None) for v in VARIANTS}
        if args.exact:
            rows["complete-complete (exact exp)"] = ("complete-complete", {"method": "auto"})
        times = {k: [] for k in rows}
        last = {}
        for _ in range(args.repeats):  # interleaved: every variant once per round
            for key, (variant, opts) in rows.items():
                t, res = run(mesh, variant, args.iterations, opts)
                times[key].append(t)
                last[key] = res
        base = np.array(times["complete-euclidean"])
        for key in rows:
            t = np.array(times[key])
            ph = last[key].phase_totals()
            detail = " ".join(f"{k}={v / max(last[key].nit, 1):.2e}" for k, v in ph.items() if v)
            ratio = float(np.median(t / base))  # per round: the runs next to each other
            print(f"{mesh.n_vertices:>6} {key:<28} {np.median(t):>10.2e} {ratio:>22.2f}  {detail}")
        cc = float(np.median(np.array(times["complete-complete"]) / base))
        note = "  <-- target ≤ 3" if 400 <= mesh.n_vertices <= 700 else ""
        print(f"{'':>6} complete-complete / complete-euclidean = {cc:.2f}{note}\n")


if __name__ == "__main__":
    main()
