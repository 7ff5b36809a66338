"""The benchmark tables' cases of ours in two git revisions, side by side.

Each revision is checked out into a temporary ``git worktree`` (the working tree itself
for ``WORKTREE``), and each selected case runs in both, alternating old and new
(old, new, then new, old, ...), every run in a process of its own with ``PYTHONPATH`` set
to that tree and one BLAS/OpenMP thread. The case is built by that tree's benchmark script
(``benchmarks/bench_*.py``) and only ours' call is timed; the fastest of ``--repeats`` runs
is the time. Printed: one markdown table per benchmark page with the worst quality in
both revisions, whether the new one is equal or better (to 1e-9 relative), both times,
their ratio and whether it is within 1.2×, and the other measures the page prints where
they differ.

Usage: ``python benchmarks/compare_revisions.py [OLD [NEW]] [--all | --page-sizes]
[--cases WORD ...] [--repeats 2] [--markdown FILE] [--list]`` (defaults: ``6b9c044`` and
``WORKTREE``); ``--page-sizes``: only the 3D cases at the mesh sizes their pages print.
"""

from __future__ import annotations

import argparse
import inspect
import itertools
import json
import math
import os
import platform
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
WORKTREE = "WORKTREE"
RTOL = 1e-9  # equal or better: relative tolerance on the worst quality
TIME_RATIO = 1.2  # the new time within this factor of the old
THREADS = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


@dataclass
class Case:
    """One row of a benchmark table: ``runner(**kwargs)`` runs in a worker process."""

    page: str
    table: str
    name: str
    runner: str
    kwargs: dict = field(default_factory=dict)
    default: bool = True
    why_not: str = ""  # why a case is not in the default set
    full: bool = False  # a 3D case at the mesh size its page prints (``--page-sizes``)


# ---------------------------------------------------------------- runners (in a worker)

_CPU = [0.0]  # the CPU seconds of the last timed call (all threads: robust to the load)


def _timed(fn, *args, **kwargs):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn(*args, **kwargs)
    _CPU[0] = time.process_time() - c0
    return out, time.perf_counter() - t0


def _accepted(fn, **options) -> dict:
    """The ``options`` that ``fn``'s signature takes (a keyword missing in one revision)."""
    params = inspect.signature(fn).parameters
    return {k: v for k, v in options.items() if k in params}


def run_move(index: int, more: bool = False, size: float = 0.05) -> dict:
    import bench_move as b

    _, mesh, handles, targets = next(itertools.islice(
        (b.more_cases if more else b.cases)(size), index, None))
    (row, why), _ = _timed(b.measure, b.ours, mesh, handles, targets)
    if row is None:
        raise RuntimeError(why)
    ar, lam, inv, err, sec, _ = row
    return {"worst": ar, "seconds": sec,
            "measures": {"mean Λ": lam, "inverted": inv, "handle err": err}}


def run_morph(index: int, more: bool = False) -> dict:
    import bench_morph as b
    import numpy as np

    import meshopt_toolkit as mt

    _, src, tgt = next(itertools.islice((b.more_pairs if more else b.pairs)(), index, None))
    res, sec = _timed(mt.morph, src, tgt, frames=9)
    worst = lambda s: float(np.nanmin(s.min_aspect_ratio))  # noqa: E731
    return {"worst": worst(res.stats), "seconds": sec,
            "measures": {"inverted": int(np.max(res.stats.inverted)), "linear": worst(res.linear),
                         "ARAP": worst(res.rigid), "iterations": res.nit, "status": res.status}}


def _eta(x, tets, handles, at_end) -> dict:
    import numpy as np
    from meshopt_toolkit.kernels.tetrahedra import mean_ratios

    eta = mean_ratios(np.asarray(x), tets)
    return {"worst": float(np.nanmin(eta)),
            "measures": {"inverted": int((~(eta > 0)).sum()),
                         "handle err": float(np.abs(np.asarray(x)[handles] - at_end).max())}}


def run_move3d(name: str, box_size: float = 0.115, channel_size: float = 0.06) -> dict:
    import bench_move3d as b

    _, domain, handles, path = next(b.cases(box_size, channel_size, [name]))
    x, sec = _timed(b.ours, domain.points, domain.tets, handles, path)
    return {**_eta(x, domain.tets, handles, path(1.0)), "seconds": sec}


