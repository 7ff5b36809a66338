"""Gmsh ``.msh`` files: read 2.2/4.0/4.1 (ASCII and binary), write 2.2 and 4.1.

Binary 4.1 files of the common shape (the sections ``$MeshFormat``, ``$PhysicalNames``,
``$Entities``, ``$Nodes``, ``$Elements``; node tags ``1..N`` in order; physical tags on
every element block or on none) are read by :func:`_read_binary41`, a direct numpy
parser of the blocks (it skips meshio's node-tag map and per-block tag arrays).
Everything else goes through meshio's gmsh reader (called directly: ``meshio.read`` would
try the ansys reader first and calls ``sys.exit`` on failure), and so does any file the
direct parser finds unusual or damaged, so that results and error messages are meshio's.

Writing is our own, vectorized, so that physical tags of triangles and boundary lines are
always written (meshio 5.3.5 under numpy 2 writes ASCII files with cell data it cannot
read back, and its 4.1 writer drops physical tags without ``gmsh:dim_tags``). Element
blocks follow runs of equal tags, so the order of triangles and lines in the file is the
order in the mesh. Float point data is written as ``$NodeData`` (:mod:`.gmsh_data`).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ReadError, WriteError
from ._common import format_rows, quiet
from ._loss import Part, cells_other_than, refuse
from .gmsh_data import holds, write_node_data
from ._files import UNCAPPED, open_input
from .cells import (GEOMETRICAL, NODES_PER_CELL, PHYSICAL, CellMesh, cell_dimension, check_cells,
                    triangle_mesh)

if TYPE_CHECKING:  # pragma: no cover
    from ..mesh import TriangleMesh

_quiet = quiet

logger = logging.getLogger(__name__)

VERSIONS = ("2.2", "4.1")


# ----------------------------------------------------------------------------- reading
#: gmsh element type → meshio cell type, for the types the direct parser reads
GMSH_TO_MESHIO = {15: "vertex", 1: "line", 2: "triangle", 3: "quad", 4: "tetra",
                  5: "hexahedron", 6: "wedge", 7: "pyramid", 8: "line3", 9: "triangle6",
                  10: "quad9", 11: "tetra10", 16: "quad8"}


def read(path: Path) -> TriangleMesh:
    """Read a gmsh file as a triangle mesh (triangles, tagged lines, physical tags and
    names); other cell types are refused (see :func:`~.cells.CellMesh.to_triangle_mesh`)."""
    return triangle_mesh(read_cells(path))


def read_cells(path: Path) -> CellMesh:
    """Read everything of a gmsh file: every element block, physical and geometrical
    tags, physical names, and node/element data (through meshio)."""
    with open_input(path, UNCAPPED) as fh:
        head = fh.read(64).lstrip()
    if not (head.startswith(b"$MeshFormat") or head.startswith(b"$Comments")):
        raise ReadError(f"{path}: not a gmsh file (no $MeshFormat header)")
    if head.startswith(b"$MeshFormat\n4.1 1 8\n"):
        with open_input(path, UNCAPPED) as fh:
            parsed = _read_binary41(fh)
        if parsed is not None:
            return _build(path, *parsed)
    from meshio.gmsh.main import read_buffer

    try:
        with _quiet(), open_input(path, UNCAPPED) as fh:
            m = read_buffer(fh)
    except (Exception, SystemExit) as exc:  # meshio may sys.exit on failure
        detail = str(exc) or type(exc).__name__
        if isinstance(exc, (ValueError, EOFError, IndexError)) or "buffer" in detail:
            detail = f"truncated or corrupt ({detail})"
        raise ReadError(f"{path}: cannot read gmsh file: {detail}") from None
    for key in (PHYSICAL, GEOMETRICAL):
        if key in m.cell_data and len(m.cell_data[key]) != len(m.cells):
            raise ReadError(f"{path}: physical tags on some element entities only "
                            "(cannot tell which elements they belong to)")
    try:
        cm = CellMesh.from_meshio(m, source=str(path))
    except (ValueError, TypeError) as exc:
        raise ReadError(f"{path}: cannot read gmsh file: {exc}") from None
    check_cells(cm)
    return _without_trivial_tags(cm)


def _without_trivial_tags(cm: CellMesh) -> CellMesh:
    """Leave out tags that hold nothing our writer would not write again: physical tags
    that are all 0 (no group), then geometrical tags that are all 1 (one entity)."""
    def all_equal(key, value):
        return all(not len(a) or (np.asarray(a) == value).all() for a in cm.cell_data[key])

    if PHYSICAL in cm.cell_data and all_equal(PHYSICAL, 0):
        del cm.cell_data[PHYSICAL]
    if PHYSICAL not in cm.cell_data and GEOMETRICAL in cm.cell_data and all_equal(GEOMETRICAL, 1):
        del cm.cell_data[GEOMETRICAL]
    return cm


def _build(path: Path, points, blocks, names: dict) -> CellMesh:
    """The cell mesh of parsed element ``blocks`` ``[(type, nodes, phys, entity)]`` as
    meshio's gmsh reader builds it (physical tag 0 where an entity has none)."""
    cells = [(GMSH_TO_MESHIO[etype], e) for etype, e, _, _ in blocks]
    cell_data = {}
    if any(t is not None for _, _, t, _ in blocks):
        cell_data[PHYSICAL] = [np.full(len(e), 0 if t is None else t, np.int64)
                               for _, e, t, _ in blocks]
    cell_data[GEOMETRICAL] = [np.full(len(e), g, np.int64) for _, e, _, g in blocks]
    field_data = {name: np.array([tag, dim]) for name, (tag, dim) in names.items()}
    cm = CellMesh(points, cells, cell_data=cell_data, field_data=field_data, source=str(path))
    check_cells(cm)
    return _without_trivial_tags(cm)


