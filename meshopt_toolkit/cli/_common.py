"""Helpers shared by the subcommands: expanding batch inputs, parsing number lists."""

from __future__ import annotations

import argparse
import glob
from pathlib import Path

from ..errors import MeshoptError

#: extensions treated as meshes when a directory is given as input
MESH_SUFFIXES = (".msh", ".obj", ".ply", ".off", ".vtk", ".vtu", ".stl")


def expand_inputs(items: list[str]) -> list[Path]:
    """Files, globs and directories (their mesh files, not recursive) → sorted unique paths.

    Raises
    ------
    MeshoptError
        An item matches nothing.
    """
    paths: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in MESH_SUFFIXES)
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
