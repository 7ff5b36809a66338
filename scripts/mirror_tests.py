"""Move the top-level test files into ``tests/<package>/`` folders mirroring the package.

Run from the repository root (re-runnable: files already in a folder are left alone)::

    python scripts/mirror_tests.py              # git mv, then compare collect-only counts
    python scripts/mirror_tests.py --dry-run    # only print where each file would go
    python scripts/mirror_tests.py --no-collect # move without the collect-only comparison

A file goes to the folder of the first rule of :data:`RULES` its name matches; a file no
rule names goes to the package it imports most (``from meshopt_toolkit.X import``) when X
is a package; the files of :data:`TOP_LEVEL` (tests of the whole package) stay, and so
does any file neither placed, which is listed. A moved file's ``Path(__file__)`` parent
chains are deepened by one level, and ``tests/test_X.py`` in the tracked docs and
sources becomes ``tests/<folder>/test_X.py``. Bare imports between test files and of the helper
modules keep working because ``tests/conftest.py`` puts ``tests/`` and each of its test
folders on ``sys.path`` (so a test file's name must be unique across ``tests/``).
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from collections import Counter
from fnmatch import fnmatch
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"
PACKAGE = ROOT / "meshopt_toolkit"

#: tests of the whole package, the repository or the benchmarks: they stay in ``tests/``
TOP_LEVEL = frozenset({
    "test_architecture.py", "test_layout.py", "test_docs.py", "test_packaging.py",
    "test_examples.py", "test_bench_surface_cases.py", "test_public_parameters.py",
    "test_bench_arap_contact.py",
})

#: (file-name pattern, folder), first match wins; ``modules`` holds the tests of the
#: single modules at the package root (solvers, progress, scaling, expressions, ...)
RULES: tuple[tuple[str, str], ...] = (
    ("test_batch*", "batch"),
    ("test_cli_*", "cli"), ("test_*_cli.py", "cli"), ("test_moved_normals.py", "cli"),
    ("test_move_summary.py", "cli"),
    ("test_io*", "io"), ("test_convert*", "io"), ("test_gmsh*", "io"), ("test_workpiece*", "io"),
    ("test_write_errors.py", "io"), ("test_fuzz_readers.py", "io"), ("test_info_*", "io"),
    ("test_kernels_*", "kernels"), ("test_predicates.py", "kernels"),
    ("test_intersections3d.py", "kernels"), ("test_injectivity.py", "kernels"),
    ("test_anchors3d.py", "kernels"),
    ("test_mesh.py", "mesh"), ("test_surface_mesh.py", "mesh"), ("test_tetrahedra.py", "mesh"),
    ("test_surface_measures.py", "mesh"), ("test_orientation.py", "mesh"),
    ("test_motion_*", "motion"), ("test_tet_*", "motion"), ("test_surface_*", "motion"),
    ("test_morph*", "motion"), ("test_move_*", "motion"), ("test_handles3d.py", "motion"),
    ("test_similarity_3d.py", "motion"), ("test_contact.py", "motion"),
    ("test_self_intersection_moves.py", "motion"),
    ("test_pipeline_*", "pipeline"), ("test_filter*", "pipeline"),
    ("test_fuzz_pipelines.py", "pipeline"),
    ("test_fem*", "fem"), ("test_poisson.py", "fem"), ("test_stokes.py", "fem"),
    ("test_elasticity*", "fem"), ("test_compliance*", "fem"), ("test_interpolation.py", "fem"),
    ("test_objective_registry.py", "shape"), ("test_shape*", "shape"), ("test_optimize*", "shape"),
    ("test_lbfgs*", "shape"),
    ("test_retractions.py", "riemannian"), ("test_metrics.py", "riemannian"),
    ("test_discrete_geodesic.py", "riemannian"),
    ("test_geodesics.py", "ode"),
    ("test_penalt*", "penalties"),
    ("test_solvers.py", "modules"), ("test_progress.py", "modules"),
    ("test_expressions.py", "modules"), ("test_diagnostics.py", "modules"),
    ("test_scal*", "modules"), ("test_operations.py", "modules"),
    ("test_deform.py", "modules"), ("test_summary_keys.py", "modules"),
)

_IMPORT = re.compile(r"^\s*(?:from|import)\s+meshopt_toolkit\.(\w+)", re.M)
# Path(__file__)[.resolve()] followed by .parent / .parents[k] steps
_CHAIN = re.compile(r"(Path\(__file__\)(?:\.resolve\(\))?)((?:\.parent(?!s)|\.parents\[\d+\])+)")


def folder_for(path: Path) -> str | None:
    """The folder under ``tests/`` a top-level test file belongs to; None when it stays."""
    name = path.name
    if name in TOP_LEVEL:
        return None
    for pattern, folder in RULES:
        if fnmatch(name, pattern):
            return folder
    counts = Counter(m for m in _IMPORT.findall(path.read_text())
                     if (PACKAGE / m / "__init__.py").exists())
    return counts.most_common(1)[0][0] if counts else None


def _depth(chain: str) -> int:
    return sum(int(k) + 1 if k else 1 for k in re.findall(r"\.parents?(?:\[(\d+)\])?", chain))


def deepen(text: str) -> str:
    """``Path(__file__)`` parent chains one level deeper (the file moved into a subfolder)."""
    return _CHAIN.sub(lambda m: f"{m.group(1)}.parents[{_depth(m.group(2))}]", text)


def fix_references() -> list[str]:
    """Rewrite ``tests/test_X.py`` in the tracked docs and sources to the file's folder."""
    where = {p.name: p.relative_to(ROOT).as_posix() for p in TESTS.glob("*/test_*.py")}
    pattern = re.compile(r"(?<![\w/])tests/(test_\w+\.py)")
    changed = []
    listed = subprocess.run(["git", "ls-files", "*.md", "*.py", "*.toml", ".ci/*"], cwd=ROOT,
                            capture_output=True, text=True, check=True).stdout.split()
    for name in listed:
        path = ROOT / name
        if not path.is_file():
            continue
        text = path.read_text(encoding="utf-8")
        new = pattern.sub(lambda m: where.get(m.group(1), m.group(0)), text)
        if new != text:
            path.write_text(new, encoding="utf-8")
            changed.append(name)
    return changed