def _read_binary41(fh):
    """:func:`_parse_binary41`, or None where it fails (truncated or damaged data)."""
    try:
        return _parse_binary41(fh)
    except (ValueError, KeyError, OSError, MemoryError, UnicodeDecodeError, IndexError):
        return None


def _parse_binary41(fh):
    """Parse a binary gmsh 4.1 file (size_t of 8 bytes, little-endian) with numpy.

    Returns
    -------
    (points (N, 3) float64, blocks, names) or None
        ``blocks`` lists ``(element type, nodes (M, k) int64 0-based, physical tag or
        None, entity tag)`` in file order, ``names`` is ``{name: (tag, dim)}``. None when
        the file has anything this parser does not handle exactly like meshio (other
        sections, sparse or unordered node tags, parametric nodes, element nodes out of
        range, element types outside :data:`GMSH_TO_MESHIO`): the caller then reads it
        with meshio.

    Raises
    ------
    ValueError
        Truncated or malformed data.
    """
    import shlex

    def take(dtype: str, count: int) -> np.ndarray:
        if count < 0 or count > 1 << 40:
            raise ValueError("bad count")
        a = np.fromfile(fh, dtype=dtype, count=count)
        if len(a) != count:
            raise ValueError("truncated")
        return a

    def end(name: bytes) -> None:
        line = fh.readline()
        if line.strip():
            raise ValueError("unexpected data")
        if fh.readline().strip() != b"$End" + name:
            raise ValueError("unclosed section")

    if fh.readline().strip() != b"$MeshFormat" or fh.readline().split() != [b"4.1", b"1", b"8"]:
        return None
    if take("<i4", 1)[0] != 1:
        return None
    end(b"MeshFormat")
    names: dict = {}
    physical: dict | None = None
    points = None
    blocks = None
    while True:
        line = fh.readline()
        if not line:
            break
        section = line.strip()
        if not section:
            continue
        if section == b"$PhysicalNames" and not names:
            for _ in range(int(fh.readline())):
                dim, tag, name = shlex.split(fh.readline().decode())[:3]
                names[name] = (int(tag), int(dim))
            if fh.readline().strip() != b"$EndPhysicalNames":
                return None
        elif section == b"$Entities" and physical is None:
            physical = {}
            for dim, count in enumerate(take("<u8", 4).tolist()):
                for _ in range(count):
                    tag = int(take("<i4", 1)[0])
                    take("<f8", 3 if dim == 0 else 6)
                    phys = take("<i4", int(take("<u8", 1)[0])).tolist()
                    physical[(dim, tag)] = phys
                    if dim > 0:
                        take("<i4", int(take("<u8", 1)[0]))
            end(b"Entities")
        elif section == b"$Nodes" and points is None:
            n_blocks, n_nodes = take("<u8", 4)[:2].tolist()
            parts = []
            first_tag = 1
            for _ in range(n_blocks):
                _, _, parametric = take("<i4", 3).tolist()
                m = int(take("<u8", 1)[0])
                if parametric:
                    return None
                if not np.array_equal(take("<u8", m), np.arange(first_tag, first_tag + m)):
                    return None  # sparse or unordered node tags: meshio maps them
                first_tag += m
                parts.append(take("<f8", 3 * m).reshape(m, 3))
            if first_tag - 1 != n_nodes:
                return None
            points = parts[0] if len(parts) == 1 else np.concatenate(parts)
            end(b"Nodes")
        elif section == b"$Elements" and points is not None and blocks is None:
            n_blocks = int(take("<u8", 4)[0])
            blocks = []
            for _ in range(n_blocks):
                dim, tag, etype = take("<i4", 3).tolist()
                m = int(take("<u8", 1)[0])
                if etype not in GMSH_TO_MESHIO:
                    return None
                k = NODES_PER_CELL[GMSH_TO_MESHIO[etype]]
                data = take("<u8", m * (1 + k)).reshape(m, 1 + k)[:, 1:]
                if m and (int(data.min()) < 1 or int(data.max()) > len(points)):
                    return None  # meshio's node-tag map decides what that means
                nodes = np.subtract(data, 1, dtype=np.int64, casting="unsafe")
                if physical is not None and (dim, tag) not in physical:
                    return None
                phys = physical.get((dim, tag)) if physical is not None else None
                blocks.append((etype, nodes, phys[0] if phys else None, tag))
            end(b"Elements")
        else:
            return None  # any other section (or a repeated one): meshio's business
    if points is None or blocks is None:
        return None
    return points, blocks, names