def run_tet_sweep(name: str, size: float = 0.11) -> dict:
    import bench_tet_sweep as b

    _, domain, handles, path = next(b.cases(size, [name]))
    x, sec = _timed(b.ours, domain.points, domain.tets, handles, path)
    return {**_eta(x, domain.tets, handles, path(1.0)), "seconds": sec}


def run_tet_move(size: float = 0.12, degrees: float = 90.0) -> dict:
    import bench_tet_move as b

    P, T = b.box_with_hole(size)
    handles, at = b.turn_case(P, T, degrees, 0.0)
    move = b.move_tets
    res, sec = _timed(move, P, T, handles, at(1.0), **_accepted(move, steps=4, quality_rounds=4))
    return {**_eta(res.points, T, handles, at(1.0)), "seconds": sec}


def run_tet_morph(size: float = 0.12, degrees: float = 90.0) -> dict:
    import bench_tet_morph as b
    import numpy as np

    P, T = b.box_with_hole(size)
    handles, at = b.turn_case(P, T, degrees, 0.0)
    Q = np.asarray(b.move_tets(P, T, handles, at(1.0)).points)
    res, sec = _timed(b.morph_tets, b.TetMesh(P, T), b.TetMesh(Q, T), 9)
    inv, worst = b.frame_quality(res.points, T)
    return {"worst": worst, "seconds": sec, "measures": {
        "inverted": inv, "target worst η": float(b.mean_ratios(Q, T).min()),
        "iterations": res.nit, "status": res.status}}


def _first(name: str, *modules: str):
    """``name`` from the first of ``modules`` the revision has (a module that moved)."""
    import importlib

    for module in modules:
        try:
            return getattr(importlib.import_module(module), name)
        except ModuleNotFoundError:
            continue
    raise ModuleNotFoundError(f"{name}: in none of {modules}")


def _surface_ours(V, F, handles, targets):
    """``move_surface`` as the tables above the contact section run it (no contact)."""
    move_surface = _first("move_surface", "meshopt_toolkit.motion.surface.move",
                          "meshopt_toolkit.motion.surface_move")
    return move_surface(V, F, handles, targets, **_accepted(move_surface, contact=False))


def _surface_cases(b) -> dict:
    cases = {}
    for table in ("CASES", "UNSEEN", "UNSEEN2", "CONTACT"):
        cases.update(getattr(b, table, {}))
    try:
        from _surface_cases3 import UNSEEN3
        cases.update(UNSEEN3)
    except ImportError:
        pass
    return cases


def run_surface(name: str) -> dict:
    import bench_surface as b
    import numpy as np

    case = _surface_cases(b)[name]()
    res, sec = _timed(_surface_ours, case.V, case.F, case.handles, case.path(1.0))
    r = b.measure(case, np.asarray(res.points), sec)
    return {"worst": r.pop("quality"), "seconds": r.pop("seconds"), "measures": r}


def run_surface_morph(pair: str, method: str = "ours", frames: int = 9) -> dict:
    import bench_surface_morph as m
    import numpy as np

    case_name, maker = m.PAIRS[pair]
    if maker == "ours":
        case = _surface_cases(m.bench)[case_name]()
        V0, F = case.V, case.F
        V1 = np.asarray(_surface_ours(V0, F, case.handles, case.path(1.0)).points, float)
    else:
        V0, F, V1 = m.pose(case_name, maker)
    run = m.METHODS[method]
    if method in ("ours", "ours, energy stop"):  # without contact, as the previous main
        morph_surface = _first("morph_surface", "meshopt_toolkit.motion.surface.morph",
                               "meshopt_toolkit.motion.surface_morph")
        options = _accepted(morph_surface, contact=False)
        if method != "ours":
            options["stop_when_healthy"] = False
        run = lambda V0, V1, F, t: m.ours(V0, V1, F, t, **options)  # noqa: E731
    path, sec = _timed(run, V0, V1, F, np.linspace(0.0, 1.0, frames))
    measures = {"folds": sum(m.fold_count(V0, X, F) for X in path)}
    try:
        measures["E"] = m.path_energy(V0, V1, F, path)
    except (ImportError, AttributeError) as exc:
        measures["E"] = f"n/a ({type(exc).__name__})"
    return {"worst": min(m.worst_relative_quality(V0, X, F, []) for X in path),
            "seconds": sec, "measures": measures}


