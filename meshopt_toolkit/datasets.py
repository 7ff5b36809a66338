"""Locate the sample meshes shipped in ``meshopt_toolkit.data``."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from .errors import ReadError


def data_path(name: str) -> Path:
    """Path of a bundled sample mesh, e.g. ``data_path("disc_146.msh")``.

    Raises
    ------
    ReadError
        No bundled file has that name; the message lists the available ones.
    """
    root = resources.files("meshopt_toolkit.data")
    path = Path(str(root.joinpath(name)))
    if not path.is_file():
        raise ReadError(f"{name}: no such bundled mesh; available: {', '.join(available())}")
    return path


def available() -> list[str]:
    """Names of the bundled sample meshes."""
    root = Path(str(resources.files("meshopt_toolkit.data")))
    return sorted(p.name for p in root.iterdir() if p.suffix == ".msh")