# ----------------------------------------------------------------------------- writing
def _gmsh_type(cell_type: str, path) -> int:
    from meshio.gmsh.common import _meshio_to_gmsh_type

    if cell_type not in _meshio_to_gmsh_type:
        raise WriteError(f"{path}: gmsh files cannot hold {cell_type} cells")
    return int(_meshio_to_gmsh_type[cell_type])


def _groups(cm: CellMesh, path):
    """Element groups ``(gmsh type, dim, elements (M, k), phys (M,) or None, geom or None)``."""
    phys = cm.cell_data.get(PHYSICAL)
    geom = cm.cell_data.get(GEOMETRICAL)
    out = []
    for i, (t, c) in enumerate(cm.cells):
        p = None if phys is None else np.asarray(phys[i]).reshape(-1).astype(np.int64)
        g = None if geom is None else np.asarray(geom[i]).reshape(-1).astype(np.int64)
        out.append((_gmsh_type(t, path), cell_dimension(t), np.asarray(c), p, g))
    return out


def unsupported(cm: CellMesh) -> list[Part]:
    """What our gmsh writer cannot hold: cell types without a gmsh element (polygon),
    point data other than float views (:func:`.gmsh_data.holds`), cell data other than
    the physical groups, field data other than ``name: (tag, dim)``."""
    from meshio.gmsh.common import _meshio_to_gmsh_type

    parts = cells_other_than(cm, _meshio_to_gmsh_type)
    parts += [("point", k) for k, v in cm.point_data.items() if not holds(k, v, cm.n_points)]
    parts += [("cell", k) for k in cm.cell_data if k not in (PHYSICAL, GEOMETRICAL)]
    for name, value in cm.field_data.items():
        v = np.asarray(value).reshape(-1)
        if v.size != 2 or not np.issubdtype(v.dtype, np.integer):
            parts.append(("field", name))
    return parts


def _physical_names(cm: CellMesh) -> bytes:
    if not cm.field_data:
        return b""
    lines = []
    for name, value in cm.field_data.items():
        tag, dim = (int(x) for x in np.asarray(value).reshape(-1)[:2])
        quoted = str(name).replace('"', "")
        lines.append(f'{dim} {tag} "{quoted}"')
    return ("$PhysicalNames\n%d\n%s\n$EndPhysicalNames\n" % (len(lines), "\n".join(lines))).encode()


