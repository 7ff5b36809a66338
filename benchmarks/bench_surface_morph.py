"""Morphing two poses of a triangle surface in 3D: linear interpolation, as-rigid-as-possible
interpolation (Alexa, Cohen-Or & Levin 2000; ``_arap_interpolation.py``) and ours
(``meshopt_toolkit.motion.surface.morph.morph_surface``) side by side in one process.

Pairs: the rest surfaces and handle motions of ``bench_surface.py`` (data/surfaces/README.md
names the meshes' sources and terms), the target pose made by libigl ARAP in 10 steps (not
our solver) or by our ``move_surface``:

* bar-ours / bar-libigl: the 6×1×1 box, one cap turned 180° about the long axis;
* bunny-ours / bunny-libigl: the bunny's ear turned 90° backwards;
* armadillo-libigl (not in the default list: libigl takes minutes): the hand raised 90°.

"ours' start" is the library's as-rigid-as-possible interpolation with the pair's best
rotation factored out (``motion/surface/interpolation.py``), its frames below the worse
end's quality lifted by local/global steps: the path ours starts from ("no steps": Alexa
et al.'s fit alone);
"ours" stops as soon as every frame is at least as healthy as the worse end (the start
included), "ours, energy stop" only by the Gauss–Newton energy tests (``rtol = 0.05``).

Printed per pair and method: the worst relative quality over all frames (aspect ratio 2r/R
over its value in the source, ``_surface_measures.py``), the folds summed over the frames
(against the source), the path energy ``E`` of ``morph_surface`` (where no triangle is
degenerate), seconds (the fastest of three runs where one takes under ten seconds); and the
requirement 0.9 × the worse end. ``--docs`` writes
the table into docs/benchmarks-surface.md (its own section, the rest kept).

Run ``python benchmarks/bench_surface_morph.py [--pairs bar-ours,bunny-libigl] [--frames 9]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_surface as bench  # noqa: E402
from _arap_interpolation import arap_interpolation, linear_interpolation  # noqa: E402
from _surface_measures import fold_count, worst_relative_quality  # noqa: E402

DOCS = Path(__file__).resolve().parent.parent / "docs" / "benchmarks-surface.md"
HEADING = "## Morphing two poses (`bench_surface_morph.py`)"


def pose(case_name: str, maker: str) -> tuple:
    """``(V0, F, V1)``: a case of bench_surface.py and its target pose made by ``maker``
    ("libigl": ARAP in 10 steps, "ours": move_surface)."""
    case = bench.CASES[case_name]()
    if maker == "libigl":
        V1 = bench.arap_incremental(case)
    else:
        from meshopt_toolkit.motion.surface.move import move_surface

        V1 = move_surface(case.V, case.F, case.handles, case.path(1.0)).points
    return case.V, case.F, np.asarray(V1, float)


PAIRS = {"bar-ours": ("bar", "ours"), "bar-libigl": ("bar", "libigl"),
         "bunny-ours": ("bunny", "ours"), "bunny-libigl": ("bunny", "libigl"),
         "armadillo-libigl": ("armadillo", "libigl")}
DEFAULT = "bar-ours,bar-libigl,bunny-ours,bunny-libigl"
#: runs of a method under ten seconds, the fastest printed (the shared machine's load varies)
REPEATS = 3


def ours(V0, V1, F, times, **options):
    from meshopt_toolkit.motion.surface.morph import morph_surface

    return list(morph_surface(V0, V1, F, len(times), **options).points)


def path_energy(V0, V1, F, path) -> float:
    """``morph_surface``'s path energy of ``path`` (NaN where a triangle degenerates)."""
    from meshopt_toolkit.motion.surface.morph import BENDING, WEIGHT, _PathProblem

    problem = _PathProblem(V0, V1, F, WEIGHT, BENDING)
    X = [problem.embed(Q) for Q in path]
    if any(x is None for x in X):
        return float("nan")
    return 0.5 * sum(float(r @ r) for r in (problem.segment(a, b) for a, b in zip(X, X[1:])))


def ours_start(V0, V1, F, times, steps=True):
    """The start of ``morph_surface``: its frames below the worse end's quality lifted by
    local/global steps (``steps``), or Alexa et al.'s fit alone."""
    from meshopt_toolkit.kernels.surface import aspect_ratios
    from meshopt_toolkit.motion.surface.interpolation import arap_interpolation as start
    from meshopt_toolkit.motion.surface.morph import START_ITERATIONS

    if not steps:
        return start(V0, V1, F, times)
    q0 = aspect_ratios(V0, F)  # the library's measure, as in morph_surface's healthy test
    floor = min(1.0, float((aspect_ratios(V1, F) / q0).min()))
    return start(V0, V1, F, times, iterations=START_ITERATIONS, until=lambda frames: all(
        float((aspect_ratios(X, F) / q0).min()) >= floor for X in frames[1:-1]))


