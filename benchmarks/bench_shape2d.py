"""2D shape optimization against closed forms and peers (docs/shape-optimization.md).

``--elasticity``: a disc hole of area π/4 in an 8 × 8 plate under the stresses (2, 1, 0)
(``meshopt optimize plate.msh --pde elasticity --stress 'outer=2,1,0' --objective
compliance --move hole --keep-area``). The closed-form optimum (the hole of least
compliance at fixed area in an infinite plate) is the ellipse with axes in the ratio of
the stresses, a/b = 2: compared with the optimized hole's axes (from its area and second
moments), and with gmsh meshes of ellipses of the same area at ratios around 2 on the
same solver, to see the optimum on this discretization. Also the run with f2's anchor
held at the initial mesh (``ANCHOR_RESTARTS = 0``).

``--stokes``: a disc of area π/4 in a 6 × 4 box moved at unit speed along x (``--pde
stokes --dirichlet 'body=1,0' --dirichlet 'outer=0,0' --objective dissipation --move
body --keep-volume --keep-barycenter``): its drag against the best ellipse of the same
area in the same box (aspect ratios scanned, gmsh meshes, the same solver) and the angles
at the optimized body's front and back (Pironneau's optimum in unbounded flow has 90°
wedge ends).

Both: every drag and compliance recomputed by scikit-fem on the written meshes
(:mod:`_peers2d`), the area (and barycenter) kept, the fixed boundary untouched, the
worst cell against the start, and the time of one iteration against one state solve
(CPU seconds: on a shared machine other processes add to wall times, not to these).

Usage: python benchmarks/bench_shape2d.py [--elasticity] [--stokes] [--size 0.6]
       [--refine-near 0.08] [--out DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import importlib
import io
import os
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _peers2d import (compliance_skfem, dissipation_skfem, loop_of, moment_axes,  # noqa: E402
                      read_groups, tip_angles)

from meshopt_toolkit.cli import main  # noqa: E402
from meshopt_toolkit.cli._common import load_workpiece  # noqa: E402
from meshopt_toolkit.kernels.triangles import aspect_ratios, signed_areas  # noqa: E402
from meshopt_toolkit.shape.cases import ellipse_in_box  # noqa: E402
from meshopt_toolkit.shape.spec import spec_from_options  # noqa: E402

optimize_module = importlib.import_module("meshopt_toolkit.optimize")

AREA = math.pi / 4
ELASTICITY = ["--pde", "elasticity", "--stress", "outer=2,1,0", "--objective", "compliance",
              "--move", "hole", "--keep-area"]
STOKES = ["--pde", "stokes", "--dirichlet", "body=1,0", "--dirichlet", "outer=0,0",
          "--objective", "dissipation", "--move", "body", "--keep-volume", "--keep-barycenter"]


def ellipse(path, ratio: float, box, size, refine_near, inner):
    """A gmsh mesh of the ellipse of area π/4 and axis ratio ``ratio`` (long along x)."""
    a = math.sqrt(AREA * ratio / math.pi)
    with quiet():
        return ellipse_in_box(path, (a, AREA / (math.pi * a)), box, size,
                              refine_near=refine_near, inner=inner)


@contextlib.contextmanager
def quiet():
    """gmsh's own lines on stdout (file descriptor 1) kept out of the tables."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        try:
            yield
        finally:
            os.dup2(saved, 1)
            os.close(saved)


@contextlib.contextmanager
def cpu_clock():
    """``time.perf_counter`` reads this process's CPU time meanwhile: the phases the
    library times (``history.csv``'s ``time_*`` columns, ``phase_totals``) come in CPU
    seconds, which other processes on a shared machine do not add to."""
    wall = time.perf_counter
    time.perf_counter = time.process_time
    try:
        yield
    finally:
        time.perf_counter = wall