def write(path: Path, mesh: TriangleMesh, binary: bool | None = None, version: str = "4.1") -> None:
    """Write a triangle mesh (triangles, tagged lines, physical names) as gmsh ``version``."""
    write_cells(path, CellMesh.from_triangle_mesh(mesh), binary, version)


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None,
                version: str = "4.1") -> None:
    """Write ``cm`` as gmsh ``version`` ("2.2" or "4.1"), binary unless ``binary=False``.

    Coordinates are exact: binary doubles, or ``repr`` (≤ 17 significant digits) in ASCII.
    Every cell block is written in order with its ``gmsh:physical`` and
    ``gmsh:geometrical`` tags (0 and a tag per physical group where missing).

    Raises
    ------
    WriteError
        What :func:`unsupported` lists, or (4.1) elements of one geometrical entity with different
        physical tags (gmsh 2.2 can hold them).
    """
    version = str(version)
    if version not in VERSIONS:
        raise WriteError(f"{path}: unsupported gmsh version {version!r}; use one of {VERSIONS}")
    refuse(path, "gmsh", cm, unsupported(cm))
    groups = _groups(cm, path)
    binary = True if binary is None else bool(binary)
    if version == "4.1":
        ents, blocks = _entities(groups, _points3d(cm), path)
    with open(path, "wb") as fh:
        if version == "2.2":
            _write22(fh, cm, groups, binary)
        else:
            _write41(fh, cm, ents, blocks, binary)
        write_node_data(fh, cm.point_data, binary)


def _header(fh, version: str, binary: bool) -> None:
    fh.write(f"$MeshFormat\n{version} {int(binary)} 8\n".encode())
    if binary:
        fh.write(np.array([1], "<i4").tobytes() + b"\n")
    fh.write(b"$EndMeshFormat\n")


def _points3d(cm: CellMesh) -> np.ndarray:
    p = np.asarray(cm.points, np.float64)
    if p.shape[1] == 3:
        return np.ascontiguousarray(p)
    return np.column_stack([p, np.zeros(len(p))])


def _write22(fh, cm: CellMesh, groups, binary: bool) -> None:
    _header(fh, "2.2", binary)
    fh.write(_physical_names(cm))
    pts = _points3d(cm)
    n = len(pts)
    fh.write(f"$Nodes\n{n}\n".encode())
    ids = np.arange(1, n + 1)
    if binary:
        rec = np.empty(n, dtype=[("i", "<i4"), ("x", "<f8", (3,))])
        rec["i"] = ids
        rec["x"] = pts
        fh.write(rec.tobytes())
        fh.write(b"\n")
    else:
        rows = zip(ids.tolist(), *pts.T.tolist())
        fh.write("".join(map("%d %r %r %r\n".__mod__, rows)).encode())
    fh.write(b"$EndNodes\n")
    total = sum(len(e) for _, _, e, _, _ in groups)
    fh.write(f"$Elements\n{total}\n".encode())
    first = 1
    for etype, _, elems, tags, geom in groups:
        m, k = elems.shape
        phys = np.zeros(m, np.int64) if tags is None else tags
        if geom is None:
            geom = np.where(phys > 0, phys, 1)
        table = np.column_stack([np.arange(first, first + m), phys, geom, elems + 1])
        first += m
        if binary:
            fh.write(np.array([etype, m, 2], "<i4").tobytes())
            fh.write(table.astype("<i4").tobytes())
        else:
            cols = np.column_stack([table[:, :1], np.full((m, 1), etype), np.full((m, 1), 2),
                                    table[:, 1:]])
            fh.write(format_rows(cols, "%d").encode())
    if binary:
        fh.write(b"\n")
    fh.write(b"$EndElements\n")


def _entities(groups, pts: np.ndarray, path):
    """Entities ``{dim: [(tag, phys or None, bbox)]}`` and element blocks
    ``[(dim, entity, type, elements)]`` in order.

    With ``gmsh:geometrical`` tags the entities are those tags (each must carry one
    physical tag); without, one entity per (dimension, physical tag), numbered from 1.
    """
    ents: dict[int, dict[int, list]] = {0: {}, 1: {}, 2: {}, 3: {}}
    blocks = []
    for etype, dim, elems, tags, geom in groups:
        phys = np.zeros(len(elems), np.int64) if tags is None else tags
        if geom is None:  # one entity per physical tag of this dimension
            uniq, inv = np.unique(phys, return_inverse=True)
            known = {p: e for e, (p, _) in ents[dim].items()}
            ent_of = {}
            for t in uniq.tolist():
                if t not in known:
                    known[t] = max(ents[dim], default=0) + 1
                    ents[dim][known[t]] = [t, []]
                ent_of[t] = known[t]
            ent = np.array([ent_of[t] for t in uniq.tolist()], np.int64)[inv]
        else:
            ent = geom
        keys = np.stack([ent, phys], axis=1)
        for e, p in np.unique(keys, axis=0).tolist():
            have = ents[dim].setdefault(e, [p, []])
            if have[0] != p:
                raise WriteError(f"{path}: gmsh 4.1 entity {e} (dimension {dim}) has elements "
                                 f"with physical tags {have[0]} and {p}; use --msh-version 2.2")
        for a, b, e in _runs(ent):
            blocks.append((dim, e, etype, elems[a:b]))
            ents[dim][e][1].append(elems[a:b])
    coords = np.ascontiguousarray(pts.T)
    out: dict[int, list] = {}
    for dim, table in ents.items():
        out[dim] = []
        for e, (p, parts) in sorted(table.items()):
            used = np.zeros(len(pts), bool)
            for part in parts:
                used[part.ravel()] = True
            sel = coords[:, used]
            if sel.shape[1]:
                bbox = np.concatenate([sel.min(axis=1), sel.max(axis=1)])
            else:
                bbox = np.zeros(6)
            out[dim].append((e, p if p > 0 else None, bbox))
    return out, blocks


