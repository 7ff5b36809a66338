"""Benchmark: the f2 penalty (QualityPenalty) on a structured, jittered mesh.

All timings are measured side by side in one process, round-robin (best of ``--repeat``
rounds), and printed as ratios against a baseline:

- f2 value + gradient vs computing the signed areas once (target ≤ 10×),
- f2 hvp vs f2 value + gradient (target ≤ 2×),
- f2 gradient_and_curvature vs gradient + hvp (the geodesic ODE's hot path),

first with β3 = 0 (no boundary-pair term), then with a cut-off boundary-pair term
(radius search), and once with the all-pairs boundary term (#V∂·#E∂ pairs in chunks).

Run: ``python benchmarks/bench_penalties.py [--n 707] [--repeat 5] [--skip-all-pairs]``
(``--n 707`` gives 2·707² ≈ 1,000,000 triangles).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import jittered_grid

from meshopt_toolkit.kernels.triangles import signed_areas
from meshopt_toolkit.mesh import PlanarMesh
from meshopt_toolkit.penalties import QualityPenalty


def round_robin(funs: dict, repeat: int) -> dict:
    """Best time of each function over ``repeat`` interleaved rounds (after a warm-up)."""
    for f in funs.values():
        f()
    best = {k: np.inf for k in funs}
    for _ in range(repeat):
        for k, f in funs.items():
            t0 = time.perf_counter()
            f()
            best[k] = min(best[k], time.perf_counter() - t0)
    return best


def report(title: str, t: dict) -> None:
    print(f"\n{title}")
    for k, v in t.items():
        print(f"  {k:28s} {1e3 * v:9.1f} ms")
    vg = t["value_and_gradient"]
    print(f"  value+gradient / signed areas        = {vg / t['signed_areas']:6.2f}  (target <= 10)")
    print(f"  hvp / value+gradient                 = {t['hvp'] / vg:6.2f}  (target <= 2)")
    print(
        "  gradient_and_curvature / (gradient + hvp) = "
        f"{t['gradient_and_curvature'] / (t['gradient'] + t['hvp']):6.2f}"
    )


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=707, help="squares per side (2n² triangles)")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--skip-all-pairs", action="store_true")
    args = parser.parse_args(argv)

    t0 = time.perf_counter()
    mesh = PlanarMesh(*jittered_grid(args.n, jitter=0.2, shuffle=False))
    _ = mesh.boundary_edges  # topology is cached in the mesh; not part of the timings
    print(
        f"mesh: {mesh.n_vertices} vertices, {mesh.n_triangles} triangles, "
        f"{len(mesh.boundary_edges)} boundary edges (setup {time.perf_counter() - t0:.1f} s)"
    )
    Q = np.array(mesh.points)
    rng = np.random.default_rng(1)
    V = rng.standard_normal(Q.shape)
    h = 1.0 / args.n
    mu = 1.0 / h  # smoothing zone 1/(2μ) = h/2

    def suite(P):
        return {
            "signed_areas": lambda: signed_areas(Q, mesh.triangles),
            "value": lambda: P.value(Q),
            "value_and_gradient": lambda: P.value_and_gradient(Q),
            "gradient": lambda: P.gradient(Q),
            "hvp": lambda: P.hvp(Q, V),
            "gradient_and_curvature": lambda: P.gradient_and_curvature(Q, V),
        }

    P0 = QualityPenalty(mesh, beta=(1.0, 0.5, 0.0, 1.0), mu=mu)
    report("f2 with beta3 = 0", round_robin(suite(P0), args.repeat))

    # cut-off boundary term: pairs with 1/D^μ > s_lo, i.e. within about 3 mesh widths
    cut = (1.0 / (3 * h), 1.0 / h)
    Pc = QualityPenalty(mesh, beta=(1.0, 0.5, 1.0, 1.0), mu=mu, cutoff=cut)
    report(
        f"f2 with a cut-off boundary term, cutoff = ({cut[0]:.0f}, {cut[1]:.0f})",
        round_robin(suite(Pc), args.repeat),
    )

    if not args.skip_all_pairs:
        Pa = QualityPenalty(mesh, beta=(1.0, 0.5, 1.0, 1.0), mu=mu)
        nb = len(mesh.boundary_vertices) * len(mesh.boundary_edges)
        t = round_robin(
            {
                "signed_areas": lambda: signed_areas(Q, mesh.triangles),
                "value": lambda: Pa.value(Q),
                "value_and_gradient": lambda: Pa.value_and_gradient(Q),
            },
            1,
        )
        print(f"\nf2 with the all-pairs boundary term (~{nb / 1e6:.1f}M pairs, one run)")
        for k, v in t.items():
            print(f"  {k:28s} {1e3 * v:9.1f} ms")
        ratio = t["value_and_gradient"] / t["signed_areas"]
        print(f"  value+gradient / signed areas        = {ratio:6.1f}")


if __name__ == "__main__":
    main()
