"""Helpers shared by the benchmark scripts: large test meshes and best-of timing (run them from anywhere:
``python benchmarks/bench_x.py`` puts this folder on ``sys.path``)."""

from __future__ import annotations

import time

import numpy as np


def jittered_grid(n: int, jitter: float = 0.15, seed: int = 0, *, shuffle: bool = True):
    """n×n squares of [0, 1]², two CCW triangles each (2n² triangles), interior nodes
    jittered by up to ``jitter``/n; with ``shuffle`` the triangle order is permuted so that
    memory access is not artificially sequential.

    Returns
    -------
    points : (N, 2) float array
    triangles : (2n², 3) int array
    """
    x = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(x, x, indexing="xy")
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    inner = (pts > 0).all(1) & (pts < 1).all(1)
    pts[inner] += jitter / n * np.random.default_rng(seed).uniform(-1, 1, (inner.sum(), 2))
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tri = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    if shuffle:
        tri = tri[np.random.default_rng(seed + 1).permutation(len(tri))]
    return pts, tri


def best_of(fn, repeat: int):
    """``(best wall time, last result)`` of ``repeat`` calls of ``fn`` (load only ever adds
    time on a shared machine, so the minimum is the estimate)."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out