RUNNERS = {f.__name__: f for f in (run_move, run_morph, run_move3d, run_tet_sweep,
                                   run_tet_move, run_tet_morph, run_surface,
                                   run_surface_morph)}


def worker(tree: str, runner: str, kwargs: str) -> None:
    """Run one case in ``tree`` and print its result as the last line of stdout (JSON)."""
    own = str(Path(__file__).resolve().parent)
    sys.path[:] = [str(Path(tree) / "benchmarks"), tree] + [p for p in sys.path if p != own]
    import meshopt_toolkit

    where = Path(meshopt_toolkit.__file__).resolve()
    if Path(tree).resolve() not in where.parents:
        raise SystemExit(f"meshopt_toolkit imported from {where}, not from {tree}")
    out = {**RUNNERS[runner](**json.loads(kwargs)), "cpu": _CPU[0]}
    print("\n" + json.dumps(out, default=float))


# ---------------------------------------------------------------- cases

_DOC, _3D, _SURF = "docs/benchmarks.md", "docs/benchmarks-3d.md", "docs/benchmarks-surface.md"
_MOVE = ["annulus, inner circle turned 45°", "annulus, turned 90°", "annulus, turned 180°",
         "channel, cylinder pushed down 0.2", "channel, pushed down 0.3"]
_MORE = ["disc_2198, sheared", "disc_2198, 4 × 0.25 ellipse", "disc_2198, star",
         "annulus, hole scaled 2.5×", "annulus, hole shifted 0.4",
         "channel, cylinder moved 1.5 along", "channel, cylinder 0.01 from the wall"]
_MORPH = ["annulus, 90° log twist", "annulus, 180° turn (move)", "disc_146, 225° twist",
          "disc_2198, 225° twist", "channel, cylinder −0.2 (move)", "disc_146, turned 90° ×1.5"]
_BOX3D = ["box, sphere turned 90°", "box, sphere turned 180°", "box, hole grown r 0.35 → 0.63"]
_CHANNEL3D = ["channel, sphere pushed down 0.3 (0.05 from the floor)",
              "channel, sphere moved 1.5 along"]
_SWEEP = ["box, ellipsoidal hole", "box, two spheres", "channel, cylinder moved 0.8",
          "channel, sphere pushed 0.25"]
_SURFACE = {  # case: in the default set (the armadillo's take a minute each)
    "bunny": True, "bar": True, "armadillo": False, "spot-head": False, "spot-leg": False,
    "bob-head": False, "blub-tail": False, "bar-bent": False, "plate-bent": True,
    "bunny-front-ear": False, "bob-tail": False, "armadillo-tail": False,
    "tube-twist": False, "tube-bent": False, "plate-twist": False, "strip-hole": True,
    "disc-bump": False, "armadillo-head": False, "spot-nod": False, "dome-twist": False,
    "l-plate-roll": True, "cylinder-bent": False, "torus-tilt": False}
_SLOW = "a few seconds but left out to keep the default run within ~15 minutes"
_MORPH_METHODS = ["ours' start, no steps", "ours' start", "ours", "ours, energy stop"]


