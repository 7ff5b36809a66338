"""Surface morphs between random poses pushed into contact: a flap standing on a sheet is
pushed down and sideways twice by ``move_surface`` (contact on, its defaults), and the two
poses are morphed in a few frames with ``mt.morph``. Each morph's frames are checked by
the exact kernel (``kernels/intersections3d.py``), every segment between consecutive
frames by ipctk's own step check (``ipctk.is_step_collision_free``, its defaults, at the
user's scale), and every frame's worst relative quality against the worse end's.

The pushes are drawn as in ``tests/motion/test_surface_morph_contact.py``'s hypothesis
test: the first drops the flap's top by 0.35–0.9, the second by 0–0.9, each shifted by up
to ±0.2 in x and ±0.3 in y (numpy's generator, one seed per run).

Printed: a line per pair (the start the morph took, or its refusal; the checks; seconds),
then per seed the count of clean morphs and of each start, and the seconds' median and
largest.

Run ``python benchmarks/bench_surface_morph_pushes.py [--seeds 23,24] [--pairs 40]
[--frames 5]`` (one BLAS thread: ``OPENBLAS_NUM_THREADS=1``).
"""

from __future__ import annotations

import argparse
import collections
import time

import numpy as np

import meshopt_toolkit as mt
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.surface import aspect_ratios
from meshopt_toolkit.mesh import SurfaceMesh
from meshopt_toolkit.motion.surface.move import move_surface


def flap_on_sheet(n: int = 3, gap: float = 0.3):
    """A sheet z = 0 over [0, 1]² (n × n quads, every vertex a handle at rest) and an
    upright flap (y = 0.5, x in [0.3, 0.7], z in [gap, gap + 1]) whose top row is the other
    handles: points, triangles, handles, the handles' rest positions, the sheet's points."""
    x = np.linspace(0.0, 1.0, n + 1)
    uv = np.stack([a.ravel() for a in np.meshgrid(x, x, indexing="ij")], 1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = (idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(),
                  idx[:-1, 1:].ravel())
    F = np.vstack([np.c_[a, b, c], np.c_[a, c, d]])
    sheet = np.c_[uv, np.zeros(len(uv))]
    flap = np.c_[0.3 + 0.4 * uv[:, 0], np.full(len(uv), 0.5), gap + uv[:, 1]]
    V = np.vstack([sheet, flap])
    top = len(uv) + np.flatnonzero(uv[:, 1] == 1.0)
    handles = np.r_[np.arange(len(uv)), top]
    return V, np.vstack([F, F + len(uv)]), handles, V[handles].copy(), len(uv)


def pushed_pose(drop: float, dx: float, dy: float) -> SurfaceMesh:
    """The flap's top moved by ``(dx, dy, -drop)`` by ``move_surface`` (its result)."""
    V, F, handles, targets, n_sheet = flap_on_sheet()
    targets[n_sheet:] += [dx, dy, -drop]
    return SurfaceMesh(move_surface(V, F, handles, targets).points, F)


def checks(frames: list, F: np.ndarray) -> dict:
    """The exact kernel's intersecting pairs per frame, ipctk's step check over every
    segment, and whether every frame is as healthy as the worse end."""
    import ipctk

    F32 = F.astype(np.int32)
    mesh = ipctk.CollisionMesh(frames[0], ipctk.edges(F32), F32)
    q0 = aspect_ratios(frames[0], F)
    worst = [float((aspect_ratios(Q, F) / q0).min()) for Q in frames]
    return {"exact": [len(self_intersections(Q, F)) for Q in frames],
            "ipctk": all(ipctk.is_step_collision_free(mesh, a, b)
                         for a, b in zip(frames[:-1], frames[1:])),
            "healthy": min(worst) >= min(worst[0], worst[-1]) * (1.0 - 1e-12)}


def run(seed: int, pairs: int, frames: int) -> None:
    rng = np.random.default_rng(seed)
    counts, seconds = collections.Counter(), []
    for i in range(pairs):
        push = (rng.uniform(0.35, 0.9), rng.uniform(-0.2, 0.2), rng.uniform(-0.3, 0.3))
        other = (rng.uniform(0.0, 0.9), rng.uniform(-0.2, 0.2), rng.uniform(-0.3, 0.3))
        source, target = pushed_pose(*push), pushed_pose(*other)
        start = time.perf_counter()
        try:
            res = mt.morph(source, target, frames)
        except mt.MeshoptError as error:
            seconds.append(time.perf_counter() - start)
            counts["refused"] += 1
            print(f"seed {seed} pair {i}: refused ({error})")
            continue
        seconds.append(time.perf_counter() - start)
        points = [np.asarray(f.points, float) for f in res.frames]
        found = checks(points, source.triangles)
        clean = not any(found["exact"]) and found["ipctk"] and found["healthy"]
        counts["clean" if clean else "not clean"] += 1
        counts[f"start {res.morph.initial_path}"] += 1
        print(f"seed {seed} pair {i}: start {res.morph.initial_path}, exact pairs "
              f"{found['exact']}, ipctk's step check {'passes' if found['ipctk'] else 'FAILS'}, "
              f"{'healthy' if found['healthy'] else 'NOT HEALTHY'}, {seconds[-1]:.2f} s")
    print(f"seed {seed}: {counts['clean']} of {pairs} clean in {frames} frames; "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items()) if k != "clean")
          + f"; seconds median {np.median(seconds):.2f}, largest {max(seconds):.2f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="23,24", help="numpy seeds, comma separated")
    ap.add_argument("--pairs", type=int, default=40, help="pairs per seed")
    ap.add_argument("--frames", type=int, default=5, help="frames per morph")
    args = ap.parse_args(argv)
    for seed in (int(s) for s in args.seeds.split(",")):
        run(seed, args.pairs, args.frames)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
