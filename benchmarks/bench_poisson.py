"""Poisson state + adjoint + shape derivative vs scikit-fem assembly + direct solve.

Side by side in one process on the same mesh of (−1, 1)² (the 5-vertex square refined
uniformly; level 9 = 1,048,576 triangles) with the default right-hand side (SPEC §6):

- ours: ``PoissonObjective(mesh)`` (admissibility check, topology), ``value`` (assembly,
  factorization/AMG hierarchy, state solve) and ``derivative`` (adjoint solve with the
  same factorization + element-wise derivative), for ``solver="auto"`` (AMG at this size)
  and ``solver="direct"``;
- scikit-fem: ``MeshTri`` + ``Basis`` + ``asm(laplace)`` + ``asm(load)`` +
  ``solve(*condense(K, b, D=boundary))`` (its default direct solver), state only.

Prints every phase and the ratio ours/scikit-fem (target ≤ 0.25). Timings are the minimum
over ``--repeat`` runs; the machine's other load affects both sides alike.

Run: ``python benchmarks/bench_poisson.py [--level 9] [--repeat 2] [--no-direct]``

SuperLU (after RCM + minimum degree) is much slower than AMG at level 9: compare the
direct path at ``--level 8`` or below, or skip it with ``--no-direct``; ``solver="auto"``
never picks it at these sizes.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from meshopt_toolkit.mesh import PlanarMesh
from meshopt_toolkit.fem.poisson import DEFAULT_RHS, PoissonObjective


def square_mesh(level: int) -> PlanarMesh:
    mesh = PlanarMesh([[-1, -1], [1, -1], [1, 1], [-1, 1], [0, 0]],
                      [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    for _ in range(level):
        mesh = mesh.refine()
    # a fresh mesh without cached topology, as a user would load it
    return PlanarMesh(mesh.points, mesh.triangles)


def r_default(x, y):
    return 2.5 * (x + 0.4 - y**2) ** 2 + x**2 + y**2 - 1


def run_ours(mesh: PlanarMesh, solver: str) -> dict:
    mesh = PlanarMesh(mesh.points, mesh.triangles)  # no topology cached from earlier runs
    t = {}
    t0 = time.perf_counter()
    J = PoissonObjective(mesh, DEFAULT_RHS, solver=solver)
    t1 = time.perf_counter()
    value = J.value(mesh.points)
    t2 = time.perf_counter()
    g = J.derivative(mesh.points)
    t3 = time.perf_counter()
    t["setup (checks, topology)"] = t1 - t0
    t["state (assembly + factor + solve)"] = t2 - t1
    t["adjoint + derivative"] = t3 - t2
    t["total"] = t3 - t0
    t["_value"] = value
    t["_gnorm"] = float(np.abs(g).max())
    t["_method"] = J._cache.solver.method
    return t


def run_skfem(mesh: PlanarMesh) -> dict:
    import skfem
    from skfem.models.poisson import laplace

    t = {}
    t0 = time.perf_counter()
    m = skfem.MeshTri(mesh.points.T.copy(), mesh.triangles.T.copy())
    basis = skfem.Basis(m, skfem.ElementTriP1())

    @skfem.LinearForm
    def load(v, w):
        return r_default(w.x[0], w.x[1]) * v

    K = skfem.asm(laplace, basis)
    b = skfem.asm(load, basis)
    t1 = time.perf_counter()
    y = skfem.solve(*skfem.condense(K, b, D=m.boundary_nodes()))
    t2 = time.perf_counter()
    t["assembly"] = t1 - t0
    t["condense + solve"] = t2 - t1
    t["total"] = t2 - t0
    t["_value"] = float(skfem.asm(skfem.LinearForm(lambda v, w: v), basis) @ y)
    return t


def best(runs: list[dict]) -> dict:
    out = dict(runs[0])
    for k in out:
        if not k.startswith("_"):
            out[k] = min(r[k] for r in runs)
    return out


def show(name: str, t: dict) -> None:
    print(f"{name}")
    for k, v in t.items():
        if not k.startswith("_"):
            print(f"  {k:36s} {v:8.3f} s")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=int, default=9, help="refinements of the 4-triangle square")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--no-direct", action="store_true", help="skip our direct solver")
    args = ap.parse_args(argv)

    mesh = square_mesh(args.level)
    print(f"mesh: {mesh.n_triangles:,} triangles, {mesh.n_vertices:,} vertices")
    sk, auto, direct = [], [], []
    for k in range(args.repeat):  # interleaved, so load changes hit both sides
        auto.append(run_ours(mesh, "auto"))
        print(f"run {k}: ours(auto) {auto[-1]['total']:.2f} s", flush=True)
        sk.append(run_skfem(mesh))
        print(f"run {k}: scikit-fem {sk[-1]['total']:.2f} s", flush=True)
        if not args.no_direct:
            direct.append(run_ours(mesh, "direct"))
            print(f"run {k}: ours(direct) {direct[-1]['total']:.2f} s", flush=True)
    sk, auto = best(sk), best(auto)
    show("scikit-fem (assembly + default direct solve, state only)", sk)
    show(f"ours, solver='auto' -> {auto['_method']} (state + adjoint + derivative)", auto)
    print(f"  j = {auto['_value']:.10f} (scikit-fem, 3-point load: {sk['_value']:.10f})")
    print(f"ratio ours(auto) / scikit-fem = {auto['total'] / sk['total']:.3f}  (target <= 0.25)")
    if direct:
        direct = best(direct)
        show("ours, solver='direct' (state + adjoint + derivative)", direct)
        print(f"ratio ours(direct) / scikit-fem = {direct['total'] / sk['total']:.3f}")
        print(f"  |j_amg − j_direct| = {abs(auto['_value'] - direct['_value']):.2e}")


if __name__ == "__main__":
    main()
