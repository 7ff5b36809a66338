"""What a clean result can reach: libigl's ARAP in increments beside ARAP with contact.

On the contact cases of ``bench_surface.py`` libigl's ARAP in 10 increments passes
through itself, so its quality and ARAP energy are no fair anchor for a result that must
stay clean. This script sets beside it a clean peer, ARAP with Incremental Potential
Contact (``_arap_contact.py``: the same energy plus ipctk's barrier, Newton steps capped by
CCD, the same increments of the handle path), and for the tube twist the closed-form twist
(each ring turned by π·clip((x − 0.1)/3.8, 0, 1), its radius kept).

Printed per case and method: worst relative quality, folds, ARAP energy, pymeshlab's
self-intersecting faces, the exact kernel's intersecting pairs
(``meshopt_toolkit.kernels.intersections3d``) and seconds; for the peer also its Newton
iterations, the increments whose handles needed the spring, and the final barrier
stiffness κ.

Run ``python benchmarks/bench_surface_clean_peer.py [--cases tube-twist,bar-folded,hand,
bunny-120] [--steps 10] [--iterations 50] [--markdown]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_surface as bench  # noqa: E402
from _arap_contact import arap_contact  # noqa: E402
from _surface_cases_contact import hand_finger  # noqa: E402

CASES = {"tube-twist": bench.tube_twist, "bar-folded": bench.bar_folded,
         "hand": hand_finger, "bunny-120": bench.bunny_ear_120}


def closed_form_twist(case: bench.Case) -> np.ndarray:
    """The tube's rings turned about the x axis by π·clip((x − 0.1)/3.8, 0, 1)."""
    V = case.V
    a = np.pi * np.clip((V[:, 0] - 0.1) / 3.8, 0.0, 1.0)
    c, s = np.cos(a), np.sin(a)
    return np.stack([V[:, 0], c * V[:, 1] - s * V[:, 2], s * V[:, 1] + c * V[:, 2]], 1)


def rows(name: str, steps: int, iterations: int):
    """(method, measures, note) for each method on one case; printed as they come."""
    case = CASES[name]()
    print(f"\n{case.name}: {len(case.V)} vertices, {len(case.F)} triangles, "
          f"{len(case.handles)} handle vertices", flush=True)
    methods = {f"libigl ARAP {steps} steps": lambda: (bench.arap_incremental(case, steps), ""),
               "ARAP + IPC": lambda: peer(case, steps, iterations)}
    if name == "tube-twist":
        methods["closed-form twist"] = lambda: (closed_form_twist(case), "")
    out = []
    for method, run in methods.items():
        t0 = time.perf_counter()
        try:
            U, note = run()
        except Exception as err:  # a method that gives up is a row, not the end of the run
            print(f"  {method:<18} failed: {type(err).__name__}: {err}", flush=True)
            continue
        m = bench.measure(case, U, time.perf_counter() - t0)
        print(f"  {method:<18} quality {m['quality']:.3f}  folds {m['folds']}  "
              f"ARAP energy {m['ARAP energy']:.4g}  pymeshlab {m['self-intersecting']}  "
              f"exact pairs {m['exact pairs']}  handle err {m['handle error']:.1e}  "
              f"{m['seconds']:.1f} s  {note}", flush=True)
        out.append((method, m, note))
    return case.name, out


def peer(case: bench.Case, steps: int, iterations: int):
    """The clean peer's points and a note of how it went."""
    r = arap_contact(case.V, case.F, case.handles, case.path, steps=steps,
                     max_iterations=iterations)
    note = (f"({sum(r.iterations)} Newton its, {sum(r.converged)}/{len(r.converged)} "
            f"increments converged, spring in {r.spring_increments}, κ {r.kappa:.3g})")
    return r.points, note + (f" STOPPED: {r.message}" if r.message else "")


def markdown(results) -> str:
    """The doc's table of every case and method."""
    lines = ["| case | method | worst rel. quality | folds | ARAP energy | pymeshlab faces "
             "| exact pairs | seconds |", "|---|---|---|---|---|---|---|---|"]
    for name, out in results:
        for i, (method, m, _) in enumerate(out):
            lines.append(f"| {name if i == 0 else ''} | {method} | {m['quality']:.3f} | "
                         f"{m['folds']} | {m['ARAP energy']:.4g} | {m['self-intersecting']} | "
                         f"{m['exact pairs']} | {m['seconds']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default=",".join(CASES),
                    help="comma-separated: " + ", ".join(CASES) + " (default: all)")
    ap.add_argument("--steps", type=int, default=bench.STEPS,
                    help="increments of the handle path (default %(default)s)")
    ap.add_argument("--iterations", type=int, default=bench.STEP_ITERATIONS[0],
                    help="the peer's Newton iterations per increment (default %(default)s, "
                         "as libigl's ARAP per increment)")
    ap.add_argument("--markdown", action="store_true", help="also print the doc's table")
    args = ap.parse_args(argv)
    names = [c for c in args.cases.split(",") if c]
    unknown = [c for c in names if c not in CASES]
    if unknown:
        print(f"bench_surface_clean_peer: unknown case {unknown[0]!r}", file=sys.stderr)
        return 2
    results = [rows(name, args.steps, args.iterations) for name in names]
    if args.markdown:
        print("\n" + markdown(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
