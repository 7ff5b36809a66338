"""How the cost of surface handle deformation grows with the number of triangles: ours
(``move_surface``) side by side with libigl ARAP in 10 increments on the same meshes.

Meshes: the bar twisted 180° of ``bench_surface.py`` (6×1×1 box surface, one cap turned
about the long axis, the other fixed) at grid spacings 0.1, 0.05, 0.025 and 0.0125 (5.2k
to 333k triangles), and the armadillo with its hand raised 90°, as read (86k) and
subdivided once (346k: every triangle cut into four; the handles chosen by the same
coordinate rules); with ``--families fold``, a motion in contact: ``--contact2``'s strip
folded in two (its turned half pressed down to 0.1 over its fixed half) at grid spacings 0.1,
0.05, 1/28, 0.025 and 0.0125 (800 to 51k triangles).

Each (mesh, method) runs in its own process pinned to its own core with one BLAS thread,
``--jobs`` at once (default: as many as there are cores, at most the number of runs), so a
many-core machine runs the whole table in the time of its largest run. Printed: triangles,
seconds of each method (wall clock and the process's CPU time, which a machine shared with
other work inflates less), their ratios, the worst relative quality of each, and the
growth exponent of each method's CPU time between consecutive sizes (∝ triangles^k).

Run ``python benchmarks/bench_surface_scale.py [--min-triangles 0] [--max-triangles 100000]
[--jobs 4] [--families bar,armadillo,fold]``.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import multiprocessing as mp  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_surface as bench  # noqa: E402

BAR_SPACINGS = (0.1, 0.05, 0.025, 0.0125)
FOLD_SPACINGS = (0.1, 0.05, 1 / 28, 0.025, 0.0125)
METHODS = ("ours", "ARAP 10 steps")


def bar_case(spacing: float) -> bench.Case:
    """bench_surface's twisted bar at another grid spacing."""
    V, F = bench.box_surface([6.0, 1.0, 1.0], spacing)
    fixed = np.flatnonzero(V[:, 0] < 1e-9)
    end = np.flatnonzero(V[:, 0] > 6.0 - 1e-9)
    moved = bench.turning(V[end], np.array([6.0, 0.5, 0.5]), [1, 0, 0], np.pi)
    return bench.Case(f"bar h={spacing}", V, F, np.concatenate([end, fixed]),
                      lambda t: np.concatenate([moved(t), V[fixed]]),
                      np.r_[np.ones(len(end)), np.zeros(len(fixed))])


def armadillo_case(subdivisions: int) -> bench.Case:
    """bench_surface's armadillo, each triangle cut into four ``subdivisions`` times (the
    handles found by the same coordinate rules on the finer mesh)."""
    import trimesh

    V, F = bench.read_mesh(bench.DATA / "armadillo.ply.xz")
    for _ in range(subdivisions):
        V, F = trimesh.remesh.subdivide(V, F)
    original = bench.read_mesh
    bench.read_mesh = lambda path: (np.asarray(V, float), np.asarray(F, np.int64))
    try:
        case = bench.armadillo()
    finally:
        bench.read_mesh = original
    case.name = f"armadillo ×{4 ** subdivisions}"
    return case


def fold_case(spacing: float) -> bench.Case:
    """``--contact2``'s strip folded in two at another grid spacing."""
    from _surface_cases_contact import sheet_fold

    case = sheet_fold(spacing)
    case.name = f"fold h={spacing:.4g}"
    return case


BUILDERS = {"bar": bar_case, "armadillo": armadillo_case, "fold": fold_case}


def cases(max_triangles: int, families=("bar", "armadillo")) -> list:
    """(label, builder, argument, triangles) of every mesh of ``families`` up to
    ``max_triangles``."""
    out = [("bar", bar_case, h, int(round(52 / h**2))) for h in BAR_SPACINGS]
    out += [("armadillo", armadillo_case, k, 86482 * 4**k) for k in (0, 1)]
    out += [("fold", fold_case, h, int(round(8 / h**2))) for h in FOLD_SPACINGS]
    return [c for c in out if c[3] <= max_triangles and c[0] in families]


