"""Medit ``.mesh`` (ASCII; MMG's and FreeFEM's format): read through meshio, written here.

A Medit file holds points with one integer reference each, element sections (``Edges``,
``Triangles``, ``Quadrilaterals``, ``Tetrahedra``, ``Prisms``, ``Pyramids``,
``Hexahedra``) with one integer reference per element, and comments. The element
references are the physical tags: they are read as ``cell_data["gmsh:physical"]`` and
written from it (or from ``"medit:ref"``); point references other than all 0 are kept as
``point_data["medit:ref"]``. Physical names go into comment lines
``# meshopt:PhysicalName DIM TAG "NAME"`` before ``Vertices``, which other Medit readers
skip. Coordinates are written with ``repr`` (≤ 17 significant digits, exact) under
``MeshVersionFormatted 2`` (double precision).

One section per cell type: blocks of the same type are written together in the order of
their first block, so the file's cells of each type are those of the mesh in order.
``gmsh:geometrical`` (gmsh's entity numbers) is written only where it is what the gmsh
writers make again from the physical tags; any other data is refused (:class:`WriteError`),
as are keywords meshio skips when reading (listed in ``dropped``).
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np

from ..errors import ReadError, WriteError
from ._common import decode_text, quiet, require_text_mode
from ._files import UNCAPPED, open_input, read_input
from ._loss import Part, cells_other_than, refuse
from .cells import GEOMETRICAL, PHYSICAL, CellMesh, cell_dimension, check_cells

REF = "medit:ref"
#: meshio cell type → Medit section keyword
SECTIONS = {"line": "Edges", "triangle": "Triangles", "quad": "Quadrilaterals",
            "tetra": "Tetrahedra", "wedge": "Prisms", "pyramid": "Pyramids",
            "hexahedron": "Hexahedra"}
#: keywords meshio's reader skips (their content would be lost)
SKIPPED = ("Corners", "Normals", "NormalAtVertices", "SubDomainFromMesh", "RequiredVertices",
           "VertexOnGeometricVertex", "VertexOnGeometricEdge", "EdgeOnGeometricEdge",
           "TangentAtVertices", "Tangents", "Ridges", "Identifier", "Geometry")
NAME_TAG = "# meshopt:PhysicalName"
_SKIPPED_RE = re.compile(r"^[ \t]*(" + "|".join(SKIPPED) + r")\b", re.M)
_COUNT_RE = re.compile(r"^[ \t]*(Vertices|" + "|".join(SECTIONS.values()) + r"|Hexaedra)[ \t]*\r?\n"
                       r"[ \t]*([^\s]+)", re.M)
_HEADER_RE = re.compile(r"^[ \t]*(MeshVersionFormatted|Dimension)[ \t]*\r?\n?[ \t]*([^\s]*)",
                        re.M)


def read_cells(path: Path) -> CellMesh:
    """Everything of an ASCII Medit file: points, element sections, references (as
    physical tags), the physical names of our comment lines."""
    import io as _io

    from meshio.medit._medit import read_ascii_buffer

    text = decode_text(read_input(path, UNCAPPED), path)
    head = text.lstrip()[:64]
    if not head.startswith(("MeshVersionFormatted", "#")):
        raise ReadError(f"{path}: not a Medit file (no MeshVersionFormatted header)")
    _prescan(text, path)
    try:
        with quiet():
            # meshio reads numbers with np.fromfile: a real file, opened as every input is
            with open_input(path, UNCAPPED) as raw, _io.TextIOWrapper(raw, "utf-8") as fh:
                m = read_ascii_buffer(fh)
        cm = CellMesh.from_meshio(m, source=str(path))
    except (Exception, SystemExit) as exc:  # meshio raises its own ReadError or worse
        detail = str(exc) or "malformed or truncated"
        raise ReadError(f"{path}: cannot read Medit file: {detail}") from None
    refs = cm.point_data.pop(REF, None)
    if refs is not None and np.any(refs):
        cm.point_data[REF] = np.asarray(refs, np.int64)
    refs = cm.cell_data.pop(REF, None)
    if refs is not None and any(np.any(r) for r in refs):
        cm.cell_data[PHYSICAL] = [np.asarray(r, np.int64) for r in refs]
    cm.field_data = _names(text, path)
    cm.dropped = [f"Medit section {k!r}" for k in dict.fromkeys(_SKIPPED_RE.findall(text))]
    check_cells(cm)
    return cm


def _prescan(text: str, path) -> None:
    """Refuse a version, dimension or section count the file cannot hold, before meshio
    allocates arrays of that size (a row takes at least two characters per value)."""
    for key, value in _HEADER_RE.findall(text):
        allowed = ("1", "2") if key == "MeshVersionFormatted" else ("2", "3")
        if value not in allowed:
            raise ReadError(f"{path}: unsupported Medit {key} {value!r} (expected "
                            f"{' or '.join(allowed)})")
    for key, value in _COUNT_RE.findall(text):
        if not value.isdigit() or 4 * int(value) > len(text):
            raise ReadError(f"{path}: Medit section {key} announces {value!r} entries; "
                            "the file is too short or the count is not a number")


def _names(text: str, path) -> dict:
    """Physical names from the ``# meshopt:PhysicalName DIM TAG "NAME"`` comment lines."""
    out = {}
    stop = re.search(r"^[ \t]*Vertices[ \t]*\r?$", text, re.M)
    for line in text[:stop.start() if stop else len(text)].splitlines():
        if line.startswith(NAME_TAG):
            try:
                dim, tag, name = shlex.split(line[len(NAME_TAG):])
                out[name] = np.array([int(tag), int(dim)])
            except ValueError:
                raise ReadError(f"{path}: malformed physical name line {line!r}") from None
    return out


