"""Helpers shared by the subcommands: expanding batch inputs, parsing number lists."""

from __future__ import annotations

import argparse
import glob
import logging
from pathlib import Path

from ..errors import MeshoptError

#: extensions treated as meshes when a directory is given as input
MESH_SUFFIXES = (".msh", ".obj", ".ply", ".off", ".vtk", ".vtu", ".stl")


def expand_inputs(items: list[str], recursive: bool = False) -> list[Path]:
    """Files, globs and directories (their mesh files) → sorted unique paths.

    A directory contributes the mesh files directly in it; with ``recursive`` also those
    in its sub-folders (hidden ones excluded). Skipped sub-folders are logged as a warning.

    Raises
    ------
    MeshoptError
        An item matches nothing.
    """
    paths: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found = _directory_meshes(p, recursive)
            if not found:
                raise MeshoptError(f"{item}: directory has no mesh files ({', '.join(MESH_SUFFIXES)})")
            paths.extend(found)
        elif p.exists():
            paths.append(p)
        elif glob.has_magic(item):
            found = sorted(Path(g) for g in glob.glob(item))
            if not found:
                raise MeshoptError(f"{item}: pattern matches no file")
            paths.extend(found)
        else:
            raise MeshoptError(f"{item}: no such file or directory")
    seen: set[Path] = set()
    unique = []
    for p in paths:
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            unique.append(p)
    return unique


def _directory_meshes(p: Path, recursive: bool) -> list[Path]:
    files = sorted(q for q in (p.rglob("*") if recursive else p.iterdir())
                   if q.suffix.lower() in MESH_SUFFIXES and q.is_file()
                   and not any(part.startswith(".") for part in q.relative_to(p).parts))
    if not recursive:
        subs = sorted(q.name for q in p.iterdir() if q.is_dir() and not q.name.startswith("."))
        if subs:
            logging.getLogger("meshopt").warning(
                "%s: %d sub-folder(s) not searched (%s); use --recursive to include them",
                p, len(subs), ", ".join(subs[:5]) + (", ..." if len(subs) > 5 else ""))
    return files


def float_list(n: int | None = None):
    """An argparse type for comma-separated floats, e.g. ``--beta 10,1,0,0.1``."""

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(float(x) for x in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}")
        if n is not None and len(values) != n:
            raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers, got {len(values)}")
        return values

    return parse
