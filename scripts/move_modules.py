"""Move package modules to new places and rewrite every reference to them.

Run from the repository root with a mapping file of ``old.dotted.module new.dotted.module``
lines (names below ``meshopt_toolkit``, e.g. ``motion.tet_move motion.tets.move``)::

    python scripts/move_modules.py MAPPING            # git mv, then rewrite
    python scripts/move_modules.py MAPPING --dry-run  # only list what would change

Every ``import``/``from … import`` in the package, ``tests/``, ``benchmarks/``,
``examples/`` and ``scripts/`` is resolved to the module it names (relative imports against
the importing module's own new place) and written back in the same style (relative stays
relative). Dotted names in strings (``"meshopt_toolkit.motion.move.f"`` for monkeypatching,
the lazy table's ``"motion.move"``) and file paths in text (``motion/move.py``) follow. New
folders get an ``__init__.py`` with a one-line docstring to be filled in.
"""

from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = "meshopt_toolkit"
TREES = ("meshopt_toolkit", "tests", "benchmarks", "examples", "scripts")
TEXT = ("*.md", "*.py", "*.toml", "*.cfg", "*.txt", "*.json")


def module_of(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def package_of(path: Path) -> list[str]:
    mod = module_of(path).split(".")
    return mod if path.name == "__init__.py" else mod[:-1]


def resolve(node: ast.ImportFrom, package: list[str]) -> str:
    if node.level == 0:
        return node.module or ""
    base = package[: len(package) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def relative(target: str, package: list[str]) -> str:
    t = target.split(".")
    common = 0
    while common < min(len(t), len(package)) and t[common] == package[common]:
        common += 1
    return "." * (len(package) - common + 1) + ".".join(t[common:])


def rewrite_imports(path: Path, mapping: dict[str, str], package: list[str],
                    old_package: list[str]) -> str | None:
    """The file's text with its imports pointing at the new places (None: unchanged).
    ``old_package`` is the package the file's relative imports were written against."""
    src = path.read_text()
    try:
        tree = ast.parse(src)
    except SyntaxError:
        return None
    lines = src.splitlines(keepends=True)
    edits: list[tuple[int, int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            old = resolve(node, old_package)
            indent = lines[node.lineno - 1][: node.col_offset]
            groups: dict[str, list[str]] = {}
            for alias in node.names:
                full = f"{old}.{alias.name}"
                if full in mapping:           # `from pkg import module`
                    new_parent, name = mapping[full].rsplit(".", 1)
                    bound = alias.asname or alias.name
                    text = name if name == bound else f"{name} as {bound}"
                else:
                    new_parent = mapping.get(old, old)
                    text = alias.name + (f" as {alias.asname}" if alias.asname else "")
                groups.setdefault(new_parent, []).append(text)
            if list(groups) == [old] and (node.level == 0 or old_package == package):
                continue
            stmts = []
            for parent, names in groups.items():
                where = relative(parent, package) if node.level else parent
                stmt = f"{indent}from {where} import {', '.join(names)}"
                if len(stmt) > 100:  # the project's line length: one name per line
                    inner = "".join(f"{indent}    {n},\n" for n in names)
                    stmt = f"{indent}from {where} import (\n{inner}{indent})"
                stmts.append(stmt)
            edits.append((node.lineno, node.end_lineno, "\n".join(stmts).lstrip() + "\n"))
        elif isinstance(node, ast.Import):
            names = []
            changed = False
            for alias in node.names:
                new = alias.name
                for o in sorted(mapping, key=len, reverse=True):
                    if alias.name == o or alias.name.startswith(o + "."):
                        new = mapping[o] + alias.name[len(o):]
                        changed = True
                        break
                names.append(new + (f" as {alias.asname}" if alias.asname else ""))
            if changed:
                edits.append((node.lineno, node.end_lineno, f"import {', '.join(names)}\n"))
    if not edits:
        return None
    for start, end, text in sorted(edits, reverse=True):
        first = lines[start - 1]
        indent = first[: len(first) - len(first.lstrip())]
        lines[start - 1:end] = [indent + text]
    return "".join(lines)


def rewrite_text(text: str, mapping: dict[str, str]) -> str:
    for old in sorted(mapping, key=len, reverse=True):
        new = mapping[old]
        text = re.sub(rf"(?<![\w.]){re.escape(old)}(?![\w])", new, text)
        o, n = old.split(".", 1)[1], new.split(".", 1)[1]
        text = re.sub(rf"(?<![\w]){re.escape(o)}(?![\w])", n, text)  # "motion.x", ``..motion.x.f``
        op = old.split(".", 1)[1].replace(".", "/") + ".py"
        np_ = new.split(".", 1)[1].replace(".", "/") + ".py"
        text = re.sub(rf"(?<![\w/]){re.escape(op)}", np_, text)
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mapping", type=Path)
    ap.add_argument("--dry-run", action="store_true")
    ap.add_argument("--rewrite-only", action="store_true",
                    help="the modules are moved already (a merged branch still names the old "
                         "places): rewrite the references only")
    args = ap.parse_args(argv)
    mapping = {}
    for line in args.mapping.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            old, new = line.split()
            mapping[f"{PKG}.{old}"] = f"{PKG}.{new}"
    for old, new in mapping.items():
        src = ROOT / (old.replace(".", "/") + ".py")
        dst = ROOT / (new.replace(".", "/") + ".py")
        if args.rewrite_only:
            continue
        if not src.exists():
            sys.exit(f"{src}: no such module")
        print(f"{src.relative_to(ROOT)} -> {dst.relative_to(ROOT)}")
        if args.dry_run:
            continue
        for folder in reversed(dst.relative_to(ROOT).parents[:-1]):
            init = ROOT / folder / "__init__.py"
            if not init.exists():
                (ROOT / folder).mkdir(exist_ok=True)
                init.write_text(f'"""{folder.name}."""\n')
                subprocess.run(["git", "add", str(init)], check=True, cwd=ROOT)
        subprocess.run(["git", "mv", str(src), str(dst)], check=True, cwd=ROOT)
    if args.dry_run:
        return 0
    moved_from = ({} if args.rewrite_only else
                  {ROOT / (new.replace(".", "/") + ".py"): old for old, new in mapping.items()})
    files = [p for t in TREES for p in (ROOT / t).rglob("*.py")]
    for path in files:
        old_package = (moved_from[path].split(".")[:-1] if path in moved_from
                       else package_of(path))
        new = rewrite_imports(path, mapping, package_of(path), old_package)
        if new is not None:
            path.write_text(new)
    tracked = subprocess.run(["git", "ls-files", *TEXT], capture_output=True, text=True,
                             cwd=ROOT, check=True).stdout.split()
    for name in tracked:
        path = ROOT / name
        if not path.exists() or "scripts/move_modules.py" in name:
            continue
        text = path.read_text()
        new = rewrite_text(text, mapping)
        if new != text:
            path.write_text(new)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