METHODS = {"linear": lambda V0, V1, F, t: linear_interpolation(V0, V1, t),
           "ARAP interpolation": arap_interpolation,
           "ours' start, no steps": lambda *a: ours_start(*a, steps=False),
           "ours' start": ours_start,
           "ours": ours,
           "ours, energy stop": lambda *a: ours(*a, stop_when_healthy=False)}


def run_pair(name: str, frames: int) -> list:
    V0, F, V1 = pose(*PAIRS[name])
    end = min(1.0, worst_relative_quality(V0, V1, F, []))
    print(f"\n{name}: {len(V0)} vertices, {len(F)} triangles, {frames} frames; target's "
          f"worst relative quality {end:.3f} (frames need ≥ {0.9 * end:.3f})")
    print(f"  {'method':<20} {'worst rel. q':>12} {'folds':>6} {'energy':>8} {'seconds':>8}")
    times = np.linspace(0.0, 1.0, frames)
    rows = []
    for method, run in METHODS.items():
        seconds = np.inf
        for _ in range(REPEATS):  # the best of a few runs where one is short
            t0 = time.perf_counter()
            path = run(V0, V1, F, times)
            seconds = min(seconds, time.perf_counter() - t0)
            if seconds > 10.0:
                break
        q = min(worst_relative_quality(V0, X, F, []) for X in path)
        folds = sum(fold_count(V0, X, F) for X in path)
        E = path_energy(V0, V1, F, path)
        rows.append((name, len(F), end, method, q, folds, E, seconds))
        print(f"  {method:<20} {q:>12.3f} {folds:>6d} {E:>8.3f} {seconds:>8.2f}", flush=True)
    return rows


def markdown(rows: list, frames: int) -> str:
    lines = [HEADING, "",
             f"Printed by `python benchmarks/bench_surface_morph.py --docs` ({frames} frames; "
             "the shared 2-core machine's load varies: compare seconds within a pair; run "
             "with `OPENBLAS_NUM_THREADS=1`; seconds under 10 the fastest of "
             f"{REPEATS} runs). "
             "Worst relative quality: the minimum over all frames and triangles of the aspect "
             "ratio 2r/R over its value in the source; folds summed over the frames; path "
             "energy E of `morph_surface` (– where a triangle degenerates). \"ours\" stops "
             "once every frame is at least as healthy as the worse end, \"ours, energy "
             "stop\" by the Gauss–Newton energy tests alone (`stop_when_healthy=False`).", "",
             "| pair | triangles | target's quality | method | worst rel. quality | folds "
             "| E | seconds | × ARAP interpolation |", "| --- | --- | --- | --- | --- | --- "
             "| --- | --- | --- |"]
    arap = {r[0]: r[7] for r in rows if r[3] == "ARAP interpolation"}
    for name, T, end, method, q, folds, E, seconds in rows:
        energy = "–" if np.isnan(E) else f"{E:.3f}"
        lines.append(f"| {name} | {T:,} | {end:.3f} | {method} | {q:.3f} | {folds} "
                     f"| {energy} | {seconds:.2f} | {seconds / max(arap[name], 1e-9):.1f} |")
    return "\n".join(lines) + "\n"


def write_docs(text: str) -> None:
    """Replace the section under ``HEADING`` (up to the next ``## `` heading) by ``text``,
    or append it; the rest of the page is kept as it is."""
    old = DOCS.read_text(encoding="utf-8")
    head, found, rest = old.partition(HEADING)
    tail = ""
    if found:
        after = rest.find("\n## ")
        tail = "" if after < 0 else rest[after + 1:]
    new = head.rstrip("\n") + "\n\n" + text
    DOCS.write_text(new + ("\n" + tail if tail else ""), encoding="utf-8")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pairs", default=DEFAULT, help="comma-separated: " + ", ".join(PAIRS))
    ap.add_argument("--frames", type=int, default=9)
    ap.add_argument("--docs", action="store_true",
                    help="write the table into docs/benchmarks-surface.md")
    args = ap.parse_args(argv)
    names = [p for p in args.pairs.split(",") if p]
    unknown = [p for p in names if p not in PAIRS]
    if unknown:
        print(f"bench_surface_morph: unknown pair {unknown[0]!r}", file=sys.stderr)
        return 2
    rows = [row for name in names for row in run_pair(name, args.frames)]
    text = markdown(rows, args.frames)
    print("\n" + text)
    if args.docs:
        write_docs(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
