"""Mesh file I/O: one module per format behind an extension registry.

``load(path)`` and ``save(mesh, path)`` pick the reader/writer from the file extension in
:data:`READERS` / :data:`WRITERS` (plain dicts: extension → function). Every failure is a
:class:`~meshopt_toolkit.errors.ReadError` or :class:`~meshopt_toolkit.errors.WriteError`
naming the file; writes are atomic (temporary file in the same directory, then rename).

=========  ==========================================  ===================================
format     read                                        write (default)
=========  ==========================================  ===================================
``.msh``   gmsh 2.2/4.0/4.1, ASCII and binary, tags    gmsh 4.1 binary (``msh_version``)
``.obj``   own reader, file order                      text, 17 significant digits
``.off``   own reader                                  text, 17 significant digits
``.ply``   own reader, ASCII/binary                    binary doubles
``.vtk``   meshio                                      binary (legacy 5.1)
``.vtu``   meshio                                      binary, zlib
``.stl``   corners merged, sorted ("unordered")        binary float32
=========  ==========================================  ===================================
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from pathlib import Path

from ..errors import MeshoptError, ReadError, WriteError
from ..mesh import TriangleMesh
from . import gmsh, obj, off, ply, stl, vtk
from ._atomic import atomic_path

logger = logging.getLogger(__name__)

__all__ = ["load", "save", "READERS", "WRITERS", "atomic_path", "supported_extensions"]

Reader = Callable[[Path], TriangleMesh]
Writer = Callable[..., None]

#: extension → reader(path) -> TriangleMesh
READERS: dict[str, Reader] = {
    ".msh": gmsh.read,
    ".obj": obj.read,
    ".off": off.read,
    ".ply": ply.read,
    ".vtk": vtk.read_vtk,
    ".vtu": vtk.read_vtu,
    ".stl": stl.read,
}

#: extension → writer(path, mesh, binary) -> None
WRITERS: dict[str, Writer] = {
    ".msh": gmsh.write,
    ".obj": obj.write,
    ".off": off.write,
    ".ply": ply.write,
    ".vtk": vtk.write_vtk,
    ".vtu": vtk.write_vtu,
    ".stl": stl.write,
}


def supported_extensions(kind: str = "read") -> list[str]:
    """Registered extensions for ``"read"`` or ``"write"``."""
    return sorted(READERS if kind == "read" else WRITERS)


def load(path: str | os.PathLike) -> TriangleMesh:
    """Read a mesh file, choosing the format from its extension.

    Parameters
    ----------
    path : str or PathLike

    Returns
    -------
    TriangleMesh
        A :class:`~meshopt_toolkit.mesh.PlanarMesh` with points ``(N, 2)`` when the file's
        points are 2D or every z is exactly 0, else a ``TriangleMesh`` with ``(N, 3)``
        points; ``source`` is ``str(path)``. Vertex order and connectivity are the file's
        (except STL, whose corners are merged).

    Raises
    ------
    ReadError
        Missing or unreadable file, unknown extension, malformed or truncated content, or a
        failed readable-level check (NaN coordinate, index out of range, no triangle);
        the message starts with the file name.
    """
    path = Path(path)
    ext = path.suffix.lower()
    reader = READERS.get(ext)
    if reader is None:
        raise ReadError(f"{path}: unknown mesh format {ext or '(no extension)'!r}; "
                        f"known: {', '.join(supported_extensions())}")
    if not path.exists():
        raise ReadError(f"{path}: no such file")
    if path.is_dir():
        raise ReadError(f"{path}: is a directory")
    try:
        return reader(path)
    except ReadError:
        raise
    except MeshoptError as exc:
        raise ReadError(f"{exc}" if str(path) in str(exc) else f"{path}: {exc}") from exc
    except OSError as exc:
        raise ReadError(f"{path}: {exc.strerror or exc}") from None
    except (ValueError, IndexError, TypeError, KeyError, UnicodeDecodeError, MemoryError) as exc:
        raise ReadError(f"{path}: malformed {ext} file ({type(exc).__name__}: {exc})") from None


def save(
    mesh: TriangleMesh,
    path: str | os.PathLike,
    *,
    overwrite: bool = True,
    binary: bool | None = None,
    msh_version: str = "4.1",
) -> Path:
    """Write ``mesh`` atomically, choosing the format from the extension of ``path``.

    Parameters
    ----------
    mesh : TriangleMesh
        Planar meshes get z = 0 where the format is 3D.
    path : str or PathLike
    overwrite : bool
        If false, an existing file is refused (:class:`WriteError`).
    binary : bool, optional
        None = the format's default (binary where available; OBJ/OFF are text only and
        refuse ``binary=True``).
    msh_version : {"4.1", "2.2"}
        gmsh file version for ``.msh``.

    Returns
    -------
    Path
        The written path.

    Raises
    ------
    WriteError
        Unknown extension, existing file with ``overwrite=False``, missing directory, or
        an I/O failure; nothing (not even a partial file) is left at ``path`` then.
    """
    path = Path(path)
    ext = path.suffix.lower()
    writer = WRITERS.get(ext)
    if writer is None:
        raise WriteError(f"{path}: unknown mesh format {ext or '(no extension)'!r}; "
                         f"known: {', '.join(supported_extensions('write'))}")
    if not isinstance(mesh, TriangleMesh):
        raise WriteError(f"{path}: expected a TriangleMesh, got {type(mesh).__name__}")
    kwargs = {"version": msh_version} if ext == ".msh" else {}
    if ext != ".msh" and (mesh.lines is not None or mesh.triangle_tags is not None):
        logger.info("%s: %s files do not keep physical tags or line elements", path, ext)
    with atomic_path(path, overwrite=overwrite) as tmp:
        try:
            writer(tmp, mesh, binary, **kwargs)
        except WriteError as exc:
            raise WriteError(str(exc).replace(str(tmp), str(path))) from None
        except (OSError, ValueError, TypeError) as exc:
            raise WriteError(f"{path}: cannot write {ext} file: {exc}") from None
    return path
