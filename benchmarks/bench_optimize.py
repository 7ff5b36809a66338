"""Thesis table 6.4, parameter set 2, per method (``--table``, the default) and the time
per optimization iteration of each variant on the bundled discs (``--per-iteration``, like
thesis table 6.6).

``--table``: every variant × method (steepest, lbfgs, cg) on disc_146 with the default
stopping rules; iterations, seconds, final j + f2 and its difference from steepest
descent's (must be within 2e-4), the ratios to steepest descent (targets ≤ 1/4 of the
iterations and ≤ 1/2 of the time for complete-euclidean, elasticity-euclidean and
complete-complete), then the elasticity-euclidean L-BFGS iteration counts and final min AR
on the bundled discs up to ``--max-vertices`` (a good metric: nearly mesh-independent).
The complete-* rows add ``lbfgs/B=G``: L-BFGS without the default preconditioner
(``lbfgs_preconditioner="none"``, ``H_0 = γ G⁻¹``; :mod:`meshopt_toolkit.shape.preconditioners`).

``--defaults``: what ``meshopt optimize MESH`` does on every bundled disc (146 to 13,586
vertices; the criterion: converged and min AR ≥ ½ its initial value) — the
default variant, method and penalty — beside the two choices they replace: thesis set 2
with β4 = 0.001·N, and variant complete-euclidean.

``--per-iteration``: side by side in one process with the runs interleaved (the machine is shared
and noisy), and the ratio complete-complete / complete-euclidean (target ≤ 3 on the
~541-vertex disc; the thesis: about 2000).

complete-complete uses the default retraction (second order, ``optimize.RETRACTIONS``);
``--table`` adds rows along the exponential map (``retraction="exp"``: its line-search
mode, ``optimize.EXP_DEFAULTS``, and the 1e-6-accurate map, ``exp_options={"method":
"auto"}``), ``--exact`` a per-iteration row with the accurate map, for comparison.

``--users``: ``meshopt optimize MESH``'s defaults on users' kinds of gmsh meshes
(:mod:`meshopt_toolkit.shape.cases`: plates with holes, L-shapes, airfoils in boxes,
channels with obstacles, 0.3k to 20k vertices, up to ``--max-vertices``) and a plate
whose outer boundary is fixed and whose area is kept: iterations, seconds, the objective
weight, the worst triangle (min aspect ratio) and j before and after, as a Markdown table
(docs/shape-optimization.md). Done when every run converges and keeps AR ≥ ½ AR0.

Usage: python benchmarks/bench_optimize.py [--table] [--max-vertices 2200]
       python benchmarks/bench_optimize.py --users [--max-vertices 21000] [--row N ...]
       python benchmarks/bench_optimize.py --defaults [--max-vertices 14000]
       python benchmarks/bench_optimize.py --per-iteration [--iterations 10] [--repeats 3]
       [--max-vertices 14000] [--exact]
"""

from __future__ import annotations

import argparse

import numpy as np
from _common import best_of

import meshopt_toolkit as mt
from meshopt_toolkit import datasets
from meshopt_toolkit.optimize import (
    DEFAULT_METHOD,
    DEFAULT_PENALTY_BETA,
    DEFAULT_VARIANT,
    VARIANTS,
    default_metric_beta,
    optimize,
    thesis_penalty_beta,
)
from meshopt_toolkit.fem.poisson import DEFAULT_RHS, PoissonObjective


def run(mesh, variant, iterations, exp_options=None):
    """(wall time / iteration, result) of a run with penalty parameter set 2 and the
    default metric β, no early stop; ``exp_options``: along the exponential map."""
    retraction = {} if exp_options is None else {"retraction": "exp", "exp_options": exp_options}
    res = optimize(mesh, PoissonObjective(mesh), variant=variant, method="steepest",
                   penalty=thesis_penalty_beta(2, mesh.n_vertices),
                   metric_beta=default_metric_beta(mesh.n_vertices),
                   max_iterations=iterations, options=dict(tolerance=None, **retraction))
    return res.seconds / max(res.nit, 1), res


def solve(mesh, variant, method, **options):
    """A run of table 6.4 set 2 with the default stopping rules (``options``: fields of
    :class:`~meshopt_toolkit.shape.options.OptimizeOptions`)."""
    return optimize(mesh, PoissonObjective(mesh), variant=variant, method=method,
                    penalty=thesis_penalty_beta(2, mesh.n_vertices),
                    metric_beta=default_metric_beta(mesh.n_vertices), options=options)


