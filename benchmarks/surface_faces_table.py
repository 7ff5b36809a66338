"""docs/benchmarks-surface.md's table of self-intersecting faces from the logs of
``run_surface_cases.sh`` (``bench_surface.py --markdown --every-frame``, a log per case):
one row per case, ours first, then ours' measures one row per case.

Run ``python benchmarks/surface_faces_table.py LOGDIR CASE [CASE ...]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

METHODS = ("ours", "harmonic", "biharmonic", "ARAP", "ARAP 10 steps")


def rows(log: Path) -> tuple[str, dict]:
    """The case's name and its markdown rows' cells by method."""
    name, out = "", {}
    for line in log.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| ") and len(cells) >= 8 and cells[1] in METHODS:
            name = cells[0] or name
            out[cells[1]] = cells
    return name, out


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    logdir, cases = Path(args[0]), args[1:]
    faces = ["| case | " + " | ".join(METHODS) + " |", "| --- |" + " ---: |" * len(METHODS)]
    ours = ["| case | worst rel. quality | folds | handle error | seconds (CPU) | ARAP energy "
            "| ours / best fold-free libigl |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for case in cases:
        log = logdir / f"{case}.log"
        name, by = rows(log) if log.exists() else (case, {})
        faces.append(f"| {name} | " + " | ".join(
            by[m][7].replace(" over every frame", " every frame") if m in by else "not run"
            for m in METHODS) + " |")
        o = by.get("ours")
        ours.append(f"| {name} | " + (" | ".join(o[2:7] + o[8:9]) if o else "not run")
                    + " |")
    print("\n".join(faces) + "\n\n" + "\n".join(ours))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
