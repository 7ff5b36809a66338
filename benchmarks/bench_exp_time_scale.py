"""Why the exponential map's step count grows with refinement: the geodesic's
own time scale, measured, and an A-stable implicit method on the same geodesic.

Set-up of ``bench_scale.py``: disc_13586 and its uniform refinements, f2 with β = (10, 1,
0, 0.001·N), velocity ``0.3·(sin πy, cos πx)``, t ∈ [0, 1]. Per size it prints

- the default ``exp_map`` (DOP853, rtol 1e-6): steps (rejected) and the step it would
  take next at t = 1;
- the geodesic's time scale: from a tight solution (rtol 1e-9) sampled at 501 times,
  ``max|V^(k+1)| / max|V^(k)|`` over t ∈ [0.75, 1] for k = 1, 2, 3 (finite differences of
  the velocity; each ratio is a rate 1/τ at which the solution itself varies). An accurate
  integrator of order p takes steps of about ``τ·rtol^(1/(p+1))`` however stable it is;
- with ``--implicit``: scipy's Radau IIA (order 5, A-stable, so not limited by the stiff
  modes' stability bound) at rtol 1e-6 with the sparse Jacobian ``[[0, I], [−κ∇²f, 0]]``,
  ``κ = Vᵀ∇²f V / (1 + |∇f|²)`` (``∇²f`` by finite differences of ``∇f`` over a
  distance-2 colouring of the vertices): steps, the median of its last five full steps,
  time. Ten minutes at 107k.

If the steps were limited by stability alone, the implicit method's step count would not
grow with N; measured, it grows like DOP853's, and the ratios show why: the exact geodesic
varies faster on finer meshes (its boundary triangles stretch more, see docs/design-notes.md
"Performance at scale").

Usage: ``python benchmarks/bench_exp_time_scale.py [--max-triangles 110000] [--implicit]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp

import meshopt_toolkit as mt
from meshopt_toolkit.penalties import QualityPenalty
from meshopt_toolkit.riemannian.field import GeodesicField
from meshopt_toolkit.riemannian.geodesics import geodesic


def problem(refinements: int):
    mesh = mt.load(mt.data_path("disc_13586.msh")).as_planar()
    for _ in range(refinements):
        mesh = mesh.refine()
    pen = QualityPenalty(mesh, beta=(10, 1, 0, 0.001 * mesh.n_vertices))
    Q = mesh.points
    V = 0.3 * np.stack([np.sin(np.pi * Q[:, 1]), np.cos(np.pi * Q[:, 0])], axis=1)
    return mesh, pen, Q, V


def derivative_ratios(pen, Q, V, samples: int = 501) -> list[float]:
    """``max|V^(k+1)| / max|V^(k)|`` over t ∈ [0.75, 1], k = 1, 2, 3 (finite differences
    of ``samples`` velocities, spacing 1/2000)."""
    ts = np.linspace(0.75, 1.0, samples)
    res = geodesic(pen, Q, V, 1.0, times=ts, rtol=1e-9, monitor=False)
    d = [res.velocities.reshape(samples, -1)]
    for _ in range(4):
        d.append(np.diff(d[-1], axis=0) / (ts[1] - ts[0]))
    m = [float(np.abs(x).max()) for x in d]
    return [m[k + 1] / m[k] for k in (1, 2, 3)]


def hessian_by_colouring(mesh, pen):
    """``Q ↦ (∇²f(Q), ∇f(Q))``, the Hessian (sparse, vertex-neighbour pattern) from
    finite differences of ∇f along the columns of one colour of a distance-2 colouring."""
    n = mesh.n_vertices
    tri = mesh.triangles
    rows = tri[:, [0, 1, 2, 1, 2, 0]].ravel()
    cols = tri[:, [1, 2, 0, 0, 1, 2]].ravel()
    adj = (sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)).tocsr()
           + sp.identity(n, format="csr"))
    two = (adj @ adj).tocsr()
    colour = -np.ones(n, int)
    for i in range(n):
        taken = colour[two.indices[two.indptr[i]:two.indptr[i + 1]]]
        free = np.setdiff1d(np.arange(len(taken) + 1), taken[taken >= 0])
        colour[i] = free[0]
    pattern = sp.kron(adj, np.ones((2, 2))).tocoo()
    pr, pc = pattern.row, pattern.col
    groups = [(k, d, np.flatnonzero((colour[pc // 2] == k) & (pc % 2 == d)))
              for k in range(colour.max() + 1) for d in range(2)]

    def hessian(q):
        g0 = pen.gradient(q).ravel()
        vals = np.empty(len(pr))
        eps = 1e-7
        for k, d, sel in groups:
            dq = np.zeros((n, 2))
            dq[colour == k, d] = eps
            vals[sel] = ((pen.gradient(q + dq).ravel() - g0) / eps)[pr[sel]]
        H = sp.csr_matrix((vals, (pr, pc)), shape=(2 * n, 2 * n))
        return 0.5 * (H + H.T), g0

    return hessian


def implicit(mesh, pen, Q, V) -> tuple[int, float, float]:
    """Radau IIA at rtol 1e-6: (steps, median of its last five full steps, seconds)."""
    from scipy.integrate import solve_ivp

    field = GeodesicField(pen)
    hessian = hessian_by_colouring(mesh, pen)
    n = Q.size
    eye = sp.identity(n, format="csr")

    def rhs(_t, y):
        q, v = y[:n].reshape(Q.shape), y[n:].reshape(Q.shape)
        if not field.admissible(q):
            return np.full_like(y, np.nan)
        return np.concatenate([v.ravel(), field.acceleration(q, v)[0].ravel()])

    def jac(_t, y):
        H, g = hessian(y[:n].reshape(Q.shape))
        v = y[n:]
        kappa = float(v @ (H @ v)) / (1.0 + g @ g)
        return sp.bmat([[sp.csr_matrix((n, n)), eye], [-kappa * H, None]], format="csc")

    scale = max(np.abs(Q).max(), np.abs(V).max())
    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, 1.0), np.concatenate([Q.ravel(), V.ravel()]), method="Radau",
                    jac=jac, rtol=1e-6, atol=1e-6 * scale)
    if not sol.success:
        raise RuntimeError(sol.message)
    steps = np.diff(sol.t)
    return len(steps), float(np.median(steps[-6:-1])), time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-triangles", type=int, default=110_000)
    ap.add_argument("--implicit", action="store_true", help="also run Radau IIA (minutes)")
    args = ap.parse_args()
    print(f"{'triangles':>10} {'DOP853 steps (rej.)':>19} {'next h':>8} "
          f"{'|V^2|/|V^1|':>12} {'|V^3|/|V^2|':>12} {'|V^4|/|V^3|':>12}"
          + (f" {'Radau steps':>12} {'late h':>8} {'s':>6}" if args.implicit else ""))
    for refinements in range(4):
        mesh, pen, Q, V = problem(refinements)
        if mesh.n_triangles > args.max_triangles:
            break
        res = geodesic(pen, Q, V, 1.0)
        ratios = derivative_ratios(pen, Q, V)
        steps = f"{res.n_steps} ({res.n_rejected})"
        line = (f"{mesh.n_triangles:>10} {steps:>19} {res.last_step:>8.4f} "
                + " ".join(f"{r:>12.0f}" for r in ratios))
        if args.implicit:
            steps, h, sec = implicit(mesh, pen, Q, V)
            line += f" {steps:>12} {h:>8.4f} {sec:>6.0f}"
        print(line, flush=True)


if __name__ == "__main__":
    main()