def table(max_vertices: int) -> None:
    mesh = mt.load(mt.data_path("disc_146.msh")).as_planar()
    targets = ("complete-euclidean", "elasticity-euclidean", "complete-complete")
    rows = {v: (v, {}) for v in VARIANTS}
    # complete-complete along the exponential map instead of the second-order retraction:
    # the geodesic's line-search mode, and the 1e-6-accurate map (the thesis' algorithm)
    rows["c-c, exp (line-search)"] = ("complete-complete", {"retraction": "exp"})
    rows["c-c, exp (accurate)"] = ("complete-complete", {"retraction": "exp",
                                                         "exp_options": {"method": "auto"}})
    print("table 6.4, parameter set 2, disc_146 (default stopping rules)")
    print(f"{'variant':<22} {'method':<9} {'status':<15} {'iter':>5} {'s':>7} {'j+f2':>10} "
          f"{'Δ vs sd':>9} {'iter/sd':>8} {'s/sd':>6} {'minAR':>6} {'rej.pairs':>9}")
    for label, (variant, kw) in rows.items():
        base = None
        methods = ["steepest", "lbfgs", "cg"]
        if variant.startswith("complete"):  # L-BFGS with H0 = γ G⁻¹ (no preconditioner)
            methods.insert(2, "lbfgs/B=G")
        for method in methods:
            extra = {"lbfgs_preconditioner": "none"} if method == "lbfgs/B=G" else {}
            res = solve(mesh, variant, method.split("/")[0], **kw, **extra)
            base = base or res
            last = res.history[-1]
            di, dt = res.nit / base.nit, res.seconds / base.seconds
            ok = ""
            if method != "steepest" and variant in targets:
                ok = "  ok" if di <= 0.25 and dt <= 0.5 and abs(res.fun - base.fun) <= 2e-4 \
                    else "  MISSED"
            print(f"{label:<22} {method:<9} {res.status:<15} {res.nit:>5} {res.seconds:>7.2f} "
                  f"{res.fun:>10.6f} {res.fun - base.fun:>+9.1e} {di:>8.2f} {dt:>6.2f} "
                  f"{last.min_aspect_ratio:>6.3f} {res.rejected_pairs:>9}{ok}", flush=True)
    print("\nelasticity-euclidean, lbfgs, parameter set 2, per disc")
    print(f"{'N_V':>6} {'status':<15} {'iter':>5} {'s':>8} {'j+f2':>10} {'AR0':>6} {'AR':>6}")
    for name in _discs(max_vertices):
        m = mt.load(mt.data_path(name)).as_planar()
        res = solve(m, "elasticity-euclidean", "lbfgs")
        print(f"{m.n_vertices:>6} {res.status:<15} {res.nit:>5} {res.seconds:>8.2f} {res.fun:>10.6f} "
              f"{res.history[0].min_aspect_ratio:>6.3f} {res.history[-1].min_aspect_ratio:>6.3f}",
              flush=True)


def defaults(max_vertices: int) -> None:
    print(f"meshopt optimize's defaults ({DEFAULT_VARIANT}, {DEFAULT_METHOD}, "
          f"β = {DEFAULT_PENALTY_BETA}, default rhs) beside what they replace")
    print(f"{'N_V':>6} {'run':<34} {'status':<15} {'iter':>5} {'s':>8} {'j':>9} "
          f"{'AR0':>6} {'AR':>7} {'AR/AR0':>7}")
    for name in _discs(max_vertices):
        mesh = mt.load(mt.data_path(name)).as_planar()
        runs = {
            "defaults": (DEFAULT_VARIANT, DEFAULT_PENALTY_BETA),
            "thesis set 2 (β4 = 0.001·N)": (DEFAULT_VARIANT, thesis_penalty_beta(2, mesh.n_vertices)),
            "variant complete-euclidean": ("complete-euclidean", DEFAULT_PENALTY_BETA),
        }
        for label, (variant, beta) in runs.items():
            res = optimize(mesh, PoissonObjective(mesh, rhs=DEFAULT_RHS), variant=variant,
                           penalty=beta)
            ar0, ar = res.history[0].min_aspect_ratio, res.history[-1].min_aspect_ratio
            print(f"{mesh.n_vertices:>6} {label:<34} {res.status:<15} {res.nit:>5} "
                  f"{res.seconds:>8.2f} {res.j:>9.5f} {ar0:>6.3f} {ar:>7.4f} {ar / ar0:>7.2f}",
                  flush=True)


#: (label, case, element size, size near the holes/obstacles/airfoil, problem options)
USER_CASES = (
    ("plate with two holes", "plate", 0.2, None, {}),
    ("L-shape", "lshape", 0.1, None, {}),
    ("airfoil in a box", "airfoil", 0.15, 0.05, {}),
    ("channel with two obstacles", "channel", 0.08, None, {}),
    ("plate, outer fixed, area kept", "plate", 0.2, None, {"fixed": "outer", "keep": "area"}),
    ("L-shape, boundary fixed", "lshape", 0.1, None, {"fixed": "outer,reentrant"}),
    ("channel, obstacles move, area kept", "channel", 0.08, None,
     {"move": "disc,square", "keep": "area"}),
    ("plate with two holes", "plate", 0.06, None, {}),
    ("L-shape", "lshape", 0.03, None, {}),
    ("airfoil in a box", "airfoil", 0.06, 0.015, {}),
    ("channel with two obstacles", "channel", 0.025, None, {}),
    ("plate with two holes", "plate", 0.025, None, {}),
)


