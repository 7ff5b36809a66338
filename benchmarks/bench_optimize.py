"""Time per optimization iteration of each variant on the bundled discs (like thesis
table 6.6), side by side in one process, and the ratio complete-complete /
complete-euclidean (target ≤ 3 on the ~541-vertex disc; the thesis: about 2000).

Usage: python benchmarks/bench_optimize.py [--iterations 10] [--max-vertices 14000]
"""

from __future__ import annotations

import argparse

import numpy as np

import meshopt_toolkit as mt
from meshopt_toolkit.optimize import VARIANTS, default_metric_beta, optimize, thesis_penalty_beta
from meshopt_toolkit.poisson import PoissonObjective


def per_iteration(mesh, variant, iterations, repeats=3):
    """Median over repeats of (wall time / iteration) of an unpenalized-metric run with
    parameter set 2 (no early stop)."""
    times = []
    for _ in range(repeats):
        res = optimize(mesh, PoissonObjective(mesh), variant=variant,
                       penalty_beta=thesis_penalty_beta(2, mesh.n_vertices),
                       metric_beta=default_metric_beta(mesh.n_vertices),
                       max_iter=iterations, tol=None)
        times.append(res.seconds / max(res.nit, 1))
    return float(np.median(times)), res


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--iterations", type=int, default=10)
    p.add_argument("--max-vertices", type=int, default=14000)
    args = p.parse_args(argv)
    names = sorted((n for n in mt.datasets.available() if n.startswith("disc_")),
                   key=lambda s: int(s[5:-4]))
    print(f"{'N_V':>6} {'variant':<22} {'s/iter':>10} {'/ complete-euclidean':>22}  phases (s/iter)")
    for name in names:
        nv = int(name[5:-4])
        if nv > args.max_vertices or nv < 70:
            continue
        mesh = mt.load(mt.data_path(name)).as_planar()
        base = None
        rows = {}
        for variant in ["complete-euclidean"] + [v for v in VARIANTS if v != "complete-euclidean"]:
            t, res = per_iteration(mesh, variant, args.iterations)
            rows[variant] = (t, res)
            base = base or t
        for variant in VARIANTS:
            t, res = rows[variant]
            ph = res.phase_totals()
            detail = " ".join(f"{k}={v / max(res.nit, 1):.2e}" for k, v in ph.items() if v)
            print(f"{mesh.n_vertices:>6} {variant:<22} {t:>10.2e} {t / base:>22.2f}  {detail}")
        cc = rows["complete-complete"][0] / base
        note = "  <-- target ≤ 3" if 400 <= mesh.n_vertices <= 700 else ""
        print(f"{'':>6} complete-complete / complete-euclidean = {cc:.2f}{note}\n")


if __name__ == "__main__":
    main()
