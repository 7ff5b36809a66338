"""Benchmark: ``quality_summary`` and ``check_mesh`` on a 1,000,000-triangle mesh.

Times :func:`meshopt_toolkit.kernels.triangles.quality_summary` against the cheapest possible
pass over the same triangles, :func:`meshopt_toolkit.kernels.triangles.signed_areas`, side by side
in this process (interleaved repeats, medians), and prints the ratio (target ≤ 3×). Also
times :func:`meshopt_toolkit.mesh.check_mesh` on a fresh mesh (topology not cached), which
should take a few seconds at most.

Run::

    python benchmarks/bench_quality.py [--n 708] [--repeat 7]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import jittered_grid

from meshopt_toolkit.kernels.triangles import quality_summary, signed_areas
from meshopt_toolkit.mesh import PlanarMesh, check_mesh


def _time(f) -> float:
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=708, help="grid size (2 n² triangles)")
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args(argv)

    pts, tri = jittered_grid(args.n)
    print(f"mesh: {len(pts)} vertices, {len(tri)} triangles")
    t_area, t_quality = [], []
    for _ in range(args.repeat):  # interleaved, so both see the same machine state
        t_area.append(_time(lambda: signed_areas(pts, tri)))
        t_quality.append(_time(lambda: quality_summary(pts, tri)))
    ma, mq = np.median(t_area), np.median(t_quality)
    print(f"signed_areas     median {ma * 1e3:8.1f} ms")
    print(f"quality_summary  median {mq * 1e3:8.1f} ms")
    print(f"ratio quality_summary / signed_areas = {mq / ma:.2f}  (target <= 3)")

    # the same kernels given the triangles in column-major order (the transpose of a
    # contiguous (3, T) array, as PlanarMesh.quality() passes them): the per-vertex
    # gathers then read contiguous index rows
    cols = np.ascontiguousarray(tri.T)
    t_row, t_col = [], []
    for _ in range(args.repeat):
        t_row.append(_time(lambda: quality_summary(pts, tri)))
        t_col.append(_time(lambda: quality_summary(pts, cols.T)))
    mr, mc = np.median(t_row), np.median(t_col)
    print(f"quality_summary  (T, 3) rows {mr * 1e3:7.1f} ms, column-major {mc * 1e3:7.1f} ms"
          f"  (ratio {mr / mc:.2f})")

    # check_mesh on a fresh mesh (no cached topology); the shuffled triangle order is the
    # worst case for memory locality, a mesher's output is closer to the sorted order
    ordered = tri[np.argsort(tri.min(axis=1), kind="stable")]
    for name, t in [("shuffled", tri), ("vertex-ordered", ordered)]:
        t_check = []
        for _ in range(3):
            mesh = PlanarMesh(pts, t)
            t_check.append(_time(lambda m=mesh: check_mesh(m)))
        report = check_mesh(PlanarMesh(pts, t))
        print(
            f"check_mesh ({name:14s}) median {np.median(t_check):6.2f} s"
            f"  (admissible={report.admissible})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