def users(max_vertices: int, rows: list[int] | None = None) -> None:
    import tempfile
    from pathlib import Path

    from meshopt_toolkit.kernels.triangles import signed_areas
    from meshopt_toolkit.shape.cases import user_mesh
    from meshopt_toolkit.shape.spec import spec_from_options

    print(f"meshopt optimize MESH's defaults ({DEFAULT_VARIANT}, {DEFAULT_METHOD}, "
          f"β = {DEFAULT_PENALTY_BETA}, default rhs, objective scale auto)\n")
    print("| mesh | vertices | triangles | status | iterations | seconds | s / iteration "
          "| iteration / state solve | weight w | worst AR before → after (ratio) "
          "| j before → after | area change |")
    print("| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | --- | --- | ---: |")
    with tempfile.TemporaryDirectory() as tmp:
        for row, (label, case, size, near, options) in enumerate(USER_CASES, 1):
            if rows and row not in rows:
                continue
            path = user_mesh(case, Path(tmp) / f"{case}-{size}.msh", size, refine_near=near)
            mesh = mt.load(path).as_planar()
            if mesh.n_vertices > max_vertices:
                continue
            spec = spec_from_options(**options)
            state = best_of(lambda: spec.make_objective(mesh).value(mesh.points), 3)[0]
            res = optimize(mesh, None, problem=spec, penalty=DEFAULT_PENALTY_BETA)
            per = sum(res.phase_totals().values()) / max(res.nit, 1)
            h0, h1 = res.history[0], res.history[-1]
            ratio = h1.min_aspect_ratio / h0.min_aspect_ratio
            dA = abs(signed_areas(res.x, mesh.triangles).sum()
                     - signed_areas(mesh.points, mesh.triangles).sum())
            flag = "" if res.success and ratio >= 0.5 and h1.j < h0.j else " **MISSED**"
            print(f"| {label}{flag} | {mesh.n_vertices} | {mesh.n_triangles} | {res.status} "
                  f"| {res.nit} | {res.seconds:.1f} | {per:.3f} | {per / state:.2f} "
                  f"| {res.objective_weight:.2g} "
                  f"| {h0.min_aspect_ratio:.3f} → {h1.min_aspect_ratio:.3f} ({ratio:.2f}) "
                  f"| {h0.j:.4g} → {h1.j:.4g} | {dA:.1e} |", flush=True)


def _discs(max_vertices: int) -> list[str]:
    names = sorted((n for n in datasets.available() if n.startswith("disc_")),
                   key=lambda s: int(s[5:-4]))
    return [n for n in names if 140 <= int(n[5:-4]) <= max_vertices]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--table", action="store_true", help="table 6.4 set 2 per method (default)")
    p.add_argument("--defaults", action="store_true",
                   help="meshopt optimize's defaults on every bundled disc")
    p.add_argument("--per-iteration", action="store_true", help="time per iteration per variant")
    p.add_argument("--users", action="store_true",
                   help="the defaults on users' kinds of gmsh meshes (Markdown table)")
    p.add_argument("--row", type=int, action="append",
                   help="with --users: only this row of USER_CASES (1-based; repeatable)")
    p.add_argument("--iterations", type=int, default=10)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--max-vertices", type=int, default=None,
                   help="largest disc (default: 2200 for --table, 14000 for --per-iteration)")
    p.add_argument("--exact", action="store_true",
                   help="also time complete-complete with the exact (1e-6) exponential map")
    args = p.parse_args(argv)
    if args.users:
        users(args.max_vertices or 21000, args.row)
        return
    if args.defaults:
        defaults(args.max_vertices or 14000)
        return
    if not args.per_iteration:
        table(args.max_vertices or 2200)
        return
    args.max_vertices = args.max_vertices or 14000
    names = sorted((n for n in datasets.available() if n.startswith("disc_")),
                   key=lambda s: int(s[5:-4]))
    print(f"{'N_V':>6} {'variant':<28} {'s/iter':>10} {'/ complete-euclidean':>22}  phases (s/iter)")
    for name in names:
        nv = int(name[5:-4])
        if nv > args.max_vertices or nv < 70:
            continue
        mesh = mt.load(mt.data_path(name)).as_planar()
        rows = {v: (v, None) for v in VARIANTS}
        if args.exact:
            rows["complete-complete (exact exp)"] = ("complete-complete", {"method": "auto"})
        times = {k: [] for k in rows}
        last = {}
        for _ in range(args.repeats):  # interleaved: every variant once per round
            for key, (variant, opts) in rows.items():
                t, res = run(mesh, variant, args.iterations, opts)
                times[key].append(t)
                last[key] = res
        base = np.array(times["complete-euclidean"])
        for key in rows:
            t = np.array(times[key])
            ph = last[key].phase_totals()
            detail = " ".join(f"{k}={v / max(last[key].nit, 1):.2e}" for k, v in ph.items() if v)
            ratio = float(np.median(t / base))  # per round: the runs next to each other
            print(f"{mesh.n_vertices:>6} {key:<28} {np.median(t):>10.2e} {ratio:>22.2f}  {detail}")
        cc = float(np.median(np.array(times["complete-complete"]) / base))
        note = "  <-- target ≤ 3" if 400 <= mesh.n_vertices <= 700 else ""
        print(f"{'':>6} complete-complete / complete-euclidean = {cc:.2f}{note}\n")


if __name__ == "__main__":
    main()