def all_cases() -> list[Case]:
    """Every case, the default set marked (reduced 3D sizes in it: the pages' take minutes)."""
    out = [Case(_DOC, "Mesh motion", n, "run_move", {"index": i}) for i, n in enumerate(_MOVE)]
    out += [Case(_DOC, "Mesh motion, --more", n, "run_move", {"index": i, "more": True},
                 i == 4, _SLOW) for i, n in enumerate(_MORE)]
    out += [Case(_DOC, "Morphing", n, "run_morph", {"index": i}, i != 1,
                 "the target is move's 180° turn first") for i, n in enumerate(_MORPH)]
    out += [Case(_DOC, "Morphing, --more", n, "run_morph", {"index": i, "more": True}, False,
                 "each pair's target is a move first: 2–8 s per run before the morph")
            for i, n in enumerate(_MORE)]
    for small in (True, False):
        tag, box = (" (box size 0.25)", 0.25) if small else ("", 0.115)
        why = "" if small else "tens of seconds to minutes per run (the page's mesh sizes)"
        out += [Case(_3D, "bench_move3d" + tag, n, "run_move3d", {"name": n, "box_size": box},
                     small and "180" not in n, why or _SLOW, not small) for n in _BOX3D]
        out += [Case(_3D, "bench_move3d" + tag.replace("box size 0.25", "channel size 0.15"),
                     n, "run_move3d",
                     {"name": n, "channel_size": 0.15 if small else 0.06}, False,
                     "1.5–4 minutes per run at the page's size" if not small else
                     "still 10 s and more per run at channel size 0.15", not small)
                for n in _CHANNEL3D]
        out += [Case(_3D, "bench_tet_sweep" + tag, n, "run_tet_sweep",
                     {"name": n, "size": box if small else 0.11}, small and "sphere" in n, why
                     or "the slower two of the four", not small) for n in _SWEEP]
        out += [Case(_3D, "bench_tet_move" + tag.replace(")", "; page 0.12)"),
                     "box, sphere turned 90°", "run_tet_move", {"size": box if small else 0.12},
                     False, why or "the case of bench_move3d's first row, the finish's options",
                     not small)]
        out += [Case(_3D, "bench_tet_morph" + tag, f"box, sphere turned {d}°", "run_tet_morph",
                     {"size": box if small else 0.12, "degrees": d}, small and d == 90, why or
                     "the slower of the two", not small) for d in (90, 150)]
    out += [Case(_3D, "bench_tet_sweep (size 0.06)", n, "run_tet_sweep", {"name": n, "size": 0.06},
                 False, "the page's 150–167k tets: half a minute to 6 minutes per run", True)
            for n in _SWEEP]
    out += [Case("docs/move-3d.md", "bench_tet_move (size 0.0595)", "box, sphere turned 90°",
                 "run_tet_move", {"size": 0.0595}, False,
                 "the page's 174k tets: 3–5 minutes per run", True)]
    out += [Case(_SURF, "bench_surface (contact=False)", n, "run_surface", {"name": n}, d,
                 "" if d else ("about a minute per run" if "armadillo" in n else _SLOW))
            for n, d in _SURFACE.items()]
    for pair in ("bar-ours", "bar-libigl", "bunny-ours", "bunny-libigl", "armadillo-libigl"):
        out += [Case(_SURF, "bench_surface_morph", f"{pair}: {meth}", "run_surface_morph",
                     {"pair": pair, "method": meth},
                     "libigl" in pair and "armadillo" not in pair and (
                         meth == "ours" or (meth == "ours, energy stop" and "bar" in pair)),
                     "the pose by move_surface first" if pair.endswith("ours") else
                     "the pose by libigl's ARAP first, a minute" if "armadillo" in pair else _SLOW)
                for meth in _MORPH_METHODS]
    return out


# ---------------------------------------------------------------- comparison

def equal_or_better(old, new, rtol: float = RTOL) -> bool:
    """Whether the worst quality ``new`` is at least ``old`` to ``rtol`` relative (a run
    that failed, ``None``, is worse than any result and equal to another failure)."""
    if old is None or new is None:
        return new is not None or old is None
    if math.isnan(old) or math.isnan(new):
        return math.isnan(old)
    return new >= old - rtol * max(abs(old), abs(new))


def within(old: float | None, new: float | None, factor: float = TIME_RATIO) -> bool:
    """Whether the new time is within ``factor`` times the old (no time: not within)."""
    return old is not None and new is not None and new <= factor * old