def run_cli(mesh, args, out):
    """``meshopt optimize`` in this process: ``(summary, history rows)``, the history's
    phases in CPU seconds (:func:`cpu_clock`); the summary gets the run's CPU seconds
    (``cpu_seconds``: setup, every anchor restart and writing included)."""
    c0 = time.process_time()
    with contextlib.redirect_stdout(io.StringIO()), cpu_clock():
        code = main(["optimize", str(mesh), *args, "--no-plots", "-o", str(out)])
    cpu = time.process_time() - c0
    if code != 0:
        raise SystemExit(f"meshopt optimize {mesh} failed (exit {code})")
    with open(out / "history.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    summary = json.loads((out / "summary.json").read_text())
    summary["cpu_seconds"] = cpu
    return summary, rows


def state_seconds(mesh_path, spec_args, repeat: int = 9) -> float:
    """The median CPU time of one state solve over ``repeat`` (a fresh configuration each
    time): a typical solve, as the iterations' mean is a typical iteration."""
    mesh = load_workpiece(mesh_path, "optimize").mesh
    j = spec_from_options(**spec_args).make_objective(mesh)
    rng = np.random.default_rng(0)
    times = []
    for _ in range(repeat):
        c0 = time.process_time()
        j.value(mesh.points * (1 + 1e-9 * rng.random()))
        times.append(time.process_time() - c0)
    return float(np.median(times))


def body_report(before, after, group, fixed_group):
    """The body's shape and what the run had to keep, from the two files alone."""
    P0, T, g0 = read_groups(before)
    P1, T1, _ = read_groups(after)
    assert np.array_equal(T, T1)
    loop = loop_of(g0[group])
    a, b, angle = moment_axes(P1, loop)
    x, y = P0[loop].T, P1[loop].T

    def area_center(X, Y):
        c = X * np.roll(Y, -1) - np.roll(X, -1) * Y
        A = c.sum() / 2
        M = [((X + np.roll(X, -1)) * c).sum(), ((Y + np.roll(Y, -1)) * c).sum()]
        return A, np.array(M) / (6 * A)

    A0, c0 = area_center(*x)
    A1, c1 = area_center(*y)
    outer = np.unique(g0[fixed_group])
    ar0, ar1 = aspect_ratios(P0, T).min(), aspect_ratios(P1, T).min()
    return dict(ratio=a / b, a=a, b=b, angle=angle, area_change=abs(A1 - A0) / abs(A0),
                barycenter_shift=float(np.linalg.norm(c1 - c0)) / math.sqrt(abs(A0)),
                outer_untouched=bool(np.array_equal(P0[outer], P1[outer])),
                min_area=float(signed_areas(P1, T).min()), worst=ar1 / ar0, P=P1, loop=loop)


def iteration_table(rows, every: int, solve: float) -> None:
    """Per iteration: j, the worst cell against the start, state and total CPU seconds,
    and the iteration in state solves (``solve`` CPU seconds each)."""
    ar0 = float(rows[0]["min_aspect_ratio"])
    phases = [k for k in rows[0] if k.startswith("time_")]
    print("| iteration | j | worst AR / start | state solves (s) | iteration (s) "
          "| iteration / state solve |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in rows[1:]:
        i = int(r["iteration"])
        if i % every and r is not rows[-1]:
            continue
        total = sum(float(r[k]) for k in phases)
        print(f"| {i} | {float(r['j']):.6g} | {float(r['min_aspect_ratio']) / ar0:.3f} | "
              f"{float(r['time_state']):.3f} | {total:.3f} | {total / solve:.2f} |")


def speed(rows, solve: float, summary) -> str:
    """The mean iteration against one state solve and where its time goes (CPU
    seconds), and the whole run's CPU time per iteration (``summary`` of
    :func:`run_cli`)."""
    phases = [k for k in rows[0] if k.startswith("time_")]
    mean = {k[5:]: np.mean([float(r[k]) for r in rows[1:]]) for k in phases}
    per = sum(mean.values())
    parts = ", ".join(f"{k} {v:.4f}" for k, v in mean.items() if v >= 0.00005)
    nit = summary["iterations"]
    return (f"One iteration {per:.4f} s = {per / solve:.2f} state solves ({solve:.4f} s each, "
            f"the median of 9; CPU seconds); per phase (s): {parts}. The whole run: "
            f"{summary['cpu_seconds']:.2f} s over {nit} iterations = "
            f"{summary['cpu_seconds'] / (nit * solve):.2f} state solves per iteration (setup, "
            f"anchor restarts and output included).")


def elasticity(tmp: Path, size: float, refine_near: float) -> None:
    plate = ellipse(tmp / "plate.msh", 1.0, (8, 8), size, refine_near, "hole")
    print(f"\n### Elasticity: a hole in an 8 × 8 plate under (2, 1, 0) "
          f"({len(read_groups(plate)[0])} vertices)\n")
    print("| hole | compliance (ours) | compliance (scikit-fem) |")
    print("| --- | ---: | ---: |")
    spec = dict(pde="elasticity", stress="outer=2,1,0", objective="compliance")
    for ratio in (1.0, 1.6, 1.8, 2.0, 2.2, 2.5):
        path = plate if ratio == 1 else ellipse(tmp / f"plate{ratio}.msh", ratio, (8, 8), size,
                                                refine_near, "hole")
        mesh = load_workpiece(path, "optimize").mesh
        ours = spec_from_options(**spec).make_objective(mesh).value(mesh.points)
        print(f"| ellipse a/b = {ratio:g} (gmsh) | {ours:.6f} | "
              f"{compliance_skfem(path, 'outer', (2, 1, 0)):.6f} |")
    runs = {}
    for name, restarts in (("anchor held at Q0", 0),
                           ("anchor follows (default)", optimize_module.ANCHOR_RESTARTS)):
        kept, optimize_module.ANCHOR_RESTARTS = optimize_module.ANCHOR_RESTARTS, restarts
        try:
            runs[name] = run_cli(plate, ELASTICITY, tmp / f"plate-{restarts}")
        finally:
            optimize_module.ANCHOR_RESTARTS = kept
        summary, rows = runs[name]
        out = tmp / f"plate-{restarts}" / "optimized.msh"
        r = body_report(plate, out, "hole", "outer")
        print(f"| optimized, {name}: a/b = {r['ratio']:.3f}, {summary['iterations']} "
              f"iterations, {summary['cpu_seconds']:.1f} s CPU | {summary['j']:.6f} | "
              f"{compliance_skfem(out, 'outer', (2, 1, 0)):.6f} |")
    r = body_report(plate, tmp / f"plate-{optimize_module.ANCHOR_RESTARTS}" / "optimized.msh",
                    "hole", "outer")
    print(f"\nDefault run: axes {r['a']:.4f} × {r['b']:.4f} (a/b = {r['ratio']:.3f}, the long "
          f"axis at {r['angle']:.1f}° from x), area kept to {r['area_change']:.1e} relative, "
          f"outer boundary untouched: {r['outer_untouched']}, smallest area {r['min_area']:.2e},"
          f" worst AR {r['worst']:.3f} × the start.")
    summary, rows = runs["anchor follows (default)"]
    solve = state_seconds(plate, dict(spec, move="hole"))
    print(speed(rows, solve, summary))
    metric_factor_choices(plate, dict(spec, move="hole", keep="area"), solve, 30)
    print()
    iteration_table(rows, 10, solve)


def metric_factor_choices(path, spec_args, solve: float, iterations: int) -> None:
    """The elasticity metric's choice of a factorization per iterate: by its operation
    counts (the default, ``kept_factor.refactorize_pays``), against the counts with a
    factorization's multiply-adds as dear as a solve's (``FACTORIZATION_SPEED = 1``),
    keeping the factor until CG needs more than ``REFACTOR_AFTER_CG`` iterations (no
    counts) and a factorization at every iterate (``REFACTOR_AFTER_CG = 0``)."""
    from meshopt_toolkit.optimize import optimize
    from meshopt_toolkit.riemannian import kept_factor, metrics

    mesh = load_workpiece(path, "optimize").mesh
    spec = spec_from_options(**spec_args)
    kept_cg, counts_of, init = (metrics.ElasticityMetric.REFACTOR_AFTER_CG,
                                metrics.KeptFactorCosts.of, metrics.ElasticityMetric.__init__)
    speed_ = kept_factor.FACTORIZATION_SPEED
    made = []

    def recorded(self, *args, **kwargs):
        init(self, *args, **kwargs)
        made.append(self)

    choices = (("by operation counts (default)", kept_cg, counts_of, speed_),
               ("by operation counts, FACTORIZATION_SPEED = 1", kept_cg, counts_of, 1.0),
               ("kept until CG exceeds REFACTOR_AFTER_CG", kept_cg, lambda *a: None, speed_),
               ("at every iterate", 0, counts_of, speed_))
    out = {}
    metrics.ElasticityMetric.__init__ = recorded
    try:
        for name, cg, of, fast in choices:
            metrics.ElasticityMetric.REFACTOR_AFTER_CG, metrics.KeptFactorCosts.of = cg, of
            kept_factor.FACTORIZATION_SPEED = fast
            made.clear()
            t0 = time.process_time()
            with cpu_clock():
                r = optimize(mesh, problem=spec, max_iterations=iterations)
            out[name] = (r.x, r.phase_totals(), r.nit, sum(m.n_factorizations for m in made),
                         time.process_time() - t0)
    finally:
        metrics.ElasticityMetric.REFACTOR_AFTER_CG = kept_cg
        metrics.KeptFactorCosts.of = counts_of
        metrics.ElasticityMetric.__init__ = init
        kept_factor.FACTORIZATION_SPEED = speed_
    x0 = out[choices[0][0]][0]
    print(f"\nThe elasticity metric's factorizations over {iterations} iterations (CPU "
          f"seconds):\n")
    print("| factorization | factorizations | iteration (s) | iteration / state solve "
          "| metric solves per iteration (s) | total (s) | iterates' max difference |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name, (x, phases, nit, factorizations, total) in out.items():
        per = sum(phases.values()) / nit
        diff = np.abs(x - x0).max() / np.abs(x0).max()
        print(f"| {name} | {factorizations} | {per:.3f} | {per / solve:.2f} | "
              f"{phases['gradient'] / nit:.3f} | {total:.1f} | {diff:.1e} |")


def stokes(tmp: Path, size: float, refine_near: float, ratios) -> None:
    body = ellipse(tmp / "body.msh", 1.0, (6, 4), size, refine_near, "body")
    print(f"\n### Stokes: a body in a 6 × 4 box moved at unit speed "
          f"({len(read_groups(body)[0])} vertices)\n")
    print("| body | drag (ours) | drag (scikit-fem) | front / back angle (°) |")
    print("| --- | ---: | ---: | --- |")
    spec = dict(pde="stokes", dirichlet=["body=1,0", "outer=0,0"], objective="dissipation")
    best = (math.inf, None)
    reach = 2 * refine_near
    for ratio in ratios:
        path = body if ratio == 1 else ellipse(tmp / f"body{ratio}.msh", ratio, (6, 4), size,
                                               refine_near, "body")
        mesh = load_workpiece(path, "optimize").mesh
        ours = spec_from_options(**spec).make_objective(mesh).value(mesh.points)
        P, _, g = read_groups(path)
        front, back = tip_angles(P, loop_of(g["body"]), reach)
        print(f"| ellipse a/b = {ratio:g} (gmsh) | {ours:.5f} | "
              f"{dissipation_skfem(path, 'body'):.5f} | {front:.0f} / {back:.0f} |")
        best = min(best, (ours, ratio))
    summary, rows = run_cli(body, STOKES, tmp / "body-out")
    out = tmp / "body-out" / "optimized.msh"
    r = body_report(body, out, "body", "outer")
    front, back = tip_angles(r["P"], r["loop"], reach)
    peer = dissipation_skfem(out, "body")
    print(f"| optimized disc ({summary['iterations']} iterations, "
          f"{summary['cpu_seconds']:.1f} s CPU) | {summary['j']:.5f} | {peer:.5f} | "
          f"{front:.0f} / {back:.0f} |")
    print(f"\nBest ellipse a/b = {best[1]:g}: drag {best[0]:.5f}; the optimized body "
          f"{peer:.5f} ({100 * (peer / best[0] - 1):+.2f} %), {2 * r['a']:.3f} × "
          f"{2 * r['b']:.3f} across its second moments; angles measured between the chords "
          f"to the boundary points {reach:g} away along it. Area kept to "
          f"{r['area_change']:.1e} relative, barycenter to {r['barycenter_shift']:.1e} of "
          f"√area, box untouched: {r['outer_untouched']}, smallest area "
          f"{r['min_area']:.2e}, worst AR {r['worst']:.3f} × the start.")
    solve = state_seconds(body, dict(spec, move="body"))
    print(speed(rows, solve, summary))
    metric_factor_choices(body, dict(spec, move="body",
                                     keep="area,barycenter"), solve, 20)
    print()
    iteration_table(rows, 10, solve)


def main_(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--elasticity", action="store_true")
    p.add_argument("--stokes", action="store_true")
    p.add_argument("--size", type=float, default=0.6, help="element size away from the body")
    p.add_argument("--refine-near", type=float, default=0.08, help="element size on the body")
    p.add_argument("--ratios", default="1,2,2.5,2.75,3,3.25,3.5,4,5,6", help="ellipses' a/b (Stokes)")
    p.add_argument("--out", help="keep the meshes here (default: a temporary folder)")
    a = p.parse_args(argv)
    both = not (a.elasticity or a.stokes)
    with tempfile.TemporaryDirectory() as scratch:
        tmp = Path(a.out or scratch)
        tmp.mkdir(parents=True, exist_ok=True)
        if a.elasticity or both:
            elasticity(tmp, a.size, a.refine_near)
        if a.stokes or both:
            stokes(tmp, a.size, a.refine_near, [float(x) for x in a.ratios.split(",")])


if __name__ == "__main__":
    main_()
