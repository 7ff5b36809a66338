"""Seconds of one 3D Stokes state solve by size, direct against MINRES
(docs/shape-optimization.md, "Stokes solves in 3D").

The drag case of ``bench_shape3d.py`` (a sphere of radius ½ in the 8 × 6 × 6 box, graded
meshes by :func:`meshopt_toolkit.shape.cases.body_in_box`) at a few element sizes; for
each the objective's value (assembly and solve, a fresh solver) by ``solver="direct"``
and ``solver="minres"`` (:mod:`meshopt_toolkit.fem.stokes_solver`), wall and CPU seconds,
and the relative difference of the two drags. Run it once per thread count
(``OMP_NUM_THREADS=1``, ``=2``): BLAS and CHOLMOD read it at start-up.

Usage: OMP_NUM_THREADS=1 python benchmarks/bench_stokes3d_solvers.py
       [--sizes 1,0.15:0.8,0.1:0.7,0.08:0.6,0.07] [--write]
"""

from __future__ import annotations

import argparse
import os
import re
import tempfile
import time
from pathlib import Path

from meshopt_toolkit.io import load_cells
from meshopt_toolkit.shape.cases import body_in_box
from meshopt_toolkit.shape.spec import spec_from_options

SPEC = dict(pde="stokes", dirichlet=["body=1,0,0", "outer=0,0,0"], objective="dissipation",
            move=["body"])
DOC = Path(__file__).resolve().parents[1] / "docs" / "shape-optimization.md"


def solve_once(mesh, solver: str) -> tuple[float, float, float, int]:
    """``(drag, wall seconds, CPU seconds, unknowns)`` of a fresh objective's value."""
    j = spec_from_options(**SPEC).make_objective(mesh, solver=solver)
    t0, c0 = time.perf_counter(), time.process_time()
    value = float(j.value(mesh.points))
    return (value, time.perf_counter() - t0, time.process_time() - c0,
            3 * j.space.n_dofs + mesh.n_vertices)


def run(sizes) -> str:
    work = Path(tempfile.mkdtemp(prefix="bench_stokes3d-"))
    threads = os.environ.get("OMP_NUM_THREADS", "unset")
    lines = ["| tets | unknowns | direct: s (CPU s) | MINRES: s (CPU s) | direct / MINRES, CPU | "
             "drag difference |", "| ---: | ---: | ---: | ---: | ---: | ---: |"]
    for size, body_size in sizes:
        mesh = load_cells(body_in_box(work / f"m_{size}_{body_size}.msh", size, body_size)
                          ).to_tet_mesh("bench")
        jd, wd, cd, unknowns = solve_once(mesh, "direct")
        jm, wm, cm, _ = solve_once(mesh, "minres")
        row = (f"| {mesh.n_tets} | {unknowns} | {wd:.1f} ({cd:.1f}) | {wm:.1f} ({cm:.1f}) | "
               f"{cd / cm:.2f} | {abs(jm - jd) / jd:.1e} |")
        print(row, flush=True)
        lines.append(row)
    return f"OMP_NUM_THREADS={threads}:\n\n" + "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default="1,0.15:0.8,0.1:0.7,0.08:0.6,0.07",
                   type=lambda s: [tuple(float(x) for x in pair.split(","))
                                   for pair in s.split(":")],
                   metavar="SIZE,BODY_SIZE:...", help="element sizes at the box and the body")
    p.add_argument("--write", action="store_true", help="put the table into "
                   "docs/shape-optimization.md (one block per OMP_NUM_THREADS)")
    args = p.parse_args()
    table = run(args.sizes)
    print(table)
    if args.write:
        tag = f"bench_stokes3d_solvers {os.environ.get('OMP_NUM_THREADS', 'unset')}"
        begin, end = f"<!-- {tag}: begin -->", f"<!-- {tag}: end -->"
        text = DOC.read_text(encoding="utf-8")
        text = re.sub(re.escape(begin) + ".*?" + re.escape(end),
                      lambda _: f"{begin}\n{table}\n{end}", text, flags=re.S)
        DOC.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
