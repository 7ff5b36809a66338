"""Where a surface move's ARAP energy lies: ours (``move_surface``) on a contact case with
its options changed, before and after its polish, beside the clean peer (ARAP with
contact, ``_arap_contact.py``) and ours' last increment started from a given result (the
peer's), then polished. Each result's ARAP energy (``_surface_measures.arap_energy``) is split over
the vertices (the directed edges leaving each vertex) and summed over bands of the rest
along one axis, over the handles' rings and over the pressed vertices (those within
``--near`` of a part of the surface more than ``--apart`` from them at rest); beside it ours'
own energy ``½Σ a_t|φ_t|² + ½b Σ c_e(θ_e − θ̄_e)²`` (b = 0.3; no emphasis, barrier or step term).

    python benchmarks/surface_energy_map.py hand --variant bending=0.1 --save DIR
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_surface as bench  # noqa: E402
from _surface_measures import (_edges, arap_vertex_energy, fold_count,  # noqa: E402
                               worst_relative_quality)

CASES = {"hand": ("hand_finger", 1, [0.0, 2.0, 3.0, 3.8, 4.01]),
         "bar-folded": ("bar_folded", 0, [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.01])}


def case_of(name: str) -> tuple:
    """The case, the rest axis of its bands and the bands' edges."""
    maker, axis, edges = CASES[name]
    if name == "hand":
        from _surface_cases_contact import hand_finger
        return hand_finger(), axis, edges
    return getattr(bench, maker)(), axis, edges


def rings(F, seeds, n: int, count: int) -> np.ndarray:
    """Each vertex's ring number from ``seeds`` (0), ``count`` + 1 beyond ``count``."""
    E = _edges(F)
    A = sp.coo_matrix((np.ones(2 * len(E)), (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])),
                      shape=(n, n)).tocsr()
    ring = np.full(n, count + 1)
    front = np.zeros(n, bool)
    front[seeds] = True
    ring[front] = 0
    for k in range(1, count + 1):
        front = (A @ front.astype(float) > 0) & (ring > count)
        ring[front] = k
    return ring


def pressed(V0, V1, near: float, apart: float) -> np.ndarray:
    """Vertices within ``near`` of a vertex that lay more than ``apart`` from them at rest."""
    tree = cKDTree(V1)
    out = np.zeros(len(V1), bool)
    for i, js in enumerate(tree.query_ball_point(V1, near)):
        js = np.asarray(js, int)
        out[i] = bool(np.any(np.linalg.norm(V0[js] - V0[i], axis=1) > apart))
    return out


def ours_energy(case, U, bending: float = 0.3) -> float:
    """Ours' membrane and bending energy of ``U`` (area weights, ``c_t = 1``, no barrier
    and no step term)."""
    from meshopt_toolkit.kernels.surface import areas
    from meshopt_toolkit.motion.surface import move
    from meshopt_toolkit.motion.surface.least_squares import Problem

    V, F = case.V, case.F
    p = Problem(V, F, case.handles, 1.0, bending, move.lumped_mass(V, F))
    p.row_weights = np.sqrt(areas(V, F) / areas(V, F).mean())
    p.phi_ref, p.previous = np.zeros((len(F), 3)), U
    return p.energy(U)


