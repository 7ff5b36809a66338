"""Benchmark: regularized vertex–edge distance with derivatives vs a plain Euclidean
point–segment distance on the same pairs (baseline measured side by side).

Run: ``python benchmarks/bench_distance.py [--pairs 4000000] [--repeat 3]``.
Prints the time of each variant and its ratio to the baseline.
"""

from __future__ import annotations

import argparse

import numpy as np
from _common import best_of

from meshopt_toolkit.kernels.distance import (
    boundary_pairs,
    regularized_distance,
    regularized_distance_value,
    vertex_edge_distance,
)


def euclidean_point_segment(points: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Baseline: plain vectorized Euclidean distance from q_i0 to segment [q_j0, q_j1]."""
    p, a, b = points[pairs[:, 0]], points[pairs[:, 1]], points[pairs[:, 2]]
    e = b - a
    w = p - a
    s = np.clip(np.einsum("ij,ij->i", w, e) / np.einsum("ij,ij->i", e, e), 0.0, 1.0)
    return np.linalg.norm(w - s[:, None] * e, axis=1)


def circle_boundary(n: int, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    theta = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = 1 + 0.05 * rng.standard_normal(n)
    pts = np.stack([r * np.cos(theta), r * np.sin(theta)], 1)
    bv = np.arange(n)
    be = np.stack([bv, np.roll(bv, -1)], 1)
    return pts, bv, be


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=4_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)

    rng = np.random.default_rng(0)
    n_nodes = 2000
    pts = rng.uniform(-1, 1, (n_nodes, 2))
    pairs = np.column_stack([rng.choice(n_nodes, args.pairs), rng.choice(n_nodes, (args.pairs, 2))])
    pairs = pairs[
        (pairs[:, 0] != pairs[:, 1]) & (pairs[:, 0] != pairs[:, 2]) & (pairs[:, 1] != pairs[:, 2])
    ]
    V = rng.standard_normal(pts.shape)
    mu = 4.0

    variants = {
        "euclidean point-segment (baseline)": lambda: euclidean_point_segment(pts, pairs),
        "vertex_edge_distance (exact D)": lambda: vertex_edge_distance(pts, pairs),
        "regularized_distance_value": lambda: regularized_distance_value(pts, pairs, mu),
        "regularized_distance (value+grad)": lambda: regularized_distance(pts, pairs, mu),
        "regularized_distance (+direction)": lambda: regularized_distance(
            pts, pairs, mu, direction=V
        ),
    }
    # interleave the variants in every round so that load changes hit all of them alike
    times = {name: float("inf") for name in variants}
    for _ in range(args.repeat):
        for name, fun in variants.items():
            times[name] = min(times[name], best_of(fun, 1)[0])
    base = times["euclidean point-segment (baseline)"]
    rows = list(times.items())
    print(f"{len(pairs)} pairs, best of {args.repeat}")
    for name, t in rows:
        print(f"  {name:38s} {t:8.3f} s   ratio {t / base:6.2f}")

    # pair search: all pairs vs radius search on a boundary of 4000 vertices
    bpts, bv, be = circle_boundary(4000, rng)
    t_all = best_of(lambda: boundary_pairs(bv, be), args.repeat)[0]
    t_rad = best_of(lambda: boundary_pairs(bv, be, bpts, 0.02), args.repeat)[0]
    n_all = len(boundary_pairs(bv, be))
    n_rad = len(boundary_pairs(bv, be, bpts, 0.02))
    print(
        f"boundary_pairs, 4000 boundary vertices: all {n_all} pairs {t_all:.3f} s; "
        f"radius 0.02 -> {n_rad} pairs {t_rad:.4f} s   ratio {t_rad / t_all:.4f}"
    )


if __name__ == "__main__":
    main()