def run_one(job) -> dict:
    """One method on one mesh, in this process pinned to core ``job["core"]``."""
    if hasattr(os, "sched_setaffinity") and job["core"] is not None:
        os.sched_setaffinity(0, {job["core"]})
    builder = BUILDERS[job["family"]]
    case = builder(job["arg"])
    run = bench.ours if job["method"] == "ours" else bench.arap_incremental
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        U = run(case)
    except Exception as err:  # a method that gives up is a row, not the end of the run
        return {**job, "name": case.name, "triangles": len(case.F),
                "seconds": time.perf_counter() - t0, "cpu": time.process_time() - c0,
                "refused": str(err)}
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    m = bench.measure(case, U, seconds)
    return {**job, "name": case.name, "triangles": len(case.F), "seconds": seconds,
            "cpu": cpu, "quality": m["quality"], "folds": m["folds"]}


def table(rows: list) -> str:
    """The markdown table with the ratio and the growth exponents."""
    by = {(r["family"], r["arg"], r["method"]): r for r in rows}
    lines = ["| mesh | triangles | ours s | ARAP 10 steps s | ratio | ours CPU s | "
             "ARAP 10 steps CPU s | CPU ratio | ours quality | ARAP 10 steps quality | "
             "growth k of CPU s (ours, ARAP) |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    previous = {}
    for family, arg in dict.fromkeys((r["family"], r["arg"]) for r in rows):
        o, a = by.get((family, arg, "ours")), by.get((family, arg, "ARAP 10 steps"))
        if o is None or a is None or "refused" in o or "refused" in a:
            refused = [f"{r['method']} refused after {r['seconds']:.1f} s ({r['refused']})"
                       for r in (o, a) if r is not None and "refused" in r]
            if refused:
                lines.append(f"| {(o or a)['name']} | {(o or a)['triangles']:,} | "
                             + "; ".join(refused) + " | | | | | | | | |")
            continue
        growth = ""
        if family in previous:
            p_o, p_a = previous[family]
            n = np.log(o["triangles"] / p_o["triangles"])
            growth = (f"{np.log(o['cpu'] / p_o['cpu']) / n:.2f}, "
                      f"{np.log(a['cpu'] / p_a['cpu']) / n:.2f}")
        previous[family] = (o, a)
        lines.append(f"| {o['name']} | {o['triangles']:,} | {o['seconds']:.1f} | "
                     f"{a['seconds']:.1f} | {o['seconds'] / a['seconds']:.2f} | "
                     f"{o['cpu']:.1f} | {a['cpu']:.1f} | {o['cpu'] / a['cpu']:.2f} | "
                     f"{o['quality']:.3f} ({o['folds']} folds) | {a['quality']:.3f} "
                     f"({a['folds']} folds) | {growth} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-triangles", type=int, default=100_000)
    parser.add_argument("--min-triangles", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=0, help="processes at once (0: cores)")
    parser.add_argument("--families", default="bar,armadillo",
                        help="comma-separated: " + ", ".join(BUILDERS))
    args = parser.parse_args(argv)
    families = args.families.split(",")
    jobs = [{"family": f, "arg": a, "method": m, "size": size}
            for f, _, a, size in cases(args.max_triangles, families) for m in METHODS
            if size >= args.min_triangles]
    cores = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    n = args.jobs or max(1, min(len(cores) or 1, len(jobs)))
    jobs.sort(key=lambda j: -j["size"])  # the largest first
    for i, job in enumerate(jobs):  # a core of its own for each run where there are enough
        job["core"] = cores[i] if len(cores) >= len(jobs) else None
    print(f"{len(jobs)} runs, {n} at once, one BLAS thread each", flush=True)
    rows = []
    with mp.get_context("spawn").Pool(n, maxtasksperchild=1) as pool:
        for r in pool.imap_unordered(run_one, jobs):
            outcome = (f"refused: {r['refused']}" if "refused" in r
                       else f"quality {r['quality']:.3f}, {r['folds']} folds")
            print(f"  {r['name']:<16} {r['method']:<14} {r['triangles']:>8,} triangles "
                  f"{r['seconds']:>8.1f} s ({r['cpu']:.1f} s CPU)  {outcome}", flush=True)
            rows.append(r)
    rows.sort(key=lambda r: (r["family"], r["size"]))
    print(table(rows))


if __name__ == "__main__":
    main()