def _same(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return a == b or abs(a - b) <= RTOL * max(abs(a), abs(b))
    return a == b


def _fmt(x) -> str:
    if x is None:
        return "failed"
    if isinstance(x, float):
        return f"{x:.6g}" if x == 0 or 1e-3 <= abs(x) < 1e6 else f"{x:.3e}"
    return str(x)


def summarize(runs: list[dict]) -> dict:
    """The worst quality over ``runs`` (the same in each where the code is deterministic),
    the fastest time, the last run's other measures and the first error."""
    ok = [r for r in runs if "error" not in r]
    if not ok:
        return {"worst": None, "seconds": None, "cpu": None, "measures": {},
                "error": runs[0]["error"]}
    worsts = [r["worst"] for r in ok]
    return {"worst": min(worsts), "seconds": min(r["seconds"] for r in ok),
            "cpu": min(r["cpu"] for r in ok),
            "measures": ok[-1]["measures"], "varies": len(set(worsts)) > 1}


def row(case: Case, old: dict, new: dict) -> dict:
    good = equal_or_better(old["worst"], new["worst"])
    fast = within(old["seconds"], new["seconds"])
    ratio = new["seconds"] / old["seconds"] if old["seconds"] and new["seconds"] else None
    cpu = new["cpu"] / old["cpu"] if old["cpu"] and new["cpu"] else None
    other = [f"{k} {_fmt(old['measures'][k])} → {_fmt(v)}" for k, v in new["measures"].items()
             if k in old["measures"] and not _same(old["measures"][k], v)]
    if None not in (old["worst"], new["worst"]) and not _same(old["worst"], new["worst"]):
        other.insert(0, f"worst {new['worst'] - old['worst']:+.2e}")
    for side, r in (("old", old), ("new", new)):
        if r.get("error"):
            other.append(f"{side}: {r['error'][:80]}")
        if r.get("varies"):
            other.append(f"{side}: worst differs between repeats")
    return {"table": case.table, "case": case.name, "old": old, "new": new, "good": good,
            "fast": fast, "ratio": ratio, "cpu": cpu, "other": "; ".join(other) or "same"}


def markdown_table(rows: list[dict]) -> str:
    lines = ["| table | case | worst old | worst new | equal or better | s old | s new | "
             "new / old | within 1.2× | CPU new / old | other measures (old → new) |",
             "| --- | --- | ---: | ---: | --- | ---: | ---: | ---: | --- | ---: | --- |"]
    sec = lambda x: "–" if x is None else f"{x:.2f}"  # noqa: E731
    for r in rows:
        ratio, cpu = ("–" if x is None else f"{x:.2f}" for x in (r["ratio"], r["cpu"]))
        lines.append(
            f"| {r['table']} | {r['case']} | {_fmt(r['old']['worst'])} | "
            f"{_fmt(r['new']['worst'])} | {'yes' if r['good'] else '**no**'} | "
            f"{sec(r['old']['seconds'])} | {sec(r['new']['seconds'])} | {ratio} | "
            f"{'yes' if r['fast'] else '**no**'} | {cpu} | {r['other']} |")
    return "\n".join(lines)


# ---------------------------------------------------------------- driver

def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                          check=True).stdout.strip()


def describe(rev: str) -> str:
    if rev == WORKTREE:
        dirty = " + uncommitted changes" if _git("status", "--porcelain", "--untracked-files=no") else ""
        return f"the working tree ({_git('rev-parse', '--short', 'HEAD')}{dirty})"
    return f"{rev} ({_git('rev-parse', '--short', rev + '^{commit}')})"


def checkout(rev: str, into: Path) -> Path:
    """The tree of ``rev``: the working tree itself, or a detached ``git worktree``."""
    if rev == WORKTREE:
        return REPO
    _git("worktree", "add", "--detach", str(into), rev)
    return into