def collect_count() -> int:
    """The number of tests ``pytest --collect-only -q`` finds (the run must succeed)."""
    command = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"]
    out = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
    found = re.search(r"(\d+) tests? collected", out.stdout)
    if out.returncode != 0 or not found:
        sys.exit(f"collect-only failed (exit {out.returncode}):\n"
                 f"{out.stdout[-4000:]}{out.stderr[-2000:]}")
    return int(found.group(1))


def plan() -> tuple[dict[Path, str], list[Path]]:
    """Where each top-level test file goes, and the files left unplaced (not whole-package)."""
    moves, unplaced = {}, []
    for path in sorted(TESTS.glob("test_*.py")):
        folder = folder_for(path)
        if folder is not None:
            moves[path] = folder
        elif path.name not in TOP_LEVEL:
            unplaced.append(path)
    return moves, unplaced


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dry-run", action="store_true", help="only print the moves")
    parser.add_argument("--no-collect", action="store_true",
                        help="skip the collect-only comparison")
    args = parser.parse_args(argv)
    moves, unplaced = plan()
    taken = {p.name: p for p in TESTS.glob("*/**/test_*.py")}
    clashes = [f"{p.name} (already {taken[p.name].relative_to(ROOT)})"
               for p in moves if p.name in taken]
    if clashes:
        sys.exit("a test file name must be unique across tests/: " + ", ".join(clashes))
    before = None if args.dry_run or args.no_collect else collect_count()
    for path, folder in moves.items():
        target = TESTS / folder / path.name
        print(f"{path.relative_to(ROOT)} -> {target.relative_to(ROOT)}")
        if args.dry_run:
            continue
        target.parent.mkdir(exist_ok=True)
        subprocess.run(["git", "mv", str(path), str(target)], cwd=ROOT, check=True)
        text = target.read_text()
        if deepen(text) != text:
            target.write_text(deepen(text))
            subprocess.run(["git", "add", str(target)], cwd=ROOT, check=True)
    print(f"moved {len(moves)} file(s)" + (" (dry run)" if args.dry_run else ""))
    if not args.dry_run:
        print("references rewritten in:", *fix_references() or ["(none)"], sep="\n  ")
    if unplaced:
        print("not placed (add a rule or TOP_LEVEL entry):", *(p.name for p in unplaced),
              sep="\n  ")
    if before is not None:
        after = collect_count()
        print(f"collected before: {before}, after: {after}")
        if after != before:
            return 1
    return 1 if unplaced else 0


if __name__ == "__main__":
    sys.exit(main())
