"""Benchmark: a batch of small shape-optimization jobs with 1, 2 and 4 worker processes.

120 inputs (the 146-vertex disc, interior nodes jittered differently in each file), one
``apply_coord_shape_optimization`` step each (complete-euclidean, 30 iterations: about 0.08 s
a file), run with :func:`meshopt_toolkit.run_batch` exactly as ``meshopt run -j N`` runs
them: ``jobs=1`` in this process, ``jobs=N`` in N worker processes (their start-up
included). Every output is checked to be byte-identical to the ``jobs=1`` run.

Prints the best wall time of ``--repeat`` interleaved runs (load from other processes only
ever adds time), files per second and speedup over ``jobs=1`` for each worker count
(target: ``-j 2`` ≥ 1.6× faster than ``-j 1`` on 2 cores), and the CPU seconds each run
used (this process and its workers): with N free cores the wall time of ``-j N`` is about
the ``-j 1`` time / N plus the workers' start-up, which the CPU column shows. A last line
says how much parallelism the machine offered at that moment (a pure-Python loop in two
processes against one): on a shared machine, read the speedups against it.
Run: ``python benchmarks/bench_batch.py [--files 120] [--iterations 30] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

import meshopt_toolkit as mt
from meshopt_toolkit.datasets import data_path
from meshopt_toolkit.batch.workers import cpu_count



def _cpu_seconds() -> float:
    """User + system time of this process and its finished children (the workers)."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def _spin(n: int) -> float:
    t0 = time.perf_counter()
    x = 0
    for i in range(n):
        x += i * i
    return time.perf_counter() - t0


def parallelism_now(n: int = 5_000_000) -> float:
    """How much faster two CPU-bound processes finish twice the work than one does it once,
    right now (2.0 on two free cores; less when other programs share them)."""
    import multiprocessing

    one = _spin(n)
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        pool.map(_spin, [n // 10] * 2)  # started
        t0 = time.perf_counter()
        pool.map(_spin, [n, n])
        two = time.perf_counter() - t0
    return 2 * one / two


def make_inputs(folder: Path, n: int) -> list[Path]:
    """``n`` copies of the 146-vertex disc, interior nodes jittered by up to 10 % of h."""
    base = mt.load(data_path("disc_146.msh"))
    inner = np.ones(base.n_vertices, bool)
    inner[base.boundary_vertices] = False
    h = float(np.sqrt(2.0 * np.pi / base.n_triangles))
    paths = []
    for i in range(n):
        rng = np.random.default_rng(i)
        pts = base.points.copy()
        pts[inner] += 0.1 * h * rng.uniform(-1, 1, (int(inner.sum()), 2))
        path = folder / f"job{i:04d}.msh"
        mt.save(base.with_points(pts), path)
        paths.append(path)
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--files", type=int, default=120)
    ap.add_argument("--iterations", type=int, default=30)
    ap.add_argument("--workers", default="1,2,4", help="comma-separated worker counts")
    ap.add_argument("--repeat", type=int, default=3,
                    help="best of this many interleaved runs of each count")
    args = ap.parse_args()
    pipeline = {"filters": [{"name": "apply_coord_shape_optimization",
                             "params": {"variant": "complete-euclidean", "rhs": "1",
                                        "penalty": "0.1,0.01,0,0.5",
                                        "max_iterations": args.iterations, "tolerance": 0}}]}
    counts = [int(w) for w in args.workers.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "in").mkdir()
        inputs = make_inputs(tmp / "in", args.files)
        print(f"{args.files} shape-optimization jobs (disc_146, {args.iterations} iterations), "
              f"{cpu_count()} cores available")
        best = {w: float("inf") for w in counts}
        cpu = {w: float("inf") for w in counts}
        for _ in range(args.repeat):  # interleaved: load from others hits all counts alike
            for w in counts:
                outdir = tmp / f"out{w}"
                t0, c0 = time.perf_counter(), _cpu_seconds()
                res = mt.run_batch(pipeline, inputs, outdir, jobs=w, options={"force": True},
                                   on_record=lambda rec: None)
                best[w] = min(best[w], time.perf_counter() - t0)
                cpu[w] = min(cpu[w], _cpu_seconds() - c0)
                assert res.failed == 0, res.report()
        reference = tmp / f"out{counts[0]}"
        for w in counts[1:]:
            for p in inputs:
                same = (tmp / f"out{w}" / p.name).read_bytes() == (reference / p.name).read_bytes()
                assert same, f"{p.name}: -j {w} differs from -j {counts[0]}"
        print(f"{'workers':>7} {'seconds':>8} {'files/s':>8} {'speedup':>8} {'CPU s':>7}")
        for w in counts:
            print(f"{w:>7} {best[w]:8.2f} {args.files / best[w]:8.1f} "
                  f"{best[counts[0]] / best[w]:7.2f}x {cpu[w]:7.2f}")
        if 2 in counts and counts[0] == 1:
            print("target: -j 2 >= 1.6x faster than -j 1 on 2 cores")
        print(f"parallelism available now: {parallelism_now():.2f}x (two CPU-bound processes "
              "against one; 2.00 on two free cores)")


if __name__ == "__main__":
    main()