def run_once(tree: Path, case: Case, timeout: float) -> dict:
    env = {**os.environ, **THREADS, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"}
    command = [sys.executable, str(Path(__file__).resolve()), "--worker", str(tree),
               case.runner, json.dumps(case.kwargs)]
    try:
        out = subprocess.run(command, cwd=tree, env=env, capture_output=True, text=True,
                             timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"over {timeout:.0f} s"}
    if out.returncode != 0:
        last = (out.stderr.strip().splitlines() or ["no output"])[-1]
        return {"error": f"exit {out.returncode}: {last}"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def compare(trees: dict, cases: list[Case], repeats: int, timeout: float, log) -> list[dict]:
    rows = []
    for case in cases:
        runs = {"old": [], "new": []}
        for k in range(repeats):  # old, new, new, old, ...: drift in the load cancels
            for side in (("old", "new") if k % 2 == 0 else ("new", "old")):
                runs[side].append(run_once(trees[side], case, timeout))
        r = row(case, summarize(runs["old"]), summarize(runs["new"]))
        log(f"{case.page} | {r['table']} | {r['case']}: worst {_fmt(r['old']['worst'])} → "
            f"{_fmt(r['new']['worst'])}, {r['old']['seconds']} → {r['new']['seconds']} s, "
            f"CPU ×{r['cpu']}; {r['other']}")
        rows.append(r)
    return rows


def report(rows: list[dict], cases: list[Case], header: str, selected_all: bool) -> str:
    out = [header]
    for page in dict.fromkeys(c.page for c in cases):
        out += ["", f"## {page}", "", markdown_table([r for r, c in zip(rows, cases)
                                                      if c.page == page])]
        if not selected_all:
            left: dict = {}
            for c in all_cases():
                if c.page == page and not c.default:
                    left.setdefault((c.table, c.why_not), []).append(c.name)
            if left:
                out += ["", "Left out of the default set (`--all` runs them):", ""]
                out += [f"- {t}: {'; '.join(names)} ({why})" for (t, why), names in left.items()]
    bad = [r for r in rows if not (r["good"] and r["fast"])]
    out += ["", "## Rows where the new revision is worse", ""]
    out += [f"- {r['table']}: {r['case']}: " + ", ".join(
        (["worst quality lower"] if not r["good"] else [])
        + ([f"time ×{r['ratio']:.2f} (CPU ×{r['cpu']:.2f})" if r["ratio"] else "no time"]
           if not r["fast"] else [])) for r in bad] or ["none"]
    return "\n".join(out) + "\n"


def printed_command(argv: list[str]) -> str:
    """The command line as a shell takes it back (a word with spaces quoted), the
    ``--markdown`` file as ``FILE``."""
    given = ["FILE" if k and argv[k - 1] == "--markdown" else a for k, a in enumerate(argv)]
    return shlex.join(["python", "benchmarks/compare_revisions.py", *given])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", nargs="?", default="6b9c044", help="git revision (default 6b9c044)")
    ap.add_argument("new", nargs="?", default=WORKTREE, help=f"git revision or {WORKTREE}")
    ap.add_argument("--all", action="store_true", help="every case, the pages' sizes too")
    ap.add_argument("--page-sizes", action="store_true",
                    help="only the 3D cases at the mesh sizes their pages print")
    ap.add_argument("--cases", nargs="*", default=[], help="only cases whose page, table or "
                    "name has one of these words")
    ap.add_argument("--repeats", type=int, default=2, help="runs per revision (fastest kept)")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per run")
    ap.add_argument("--markdown", type=Path, help="also write the report to this file")
    ap.add_argument("--list", action="store_true", help="list the selected cases and stop")
    if argv is None and len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(*sys.argv[2:5])
        return 0
    args = ap.parse_args(argv)
    cases = [c for c in all_cases() if (c.full if args.page_sizes else args.all or c.default)
             and (not args.cases or any(w in f"{c.page} {c.table} {c.name}" for w in args.cases))]
    if args.list:
        print("\n".join(f"{c.page} | {c.table} | {c.name}" for c in cases))
        return 0
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # remove the worktrees when killed
    started = time.time()
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="compare_revisions_") as tmp:
        trees = {}
        try:
            for side, rev in (("old", args.old), ("new", args.new)):
                trees[side] = checkout(rev, Path(tmp) / side)
            rows = compare(trees, cases, args.repeats, args.timeout,
                           lambda line: print(line, file=sys.stderr, flush=True))
        finally:
            for tree in trees.values():
                if tree != REPO:
                    _git("worktree", "remove", "--force", str(tree))
    command = printed_command(argv if argv is not None else sys.argv[1:])
    header = (
        "# Benchmarks side by side with an earlier revision\n\n"
        f"Printed by `{command}`: old = {describe(args.old)}, new = "
        f"{describe(args.new)}. Each case is built by that revision's benchmark script and "
        f"ours is run {args.repeats} times in each revision, alternating (old, new, new, old, "
        "...), each run in a process of its own with one BLAS/OpenMP thread; the seconds are "
        "ours' call alone (wall; CPU: all the process's threads, less sensitive to the load), "
        "the fastest of the runs. Worst: the worst quality the page's "
        f"table prints (higher is better), equal or better to {RTOL:g} relative; the time "
        f"within {TIME_RATIO}× of the old. Machine: {platform.machine()}, "
        f"{os.cpu_count()} cores, Python {platform.python_version()}, shared with other work "
        f"(load average {load0[0]:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, "
        f"{(time.time() - started) / 60:.0f} minutes), so single seconds are noisy: the "
        "ratio of the alternating runs is what counts.")
    text = report(rows, cases, header, args.all or args.page_sizes)
    print(text)
    if args.markdown:
        args.markdown.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
