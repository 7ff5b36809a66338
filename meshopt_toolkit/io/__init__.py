"""Mesh file I/O: one module per format behind an extension registry.

``load(path)`` and ``save(mesh, path)`` pick the reader/writer from the file extension in
:data:`READERS` / :data:`WRITERS` (extension → function, filled by
:func:`register_format`, which third-party formats use too) and work with
triangle meshes. ``load_cells(path)`` and ``save_cells(cells, path)`` (:data:`CELL_READERS`
/ :data:`CELL_WRITERS`) move everything a file holds, as a :class:`~.cells.CellMesh`:
every cell type, point, cell and field data; a writer refuses what its format cannot
hold (:func:`fit_cells` leaves that out instead, for ``convert --allow-loss``). Every
failure is a :class:`~meshopt_toolkit.errors.ReadError` or
:class:`~meshopt_toolkit.errors.WriteError` naming the file; only regular files are read
(a FIFO or a device is refused before it is opened), up to :data:`MAX_FILE_BYTES`; writes
are atomic (temporary file in the same directory, then rename).

=========  ==========================================  ===================================
format     read                                        write (default)
=========  ==========================================  ===================================
``.msh``   gmsh 2.2/4.0/4.1, ASCII and binary, tags    the input's, else 4.1 binary
``.obj``   own reader, file order                      text, 17 significant digits
``.off``   own reader                                  text, 17 significant digits
``.ply``   own reader, ASCII/binary                    binary doubles
``.vtk``   meshio                                      binary (legacy 5.1)
``.vtu``   meshio                                      binary, zlib
``.stl``   corners merged, sorted ("unordered")        binary float32 (ASCII: exact)
``.mesh``  Medit ASCII (meshio), references as tags     text, 17 significant digits
=========  ==========================================  ===================================
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from pathlib import Path

from ..errors import FileWriteError, MeshoptError, ReadError, WriteError
from ..mesh import TriangleMesh
from . import gmsh, medit, obj, off, ply, stl, vtk
from ._atomic import atomic_path
from ._files import MAX_FILE_BYTES, check_input_file
from .cells import CellMesh, triangle_mesh, triangles_only

logger = logging.getLogger(__name__)

__all__ = ["load", "save", "load_cells", "save_cells", "CellMesh", "READERS", "WRITERS",
           "CELL_READERS", "CELL_WRITERS", "MAX_FILE_BYTES", "atomic_path",
           "register_format", "supported_extensions", "fit_cells"]

Reader = Callable[[Path], TriangleMesh]
Writer = Callable[..., None]

#: extension → reader(path) -> TriangleMesh
READERS: dict[str, Reader] = {}
#: extension → writer(path, mesh, binary) -> None
WRITERS: dict[str, Writer] = {}
#: extension → reader(path) -> CellMesh (everything the file holds)
CELL_READERS: dict[str, Callable[[Path], CellMesh]] = {}
#: extension → writer(path, cells, binary) -> None; refuses what the format cannot hold
CELL_WRITERS: dict[str, Writer] = {}
#: extension → unsupported(cells) -> the parts a cell writer refuses (see :mod:`._loss`)
UNSUPPORTED: dict[str, Callable[[CellMesh], list]] = {}


def _triangle_reader(read_cells: Callable[[Path], CellMesh]) -> Reader:
    def read(path: Path) -> TriangleMesh:
        return triangle_mesh(read_cells(path))
    return read


def _triangle_writer(write_cells: Writer) -> Writer:
    def write(path: Path, mesh: TriangleMesh, binary: bool | None = None) -> None:
        write_cells(path, triangles_only(mesh), binary)
    return write


def register_format(extension: str, *, read: Reader | None = None, write: Writer | None = None,
                    read_cells: Callable[[Path], CellMesh] | None = None,
                    write_cells: Writer | None = None,
                    unsupported: Callable[[CellMesh], list] | None = None) -> None:
    """Register the reader/writer functions of a file format by its extension (as meshio's
    ``register_format``): ``load``/``save`` use ``read``/``write`` (triangle meshes),
    ``load_cells``/``save_cells`` and ``meshopt convert`` the lossless ``read_cells`` /
    ``write_cells``. A later registration of the same extension replaces the earlier one.

    Parameters
    ----------
    extension : str
        ``".ext"`` (case-insensitive; the dot is added when missing).
    read_cells, write_cells : callables, optional
        ``read_cells(path) -> CellMesh`` and ``write_cells(path, cells, binary)``.
    read, write : callables, optional
        ``read(path) -> TriangleMesh`` and ``write(path, mesh, binary)``; by default derived
        from ``read_cells`` (the triangle mesh of what it reads; other cells refused) and
        ``write_cells`` (the mesh's points and triangles). Left out with no cell
        counterpart: that direction is not supported for the format.
    unsupported : callable, optional
        ``unsupported(cells)`` → the parts ``write_cells`` refuses (:mod:`._loss`), so that
        :func:`fit_cells` can leave them out.
    """
    ext = extension.lower() if extension.startswith(".") else "." + extension.lower()
    if read is None and read_cells is not None:
        read = _triangle_reader(read_cells)
    if write is None and write_cells is not None:
        write = _triangle_writer(write_cells)
    for table, function in ((READERS, read), (WRITERS, write), (CELL_READERS, read_cells),
                            (CELL_WRITERS, write_cells), (UNSUPPORTED, unsupported)):
        if function is not None:
            table[ext] = function


register_format(".msh", read=gmsh.read, write=gmsh.write, read_cells=gmsh.read_cells,
                write_cells=gmsh.write_cells, unsupported=gmsh.unsupported)
register_format(".vtk", read_cells=vtk.read_vtk_cells, write_cells=vtk.write_vtk_cells,
                unsupported=vtk.unsupported_vtk)
register_format(".vtu", read_cells=vtk.read_vtu_cells, write_cells=vtk.write_vtu_cells,
                unsupported=vtk.unsupported_vtu)
# one format per module, its functions named read_cells, write_cells and unsupported
for _ext, _module in ((".obj", obj), (".off", off), (".ply", ply), (".stl", stl),
                      (".mesh", medit)):
    register_format(_ext, read_cells=_module.read_cells, write_cells=_module.write_cells,
                    unsupported=_module.unsupported)


def fit_cells(cells: CellMesh, path: str | os.PathLike) -> tuple[CellMesh, str]:
    """``(what the format of path can hold, a description of the rest)``.

    The description is empty when nothing is left out (``meshopt convert --allow-loss``
    writes the first and names the second: ``"gmsh:physical cell data; 6 line cells"``).
    """
    from ._loss import describe, without

    parts = UNSUPPORTED.get(Path(path).suffix.lower(), lambda cm: [])(cells)
    return without(cells, parts), describe(cells, parts)


def supported_extensions(kind: str = "read") -> list[str]:
    """Registered extensions for ``"read"`` or ``"write"``."""
    return sorted(READERS if kind == "read" else WRITERS)


def load(path: str | os.PathLike, *, max_bytes: int | None = None) -> TriangleMesh:
    """Read a mesh file, choosing the format from its extension.

    Parameters
    ----------
    path : str or PathLike
    max_bytes : int, optional
        Refuse larger files (default :data:`MAX_FILE_BYTES`).

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
        Missing or unreadable file, not a regular file, larger than ``max_bytes``,
        unknown extension, malformed or truncated content, cells other than triangles,
        lines and vertices, or a failed readable-level check (NaN coordinate, index out
        of range, no triangle); the message starts with the file name.
    """
    return _read(path, READERS, max_bytes)


def load_cells(path: str | os.PathLike, *, max_bytes: int | None = None) -> CellMesh:
    """Read everything a mesh file holds (every cell block, point, cell and field data).

    Parameters are those of :func:`load`.

    Returns
    -------
    CellMesh
        ``dropped`` lists what the file holds that the reader cannot represent (e.g. OBJ
        texture coordinates).

    Raises
    ------
    ReadError
        As :func:`load`, except that cell types are not checked.
    """
    return _read(path, CELL_READERS, max_bytes)


def _format_of(path, table: dict, kind: str) -> tuple[Path, str, Callable]:
    """``(path, its extension in lower case, the function of table for it)``; a
    :class:`ReadError` (``kind`` "read") or :class:`WriteError` (``kind`` "write") naming
    the known extensions when table has none."""
    path = Path(path)
    ext = path.suffix.lower()
    function = table.get(ext)
    if function is None:
        error = ReadError if kind == "read" else WriteError
        raise error(f"{path}: unknown mesh format {ext or '(no extension)'!r}; "
                    f"known: {', '.join(supported_extensions(kind))}")
    return path, ext, function


def _read(path, table: dict, max_bytes: int | None):
    path, ext, reader = _format_of(path, table, "read")
    check_input_file(path, max_bytes)
    try:
        return reader(path)
    except ReadError:
        raise
    except MeshoptError as exc:
        raise ReadError(f"{exc}" if str(path) in str(exc) else f"{path}: {exc}") from exc
    except OSError as exc:
        raise ReadError(f"{path}: {exc.strerror or exc}") from None
    except (ValueError, IndexError, TypeError, KeyError, UnicodeDecodeError, MemoryError,
            OverflowError, EOFError, AttributeError, AssertionError, LookupError,
            ArithmeticError) as exc:
        raise ReadError(f"{path}: malformed {ext} file ({type(exc).__name__}: {exc})") from None


def save(
    mesh: TriangleMesh,
    path: str | os.PathLike,
    *,
    overwrite: bool = True,
    binary: bool | None = None,
    msh_version: str | None = None,
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
        refuse ``binary=True``; a gmsh file read and written again keeps its own).
    msh_version : {"4.1", "2.2"}, optional
        gmsh file version for ``.msh``; None = the version of the gmsh file the cells
        were read from, else 4.1.

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
    path, ext, writer = _format_of(path, WRITERS, "write")
    if not isinstance(mesh, TriangleMesh):
        raise WriteError(f"{path}: expected a TriangleMesh, got {type(mesh).__name__}")
    if ext != ".msh" and (mesh.lines is not None or mesh.triangle_tags is not None):
        logger.info("%s: %s files do not keep physical tags or line elements", path, ext)
    return _write(writer, mesh, path, ext, overwrite, binary, msh_version)


def save_cells(
    cells: CellMesh,
    path: str | os.PathLike,
    *,
    overwrite: bool = True,
    binary: bool | None = None,
    msh_version: str | None = None,
) -> Path:
    """Write everything of ``cells`` atomically, or refuse.

    Parameters are those of :func:`save`.

    Raises
    ------
    WriteError
        As :func:`save`, and when the format cannot hold a part of ``cells`` (a cell
        type, point, cell or field data): the message names it; nothing is written.
    """
    path, ext, writer = _format_of(path, CELL_WRITERS, "write")
    return _write(writer, cells, path, ext, overwrite, binary, msh_version)


def _write(writer, data, path: Path, ext: str, overwrite, binary, msh_version) -> Path:
    kwargs = {"version": msh_version} if ext == ".msh" else {}
    with atomic_path(path, overwrite=overwrite) as tmp:
        try:
            writer(tmp, data, binary, **kwargs)
        except WriteError as exc:
            raise type(exc)(str(exc).replace(str(tmp), str(path))) from None
        except OSError as exc:  # the file system's refusal, not the format's
            raise FileWriteError(f"{path}: cannot write: {exc.strerror or exc}") from None
        except (ValueError, TypeError) as exc:
            raise WriteError(f"{path}: cannot write {ext} file: {exc}") from None
    return path
