"""VTK legacy ``.vtk`` and XML ``.vtu`` through meshio, with its traps guarded.

meshio's readers are called directly (``meshio.read`` calls ``sys.exit`` on failure);
everything they return is kept: every cell block, point and cell data (physical groups as
``gmsh:physical``/``gmsh:geometrical`` cell data) and, for ``.vtu``, field data (the
physical names; meshio reads ``<FieldData>`` but does not write it, so it is added to the
file here). Points are written as ``(N, 3)`` (z = 0 for planar meshes). Binary output (the
default) stores doubles exactly; ``.vtu`` binary is zlib-compressed; ASCII ``.vtu`` is our
own writer with ``repr`` values (meshio's keeps only 12 significant digits). Legacy
``.vtk`` output refuses field data (meshio cannot write it).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..errors import ReadError, WriteError
from ..kernels.surface import pad3
from ._common import format_rows, quiet
from ._loss import Part, numeric, refuse
from ._files import UNCAPPED, open_input
from .cells import CellMesh, check_cells

logger = logging.getLogger(__name__)
_quiet = quiet


def _read(path: Path, reader, kind: str) -> CellMesh:
    try:
        with quiet():
            m = reader(path)
        cm = CellMesh.from_meshio(m, source=str(path))
    except (Exception, SystemExit) as exc:
        detail = str(exc) or f"not a valid {kind} file or truncated"
        raise ReadError(f"{path}: cannot read {kind} file: {detail}") from None
    if "gmsh:dim_tags" in m.point_data:  # a datum of this file, under a name kept for gmsh's
        cm.dropped.append("point data 'gmsh:dim_tags'")
    check_cells(cm)
    return cm


def read_vtk_cells(path: Path) -> CellMesh:
    """Everything of a legacy VTK file (unstructured grid or polydata)."""
    with open_input(path, UNCAPPED) as fh:
        if not fh.read(64).lstrip().startswith(b"# vtk DataFile"):
            raise ReadError(f"{path}: not a legacy VTK file (no '# vtk DataFile' header)")
    from meshio.vtk._main import read_buffer

    def read(p):
        with open_input(p, UNCAPPED) as fh:
            return read_buffer(fh)

    return _read(path, read, "VTK")


def read_vtu_cells(path: Path) -> CellMesh:
    """Everything of a VTK XML unstructured grid."""
    import meshio.vtu

    with open_input(path, UNCAPPED) as fh:
        head = fh.read(256).lstrip()
    if not (head.startswith(b"<?xml") or head.startswith(b"<VTKFile")):
        raise ReadError(f"{path}: not a VTU file (no XML header)")
    return _read(path, meshio.vtu.read, "VTU")


def unsupported_vtu(cm: CellMesh) -> list[Part]:
    """What VTU cannot hold: data that is not numeric (or not one row per point)."""
    n = cm.n_points
    parts: list[Part] = [("point", k) for k, v in cm.point_data.items()
                         if not numeric(v) or len(v) != n]
    return parts + [("cell", k) for k, v in cm.cell_data.items()
                    if not all(numeric(a) for a in v)]


def unsupported_vtk(cm: CellMesh) -> list[Part]:
    """What legacy VTK output cannot hold: as VTU, and field data (meshio cannot write
    it)."""
    return unsupported_vtu(cm) + [("field", k) for k in cm.field_data]


def _check_data(cm: CellMesh, path, fmt: str = "VTU") -> None:
    refuse(path, fmt, cm, unsupported_vtu(cm) if fmt == "VTU" else unsupported_vtk(cm))


def write_vtk_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write legacy VTK 5.1 with every cell block, point and cell data.

    Raises
    ------
    WriteError
        Field data (e.g. physical names): legacy VTK output cannot hold it.
    """
    import meshio.vtk

    _check_data(cm, path, "legacy VTK")
    with quiet():
        meshio.vtk.write(str(path), cm.to_meshio(), binary=binary is None or bool(binary))


