"""Benchmark: our file I/O against meshio on a 1,000,000-triangle planar mesh.

Side by side in one process, baseline and ours interleaved, median of ``--repeat`` runs:

* read only: ``meshio.gmsh.read(msh)``  vs  ``load(msh)`` (reader + mesh validation);
* info: meshio's own read + write of the same .msh file (gmsh 4.1 binary)  vs
  :func:`meshopt_toolkit.cli.info.mesh_info` (``load`` + ``check_mesh`` +
  ``quality_summary``: exactly what ``meshopt info`` does per file);
* round trip:  meshio read .msh → write .vtu → read .vtu → write .msh  vs  the same with
  ``load``/``save`` (atomic writes included).

Prints the times and the ratios ours / meshio (target ≤ 1.5), and where the time of
``info`` goes (load, quality summary, check on a fresh mesh).
Run: ``python benchmarks/bench_io.py [--n 708] [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import meshio
import meshio.gmsh
import meshio.vtu
import numpy as np

from meshopt_toolkit.cli.info import mesh_info
from meshopt_toolkit.kernels.triangles import quality_summary
from meshopt_toolkit.io import load, save
from meshopt_toolkit.mesh import PlanarMesh, check_mesh


def grid(n: int) -> PlanarMesh:
    """n×n squares of [0, 1]², two triangles each (2 n² triangles), slightly jittered."""
    x = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(x, x)
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    inner = (pts > 0).all(1) & (pts < 1).all(1)
    pts[inner] += 0.2 / n * np.random.default_rng(0).uniform(-1, 1, (inner.sum(), 2))
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return PlanarMesh(pts, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]))


def medians(fns, repeat: int) -> list[float]:
    """Median time of each function, the functions run in turn ``repeat`` times."""
    times = [[] for _ in fns]
    for _ in range(repeat):
        for fn, ts in zip(fns, times):
            t = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t)
    return [float(np.median(ts)) for ts in times]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=708, help="grid size (2 n^2 triangles)")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    mesh = grid(args.n)
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        msh = d / "big.msh"
        save(mesh, msh)
        print(f"mesh: {mesh.n_vertices} vertices, {mesh.n_triangles} triangles, "
              f".msh {msh.stat().st_size / 1e6:.1f} MB (gmsh 4.1 binary)")

        def meshio_read():
            meshio.gmsh.read(msh)

        def meshio_read_write():
            # geometry only: meshio cannot write the gmsh data it reads back into a 4.1
            # file (KeyError 'gmsh:physical')
            m = meshio.gmsh.read(msh)
            meshio.gmsh.write(d / "m.msh", meshio.Mesh(m.points, m.cells), binary=True)

        def ours_info():
            info = mesh_info(msh)
            assert info["admissible"]

        def meshio_roundtrip():
            m = meshio.gmsh.read(msh)
            meshio.vtu.write(d / "a.vtu", meshio.Mesh(m.points, m.cells))
            m2 = meshio.vtu.read(d / "a.vtu")
            meshio.gmsh.write(d / "a.msh", meshio.Mesh(m2.points, m2.cells))

        def ours_roundtrip():
            m = load(msh)
            save(m, d / "b.vtu")
            m2 = load(d / "b.vtu")
            save(m2, d / "b.msh")

        rows = []
        for name, base, ours in [("read only", meshio_read, lambda: load(msh)),
                                 ("info", meshio_read_write, ours_info),
                                 ("msh->vtu->msh", meshio_roundtrip, ours_roundtrip)]:
            tb, to = medians([base, ours], args.repeat)
            rows.append((name, tb, to))
        # parts of "info", to see where the time goes
        m = load(msh)
        t_load, t_check, t_q = medians(
            [lambda: load(msh),
             lambda: check_mesh(PlanarMesh(m.points, m.triangles)),
             lambda: quality_summary(m.points, m.triangles)],
            args.repeat,
        )
    print(f"{'task':<16}{'meshio s':>10}{'ours s':>10}{'ratio':>8}")
    for name, tb, to in rows:
        print(f"{name:<16}{tb:>10.3f}{to:>10.3f}{to / tb:>8.2f}")
    print(f"info parts: load {t_load:.3f} s, check_mesh {t_check:.3f} s, "
          f"quality_summary {t_q:.3f} s")


if __name__ == "__main__":
    main()