def _runs(tags: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs ``(start, stop, tag)`` of equal consecutive tags."""
    if len(tags) == 0:
        return []
    cut = np.flatnonzero(np.diff(tags)) + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [len(tags)]])
    return [(int(a), int(b), int(tags[a])) for a, b in zip(starts, stops)]


def _write41(fh, cm: CellMesh, ents, blocks, binary: bool) -> None:
    _header(fh, "4.1", binary)
    fh.write(_physical_names(cm))
    pts = _points3d(cm)
    n = len(pts)
    counts = [len(ents[d]) for d in range(4)]
    fh.write(b"$Entities\n")
    if binary:
        fh.write(np.array(counts, "<u8").tobytes())
    else:
        fh.write(" ".join(map(str, counts)).encode() + b"\n")
    for dim in range(4):
        for tag, phys, bbox in ents[dim]:
            box = bbox[:3] if dim == 0 else bbox
            if binary:
                fh.write(np.array([tag], "<i4").tobytes() + box.astype("<f8").tobytes())
                if phys is None:
                    fh.write(np.array([0], "<u8").tobytes())
                else:
                    fh.write(np.array([1], "<u8").tobytes() + np.array([phys], "<i4").tobytes())
                if dim > 0:
                    fh.write(np.array([0], "<u8").tobytes())
            else:
                text = " ".join(repr(float(v)) for v in box)
                ph = "0" if phys is None else f"1 {phys}"
                fh.write(f"{tag} {text} {ph}{' 0' if dim > 0 else ''}\n".encode())
    if binary:
        fh.write(b"\n")
    fh.write(b"$EndEntities\n")
    # all nodes in one block on the first entity of the highest dimension
    ndim = max((d for d in range(4) if ents[d]), default=2)
    first_ent = ents[ndim][0][0] if ents[ndim] else 1
    fh.write(b"$Nodes\n")
    if binary:
        fh.write(np.array([1, n, 1, n], "<u8").tobytes())
        fh.write(np.array([ndim, first_ent, 0], "<i4").tobytes() + np.array([n], "<u8").tobytes())
        fh.write(np.arange(1, n + 1, dtype="<u8").tobytes())
        fh.write(pts.astype("<f8").tobytes())
        fh.write(b"\n")
    else:
        fh.write(f"1 {n} 1 {n}\n{ndim} {first_ent} 0 {n}\n".encode())
        fh.write(format_rows(np.arange(1, n + 1)[:, None], "%d").encode())
        fh.write(format_rows(pts, "%r").encode())
    fh.write(b"$EndNodes\n")
    total = sum(len(b[3]) for b in blocks)
    fh.write(b"$Elements\n")
    if binary:
        fh.write(np.array([len(blocks), total, 1, total], "<u8").tobytes())
    else:
        fh.write(f"{len(blocks)} {total} 1 {total}\n".encode())
    first = 1
    for dim, ent, etype, elems in blocks:
        m = len(elems)
        table = np.empty((m, 1 + elems.shape[1]), "<u8" if binary else np.int64)
        table[:, 0] = np.arange(first, first + m)
        np.add(elems, 1, out=table[:, 1:], casting="unsafe")
        first += m
        if binary:
            fh.write(np.array([dim, ent, etype], "<i4").tobytes() + np.array([m], "<u8").tobytes())
            table.tofile(fh)
        else:
            fh.write(f"{dim} {ent} {etype} {m}\n".encode())
            fh.write(format_rows(table, "%d").encode())
    if binary:
        fh.write(b"\n")
    fh.write(b"$EndElements\n")