def write_vtu_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write VTU with every cell block, point, cell and field data.

    Binary (default): meshio's zlib-compressed writer, then a ``<FieldData>`` element is
    added. ``binary=False``: our own ASCII writer with ``repr`` values.
    """
    _check_data(cm, path)
    if binary is None or binary:
        import meshio.vtu

        with quiet():
            meshio.vtu.write(str(path), cm.to_meshio(), binary=True)
        if cm.field_data:
            text = Path(path).read_bytes()
            tag = b"<UnstructuredGrid>"
            at = text.find(tag)
            if at < 0:
                raise WriteError(f"{path}: unexpected VTU layout from meshio")
            at += len(tag)
            Path(path).write_bytes(text[:at] + b"\n" + _field_data_xml(cm).encode() +
                                   text[at:])
        return
    _write_vtu_ascii(path, cm)


def quoteattr(text: str) -> str:
    """An XML attribute value in double quotes (no xml.sax import: it pulls in urllib)."""
    return '"' + (str(text).replace("&", "&amp;").replace('"', "&quot;")
                  .replace("<", "&lt;").replace(">", "&gt;")) + '"'


def _vtu_type(a: np.ndarray) -> str:
    kind = {"f": "Float", "i": "Int", "u": "UInt", "b": "UInt"}[a.dtype.kind]
    return f"{kind}{8 * (1 if a.dtype.kind == 'b' else a.dtype.itemsize)}"


def _array_xml(name: str, a: np.ndarray, tuples: bool = False) -> str:
    a = np.asarray(a)
    if a.dtype.kind == "b":
        a = a.astype(np.uint8)
    comps = 1 if a.ndim == 1 else int(np.prod(a.shape[1:]))
    flat = a.reshape(len(a), comps) if len(a) else a.reshape(0, comps)
    extra = f' NumberOfTuples="{len(a)}"' if tuples else ""
    if a.ndim > 1:
        extra = f' NumberOfComponents="{comps}"' + extra
    body = format_rows(flat, "%r" if a.dtype.kind == "f" else "%d")
    return (f'<DataArray type="{_vtu_type(a)}" Name={quoteattr(name)}{extra} '
            f'format="ascii">\n{body}</DataArray>\n')


def _field_data_xml(cm: CellMesh) -> str:
    parts = [_array_xml(k, np.atleast_1d(np.asarray(v)), tuples=True)
             for k, v in cm.field_data.items()]
    return "<FieldData>\n" + "".join(parts) + "</FieldData>\n"


def _write_vtu_ascii(path: Path, cm: CellMesh) -> None:
    from meshio._vtk_common import meshio_to_vtk_type

    for t, _ in cm.cells:
        if t not in meshio_to_vtk_type:
            raise WriteError(f"{path}: VTU files cannot hold {t} cells")
    pts = pad3(cm.points)
    n = len(pts)
    ncell = cm.n_cells
    conn = [np.asarray(c).reshape(-1) for _, c in cm.cells]
    sizes = np.concatenate([np.full(len(c), c.shape[1]) for _, c in cm.cells]) \
        if cm.cells else np.zeros(0, np.int64)
    types = np.concatenate([np.full(len(c), meshio_to_vtk_type[t]) for t, c in cm.cells]) \
        if cm.cells else np.zeros(0, np.int64)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write('<?xml version="1.0"?>\n'
                 '<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">\n'
                 '<UnstructuredGrid>\n')
        if cm.field_data:
            fh.write(_field_data_xml(cm))
        fh.write(f'<Piece NumberOfPoints="{n}" NumberOfCells="{ncell}">\n<Points>\n'
                 '<DataArray type="Float64" NumberOfComponents="3" format="ascii">\n')
        fh.write(format_rows(pts, "%r"))
        fh.write('</DataArray>\n</Points>\n<Cells>\n'
                 '<DataArray type="Int64" Name="connectivity" format="ascii">\n')
        for c in conn:
            fh.write(format_rows(c[:, None], "%d"))
        fh.write('</DataArray>\n<DataArray type="Int64" Name="offsets" format="ascii">\n')
        fh.write(format_rows(np.cumsum(sizes)[:, None], "%d"))
        fh.write('</DataArray>\n<DataArray type="UInt8" Name="types" format="ascii">\n')
        fh.write(format_rows(types[:, None], "%d"))
        fh.write("</DataArray>\n</Cells>\n")
        cell_data = {k: np.concatenate([np.asarray(x) for x in v]) for k, v in cm.cell_data.items()}
        for tag, data in (("PointData", cm.point_data), ("CellData", cell_data)):
            if data:
                fh.write(f"<{tag}>\n" + "".join(_array_xml(k, v) for k, v in data.items())
                         + f"</{tag}>\n")
        fh.write("</Piece>\n</UnstructuredGrid>\n</VTKFile>\n")