def report(label: str, case, axis: int, edges, U, near: float, apart: float) -> dict:
    """The measures and the energy's split of one result (printed and returned)."""
    e = arap_vertex_energy(case.V, U, case.F)
    total = float(e.sum())
    ring = rings(case.F, case.handles, len(case.V), 4)
    press = pressed(case.V, U, near, apart)
    bands = {f"{a:g}-{b:g}": float(e[(case.V[:, axis] >= a) & (case.V[:, axis] < b)].sum())
             for a, b in zip(edges, edges[1:])}
    out = {"label": label, "quality": worst_relative_quality(case.V, U, case.F, case.handles),
           "folds": fold_count(case.V, U, case.F, case.handles), "arap": total,
           "bands": bands,
           "rings": {str(k): float(e[ring == k].sum()) for k in range(6)},
           "pressed": float(e[press].sum()), "pressed_vertices": int(press.sum()),
           "top1pct": float(np.sort(e)[::-1][: max(1, len(e) // 100)].sum()),
           "ours_energy": ours_energy(case, U)}
    share = " ".join(f"{k}:{v / total:.2f}" for k, v in bands.items())
    rshare = " ".join(f"r{k}:{v / total:.2f}" for k, v in out["rings"].items())
    print(f"{label:<34} q {out['quality']:.3f} folds {out['folds']} ARAP {total:.4g} | "
          f"bands {share} | {rshare} | pressed {out['pressed'] / total:.2f} "
          f"({out['pressed_vertices']} v) | top1% {out['top1pct'] / total:.2f} | "
          f"ours' energy {out['ours_energy']:.4g}", flush=True)
    return out


def ours(case, options: dict, way: str, polish: int):
    """Ours with ``options`` (its polish off), then the polish: (before, after, seconds)."""
    from meshopt_toolkit.motion.engine.contact import contact_term
    from meshopt_toolkit.motion.engine.similarity import HandlePath, handle_groups
    from meshopt_toolkit.motion.surface import move
    from meshopt_toolkit.motion.surface.polish import polish_worst_triangles

    V, F, handles, targets = case.V, case.F, case.handles, case.path(1.0)
    o = move.SurfaceMoveOptions(**{**options, "polish": 0})
    t0 = time.perf_counter()
    if way == "auto":
        result = move.move_surface(V, F, handles, targets, options=o)
    else:
        path = HandlePath(V[handles], targets, handle_groups(handles, F, len(V)),
                          motion="screw")
        if way == "clearer":
            path = move.clearer_half_turns(path, V, F, handles)
        result = move._move_along(V, F, handles, targets, (path, None), 10, True, o, t0)
    before = result.points
    print(f"  {result.iterations} Gauss-Newton iterations, {result.factorizations} "
          f"factorizations, {result.steps} increments", flush=True)
    seconds = time.perf_counter() - t0
    free = np.ones(len(V), bool)
    free[handles] = False
    contact = contact_term(V, F, free, move.lumped_mass(V, F), True)
    after, _ = polish_worst_triangles(V, F, before, handles, iterations=polish,
                                      clear=contact.clear)
    if not contact.embedded(after):
        after = before
    return before, after, seconds


def ours_from(case, start, options: dict, polish: int):
    """Ours' last increment (handles at their targets, ``options``' final budget) from
    ``start``, then its polish: (relaxed, polished)."""
    from meshopt_toolkit.kernels.surface import areas
    from meshopt_toolkit.motion.engine.contact import contact_term
    from meshopt_toolkit.motion.surface import move
    from meshopt_toolkit.motion.surface.least_squares import Problem, solve_increment
    from meshopt_toolkit.motion.surface.polish import polish_worst_triangles

    V, F, handles, targets = case.V, case.F, case.handles, case.path(1.0)
    o = move.SurfaceMoveOptions(**options)
    p = Problem(V, F, handles, o.weight, o.bending, move.lumped_mass(V, F))
    p.contact = contact_term(V, F, p.free, p.mass, True)
    a = np.sqrt(areas(V, F) / areas(V, F).mean())
    size = np.linalg.norm(p.membrane.values(start), axis=1)
    rms = float(np.sqrt(np.mean(size[p.free_triangles] ** 2)))
    p.row_weights = o.weight * a * np.maximum(1.0, size / rms) ** (0.5 * o.emphasis)
    p.previous, p.phi_ref = start, np.zeros((len(F), 3))
    out = solve_increment(p, start, targets, handles, o.final_iterations, o.final_rtol,
                          o.final_stall)
    relaxed = start if out is None else out[0]
    after, _ = polish_worst_triangles(V, F, relaxed, handles, iterations=polish,
                                      clear=p.contact.clear)
    return relaxed, (after if p.contact.embedded(after) else relaxed)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("case", choices=sorted(CASES))
    ap.add_argument("--variant", default="", help="SurfaceMoveOptions fields, a=1,b=2")
    ap.add_argument("--way", default="auto", choices=("auto", "fit", "clearer"),
                    help="the handles' half turn: move_surface's choice, the fit's, the clearer")
    ap.add_argument("--polish", type=int, default=100)
    ap.add_argument("--load", type=Path, help="an .npz of saved results to report only")
    ap.add_argument("--peer", action="store_true", help="the clean peer instead of ours")
    ap.add_argument("--start", type=Path,
                    help="an .npz whose 'peer' (or 'after') result starts ours' last increment")
    ap.add_argument("--save", type=Path, help="folder for the results (.npz)")
    ap.add_argument("--near", type=float, default=0.15)
    ap.add_argument("--apart", type=float, default=0.6)
    args = ap.parse_args(argv)
    case, axis, edges = case_of(args.case)
    results = {}
    if args.load:
        results = dict(np.load(args.load))
    elif args.start:
        saved = np.load(args.start)
        start = saved["peer"] if "peer" in saved else saved["after"]
        options = {k: json.loads(v) for k, v in
                   (kv.split("=") for kv in args.variant.split(",") if kv)}
        results["start"] = start
        results["relaxed"], results["polished"] = ours_from(case, start, options, args.polish)
    elif args.peer:
        from _arap_contact import arap_contact
        t0 = time.perf_counter()
        r = arap_contact(case.V, case.F, case.handles, case.path, steps=10)
        results["peer"] = r.points
        print(f"peer {time.perf_counter() - t0:.1f} s", flush=True)
    else:
        options = {k: json.loads(v) for k, v in
                   (kv.split("=") for kv in args.variant.split(",") if kv)}
        before, after, seconds = ours(case, options, args.way, args.polish)
        print(f"ours {args.variant or 'defaults'} way {args.way}: {seconds:.1f} s", flush=True)
        results["before"], results["after"] = before, after
    out = {k: report(f"{args.case} {args.variant or args.way} {k}", case, axis, edges, U,
                     args.near, args.apart) for k, U in results.items()}
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
        stem = f"{args.case}_{'peer' if args.peer else (args.variant or 'defaults')}_{args.way}"
        stem += f"_from_{args.start.stem}" if args.start else ""
        if not args.load:
            np.savez(args.save / f"{stem}.npz", **results)
        (args.save / f"{stem}.json").write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
