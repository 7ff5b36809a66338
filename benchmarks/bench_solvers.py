"""Benchmark: the direct SPD factorizations of the solver layer, side by side.

The elasticity metric's matrix ``K + δM`` (2 unknowns per vertex) on disc_13586 and its
uniform refinements, in the nested-dissection order all our factorizations use (its
time printed once): per size, factorization and one solve by

- SuperLU, float32 factor refined by CG to the relative residual 1e-10
  (``solvers.refined_spd_solve``: what the elasticity metric used before CHOLMOD),
- SuperLU, double precision (``solvers._superlu_spd``: the fallback without CHOLMOD),
- CHOLMOD's supernodal Cholesky, double precision (``solvers.cholesky_spd``: the default),

with relative residuals and the ratio of SuperLU float32's time to CHOLMOD's. Each is the
best of ``--repeat`` runs (load only ever adds time). The 1.7M size takes about two
minutes and 4 GB.

Usage: ``python benchmarks/bench_solvers.py [--max-triangles 1800000] [--repeat 2]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import meshopt_toolkit as mt
from meshopt_toolkit.fem.elasticity import assemble
from meshopt_toolkit.solvers import (_superlu_spd, cholesky_spd, nested_dissection,
                                     refined_spd_solve)


def best(run, repeat: int) -> tuple[float, float, np.ndarray]:
    """(factorization s, solve s, solution) of the fastest of ``repeat`` runs."""
    rows = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        solve = run()
        t1 = time.perf_counter()
        x = solve()
        rows.append((t1 - t0, time.perf_counter() - t1, x))
    return min(rows, key=lambda r: r[0] + r[1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-triangles", type=int, default=500_000)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    mesh = mt.load(mt.data_path("disc_13586.msh")).as_planar()
    print(f"{'triangles':>10}{'dofs':>10}{'order s':>9}"
          f"{'SuperLU f32+CG':>17}{'SuperLU f64':>15}{'CHOLMOD':>15}{'ratio':>7}  residuals")
    while mesh.n_triangles <= args.max_triangles:
        A = assemble(mesh.points, mesh.triangles).tocsr()
        b = np.random.default_rng(0).standard_normal(A.shape[0])
        t0 = time.perf_counter()
        order = nested_dissection(mesh.points, A, block=2)
        t_order = time.perf_counter() - t0
        runs = {
            "f32": lambda: (lambda s: lambda: s(b))(refined_spd_solve(A, order, 1e-10)[0]),
            "f64": lambda: (lambda s: lambda: s(b))(_superlu_spd(A, order, False)),
            "cholmod": lambda: (lambda s: lambda: s(b))(cholesky_spd(A, order)),
        }
        out = {k: best(run, args.repeat) for k, run in runs.items()}
        cells = "".join(f"{f'{f:.2f} + {s:.2f}':>15}" for f, s, _ in out.values())
        residuals = " ".join(f"{np.linalg.norm(A @ x - b) / np.linalg.norm(b):.0e}"
                             for _, _, x in out.values())
        ratio = sum(out["f32"][:2]) / sum(out["cholmod"][:2])
        print(f"{mesh.n_triangles:>10}{A.shape[0]:>10}{t_order:9.2f}  {cells}{ratio:7.1f}  "
              f"{residuals}", flush=True)
        mesh = mesh.refine()


if __name__ == "__main__":
    main()
