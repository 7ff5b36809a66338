"""VTK legacy ``.vtk`` and XML ``.vtu`` through meshio, with its traps guarded.

meshio's readers are called directly (``meshio.read`` calls ``sys.exit`` on failure);
points are written as ``(N, 3)`` (z = 0 for planar meshes). Binary output (the default)
stores doubles exactly; ``.vtu`` binary is zlib-compressed.
"""

from __future__ import annotations

import contextlib
import io
import logging
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..errors import ReadError
from ..mesh import TriangleMesh
from ._common import format_rows, points3d

logger = logging.getLogger(__name__)


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Route meshio's console warnings (printed to stderr) to the log instead."""
    buf = io.StringIO()
    with contextlib.redirect_stderr(buf):
        yield
    if buf.getvalue().strip():
        logger.debug("meshio: %s", buf.getvalue().strip())


def _read(path: Path, reader, kind: str) -> TriangleMesh:
    from ..conversions import from_meshio
    from ..errors import InvalidMeshError

    try:
        with _quiet():
            m = reader(path)
    except (Exception, SystemExit) as exc:
        detail = str(exc) or f"not a valid {kind} file or truncated"
        raise ReadError(f"{path}: cannot read {kind} file: {detail}") from None
    try:
        return from_meshio(m, source=str(path))
    except InvalidMeshError as exc:
        raise ReadError(str(exc)) from None


def read_vtk(path: Path) -> TriangleMesh:
    """Read a legacy VTK file (unstructured grid or polydata triangles)."""
    import meshio.vtk

    with open(path, "rb") as fh:
        if not fh.read(64).lstrip().startswith(b"# vtk DataFile"):
            raise ReadError(f"{path}: not a legacy VTK file (no '# vtk DataFile' header)")
    return _read(path, meshio.vtk.read, "VTK")


def read_vtu(path: Path) -> TriangleMesh:
    """Read a VTK XML unstructured grid."""
    import meshio.vtu

    return _read(path, meshio.vtu.read, "VTU")


def _mesh_out(mesh: TriangleMesh):
    import meshio

    return meshio.Mesh(points3d(mesh), [("triangle", mesh.triangles)])


def write_vtk(path: Path, mesh: TriangleMesh, binary: bool | None = None) -> None:
    """Write legacy VTK 5.1 (binary by default)."""
    import meshio.vtk

    with _quiet():
        meshio.vtk.write(str(path), _mesh_out(mesh), binary=binary is None or bool(binary))


def write_vtu(path: Path, mesh: TriangleMesh, binary: bool | None = None) -> None:
    """Write VTU: binary zlib-compressed by meshio by default; with ``binary=False`` our own
    ASCII writer with ``repr`` coordinates (meshio's keeps only 12 significant digits)."""
    import meshio.vtu

    if binary is None or binary:
        with _quiet():
            meshio.vtu.write(str(path), _mesh_out(mesh), binary=True)
        return
    n, t = mesh.n_vertices, mesh.n_triangles
    with open(path, "w", encoding="ascii") as fh:
        fh.write(
            '<?xml version="1.0"?>\n'
            '<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">\n'
            f'<UnstructuredGrid>\n<Piece NumberOfPoints="{n}" NumberOfCells="{t}">\n<Points>\n'
            '<DataArray type="Float64" NumberOfComponents="3" format="ascii">\n'
        )
        fh.write(format_rows(points3d(mesh), "%r"))
        fh.write('</DataArray>\n</Points>\n<Cells>\n'
                 '<DataArray type="Int64" Name="connectivity" format="ascii">\n')
        fh.write(format_rows(mesh.triangles, "%d"))
        fh.write('</DataArray>\n<DataArray type="Int64" Name="offsets" format="ascii">\n')
        fh.write(format_rows(3 * np.arange(1, t + 1)[:, None], "%d"))
        fh.write('</DataArray>\n<DataArray type="UInt8" Name="types" format="ascii">\n')
        fh.write("5\n" * t)
        fh.write("</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n")