def regenerated_entities(cm: CellMesh, phys: list[np.ndarray]) -> list[list[np.ndarray]]:
    """The ``gmsh:geometrical`` tags the gmsh writers make from physical tags alone:
    2.2 (the physical tag, 1 where 0) and 4.1 (one entity per dimension and physical tag,
    numbered from 1 in order of appearance)."""
    v22 = [np.where(p > 0, p, 1) for p in phys]
    known: dict[int, dict[int, int]] = {}
    v41 = []
    for (t, _), p in zip(cm.cells, phys):
        table = known.setdefault(cell_dimension(t), {})
        for tag in np.unique(p).tolist():
            table.setdefault(tag, len(table) + 1)
        v41.append(np.array([table[x] for x in p.tolist()], np.int64) if len(p) else p)
    return [v22, v41]


def _element_refs(cm: CellMesh, path) -> list[np.ndarray]:
    """One reference per element of each block (zeros without tags)."""
    keys = [k for k in (PHYSICAL, REF) if k in cm.cell_data]
    if len(keys) == 2 and not all(np.array_equal(a, b) for a, b in
                                  zip(cm.cell_data[PHYSICAL], cm.cell_data[REF])):
        raise WriteError(f"{path}: Medit files hold one reference per element; 'gmsh:physical' "
                         "and 'medit:ref' differ (use .vtu)")
    if not keys:
        return [np.zeros(len(c), np.int64) for _, c in cm.cells]
    return [np.asarray(r).reshape(-1).astype(np.int64) for r in cm.cell_data[keys[0]]]


def unsupported(cm: CellMesh) -> list[Part]:
    """What a Medit file cannot hold: cell types without a section, point data other than
    integer ``medit:ref``, cell data other than the references (``gmsh:geometrical`` only
    where the gmsh writers regenerate it from them), field data other than physical names."""
    parts = cells_other_than(cm, tuple(SECTIONS))
    parts += [("point", k) for k, v in cm.point_data.items()
              if k != REF or np.asarray(v).dtype.kind not in "iu" or np.asarray(v).ndim != 1]
    parts += [("cell", k) for k in cm.cell_data if k not in (PHYSICAL, REF, GEOMETRICAL)]
    parts += [("field", k) for k, v in cm.field_data.items()
              if np.asarray(v).size != 2 or np.asarray(v).dtype.kind not in "iu"
              or "\n" in str(k) or "\r" in str(k)]
    geom = cm.cell_data.get(GEOMETRICAL)
    if geom is not None and not parts:
        refs = _element_refs(cm, cm.source or "mesh")
        if not any(all(np.array_equal(np.asarray(g).reshape(-1), r) for g, r in zip(geom, regen))
                   for regen in regenerated_entities(cm, refs)):
            parts.append(("cell", GEOMETRICAL))
    return parts


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None) -> None:
    """Write points, element sections, references and physical names as ASCII Medit.

    Raises
    ------
    WriteError
        Cell types Medit has no section for, point data other than integer
        ``medit:ref``, cell data other than the references (``gmsh:geometrical`` only
        where the gmsh writers regenerate it), field data other than physical names.
    """
    require_text_mode(binary, path, "Medit")
    refuse(path, "Medit", cm, unsupported(cm))
    refs = _element_refs(cm, path)
    pts = np.asarray(cm.points, np.float64)
    n, d = pts.shape
    out = [f"MeshVersionFormatted 2\nDimension {d}\n"]
    for name, value in cm.field_data.items():
        tag, dim = (int(x) for x in np.asarray(value).reshape(-1))
        quoted = '"' + str(name).replace("\\", "\\\\").replace('"', '\\"') + '"'
        out.append(f"{NAME_TAG} {dim} {tag} {quoted}\n")
    point_refs = cm.point_data.get(REF, np.zeros(n, np.int64))
    out.append(f"Vertices\n{n}\n")
    out.append(_rows(pts, point_refs, "%r"))
    for t in dict.fromkeys(t for t, _ in cm.cells):
        idx = [i for i, (u, _) in enumerate(cm.cells) if u == t]
        elems = np.concatenate([np.asarray(cm.cells[i][1], np.int64) for i in idx]) + 1
        out.append(f"{SECTIONS[t]}\n{len(elems)}\n")
        out.append(_rows(elems, np.concatenate([refs[i] for i in idx]), "%d"))
    out.append("End\n")
    with open(path, "w", encoding="utf-8") as fh:
        fh.writelines(out)


def _rows(values: np.ndarray, refs: np.ndarray, fmt: str) -> str:
    """``v1 ... vk ref`` lines in one formatting pass."""
    if not len(values):
        return ""
    k = values.shape[1]
    table = np.empty((len(values), k + 1), dtype=object)
    table[:, :k] = values.tolist()
    table[:, k] = np.asarray(refs, np.int64).tolist()
    row = " ".join([fmt] * k) + " %d\n"
    return (row * len(values)) % tuple(table.ravel().tolist())
