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
from ..kernels.surface import pad3
from ._common import format_rows, quiet
from ._files import UNCAPPED, open_input
from ._loss import Part, cells_other_than, refuse
from .cells import GEOMETRICAL, PHYSICAL, CellMesh, cell_dimension, check_cells, triangle_mesh
from .gmsh_data import holds, write_node_data
from .gmsh_layout import PARAMETRIC, Entity, GmshLayout, Parsed, parse41, write41

if TYPE_CHECKING:  # pragma: no cover
    from ..mesh import TriangleMesh

_quiet = quiet

logger = logging.getLogger(__name__)

VERSIONS = ("2.2", "4.1")
#: the version argument that asks for the input file's version (as None does)
INPUT_VERSION = "input"


# ----------------------------------------------------------------------------- reading

def read(path: Path) -> TriangleMesh:
    """Read a gmsh file as a triangle mesh (triangles, tagged lines, physical tags and
    names); other cell types are refused (see :func:`~.cells.CellMesh.to_triangle_mesh`)."""
    return triangle_mesh(read_cells(path))


def read_cells(path: Path) -> CellMesh:
    """Read everything of a gmsh file: every element block, physical and geometrical
    tags, physical names, node/element data, and the file's layout (version, encoding,
    entities, node classification: :class:`~.gmsh_layout.GmshLayout`) that
    :func:`write_cells` keeps."""
    with open_input(path, UNCAPPED) as fh:
        head = fh.read(4096)
    if not (head.lstrip().startswith(b"$MeshFormat") or head.lstrip().startswith(b"$Comments")):
        raise ReadError(f"{path}: not a gmsh file (no $MeshFormat header)")
    try:
        with open_input(path, UNCAPPED) as fh:
            parsed = parse41(fh)
    except (ValueError, KeyError, OSError, MemoryError, UnicodeDecodeError, IndexError):
        parsed = None  # damaged: meshio's message
    if parsed is not None and parsed.complete and parsed.layout is not None:
        return _build(path, parsed)
    cm = _read_meshio(path)
    layout = parsed.layout if parsed is not None else _header_layout(head)
    if layout is not None and layout.fits(cm):
        cm.layout = layout
    return cm


def _header_layout(head: bytes) -> GmshLayout | None:
    """Version and encoding of a file other than 4.1 (4.0 is written as 4.1)."""
    at = head.find(b"$MeshFormat")
    fields = head[at:].split(b"\n", 2)[1].split() if at >= 0 and head.count(b"\n") > 1 else []
    if len(fields) < 2 or fields[0] not in (b"2.2", b"4", b"4.0"):
        return None
    return GmshLayout("2.2" if fields[0] == b"2.2" else "4.1", fields[1] == b"1")


def _read_meshio(path: Path) -> CellMesh:
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


def _build(path: Path, parsed: Parsed) -> CellMesh:
    """The cell mesh of a parsed file as meshio's gmsh reader builds it (physical tag 0
    where an entity has none), with the file's layout."""
    blocks = parsed.blocks
    cells = [(ctype, e) for ctype, e, _, _ in blocks]
    cell_data = {}
    if any(t is not None for _, _, t, _ in blocks):
        cell_data[PHYSICAL] = [np.full(len(e), 0 if t is None else t, np.int64)
                               for _, e, t, _ in blocks]
    cell_data[GEOMETRICAL] = [np.full(len(e), g, np.int64) for _, e, _, g in blocks]
    field_data = {name: np.array([tag, dim]) for name, (tag, dim) in parsed.names.items()}
    cm = CellMesh(parsed.points, cells, cell_data=cell_data, field_data=field_data,
                  source=str(path), layout=parsed.layout)
    check_cells(cm)
    return _without_trivial_tags(cm)


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
    the physical groups, field data other than ``name: (tag, dim)``, and the parametric
    coordinates of the file's nodes once the nodes moved (``gmsh:parametric``)."""
    from meshio.gmsh.common import _meshio_to_gmsh_type

    parts = cells_other_than(cm, _meshio_to_gmsh_type)
    parts += [("point", k) for k, v in cm.point_data.items() if not holds(k, v, cm.n_points)]
    parts += [("cell", k) for k in cm.cell_data if k not in (PHYSICAL, GEOMETRICAL)]
    for name, value in cm.field_data.items():
        v = np.asarray(value).reshape(-1)
        if v.size != 2 or not np.issubdtype(v.dtype, np.integer):
            parts.append(("field", name))
    layout = _layout(cm)
    if layout is not None and layout.has_parametric() and (
            layout.moved(pad3(cm.points)) or not layout.fits(cm)):
        parts.append(("point", PARAMETRIC))
    return parts


def _layout(cm: CellMesh) -> GmshLayout | None:
    return cm.layout if isinstance(cm.layout, GmshLayout) else None


def _physical_names(cm: CellMesh) -> bytes:
    if not cm.field_data:
        return b""
    lines = []
    for name, value in cm.field_data.items():
        tag, dim = (int(x) for x in np.asarray(value).reshape(-1)[:2])
        quoted = str(name).replace('"', "")
        lines.append(f'{dim} {tag} "{quoted}"')
    return ("$PhysicalNames\n%d\n%s\n$EndPhysicalNames\n" % (len(lines), "\n".join(lines))).encode()


def write(path: Path, mesh: TriangleMesh, binary: bool | None = None,
          version: str | None = None) -> None:
    """Write a triangle mesh (triangles, tagged lines, physical names) as gmsh ``version``."""
    write_cells(path, CellMesh.from_triangle_mesh(mesh), binary, version)


def write_cells(path: Path, cm: CellMesh, binary: bool | None = None,
                version: str | None = None) -> None:
    """Write ``cm`` as gmsh ``version`` ("2.2", "4.1", or None/"input"), binary or not.

    A cell mesh read from a gmsh file is written in that file's version and encoding
    where ``version``/``binary`` are None, and, while its cell blocks and tags are those
    read (:meth:`~.gmsh_layout.GmshLayout.fits`), in the file's layout: its entities
    (bounding boxes updated where the points moved), node and element blocks and tags,
    each node on its entity. Otherwise (other sources, changed cells) 4.1 binary by
    default, entities made from the ``gmsh:geometrical`` tags (one per physical group
    and dimension without them), the nodes in one block on the first entity of the
    highest dimension. Coordinates are exact: binary doubles, or ``repr`` (≤ 17
    significant digits) in ASCII. Every cell block is written in order with its
    ``gmsh:physical`` and ``gmsh:geometrical`` tags (0 and a tag per physical group
    where missing).

    Raises
    ------
    WriteError
        What :func:`unsupported` lists, or (4.1, layout not kept) elements of one
        geometrical entity with different physical tags (gmsh 2.2 can hold them).
    """
    layout = _layout(cm)
    if version is None or version == INPUT_VERSION:
        version = layout.version if layout is not None else "4.1"
    version = str(version)
    if version not in VERSIONS:
        raise WriteError(f"{path}: unsupported gmsh version {version!r}; use one of {VERSIONS}")
    refuse(path, "gmsh", cm, unsupported(cm))
    if binary is None:
        binary = layout.binary if layout is not None else True
    binary = bool(binary)
    pts = pad3(cm.points)
    tags = None
    if version == "4.1":
        if layout is None or layout.version != "4.1" or not layout.fits(cm):
            if layout is not None and layout.version == "4.1":
                logger.info("%s: cells or tags changed; gmsh entities made anew", path)
            layout = _made_layout(_groups(cm, path), pts, path)
        tags = layout.node_tags
    with open(path, "wb") as fh:
        if version == "2.2":
            _write22(fh, cm, _groups(cm, path), binary)
        else:
            write41(fh, layout, pts, _physical_names(cm), binary)
        write_node_data(fh, cm.point_data, binary, tags)


def _write22(fh, cm: CellMesh, groups, binary: bool) -> None:
    from meshio.gmsh.common import _gmsh_to_meshio_type, _meshio_to_gmsh_order

    fh.write(f"$MeshFormat\n2.2 {int(binary)} 8\n".encode())
    if binary:
        fh.write(np.array([1], "<i4").tobytes() + b"\n")
    fh.write(b"$EndMeshFormat\n")
    fh.write(_physical_names(cm))
    pts = pad3(cm.points)
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
        nodes = _meshio_to_gmsh_order(_gmsh_to_meshio_type[etype], elems) + 1
        table = np.column_stack([np.arange(first, first + m), phys, geom, nodes])
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


def _made_layout(groups, pts: np.ndarray, path) -> GmshLayout:
    """A 4.1 layout for cells of no gmsh file (or changed ones): entities and element
    blocks by :func:`_entities`, every node in one block on the first entity of the
    highest dimension, nodes and elements numbered from 1 in order."""
    ents, blocks = _entities(groups, path)
    ndim = max((d for d, _ in ents), default=2)
    first = min((t for d, t in ents if d == ndim), default=1)
    entities = tuple(Entity(d, t, np.zeros(3 if d == 0 else 6), () if p <= 0 else (p,))
                     for (d, t), p in sorted(ents.items()))
    sizes = np.cumsum([0] + [len(e) for *_, e in blocks])
    return GmshLayout(
        "4.1", True, entities, ((ndim, first, len(pts)),), np.arange(1, len(pts) + 1),
        (None,), tuple((d, t, etype) for d, t, etype, _ in blocks),
        tuple(np.arange(a + 1, b + 1) for a, b in zip(sizes[:-1], sizes[1:])),
        tuple(e for *_, e in blocks))


def _entities(groups, path):
    """Entities ``{(dim, tag): physical tag}`` and element blocks
    ``[(dim, entity, type, elements)]`` in order.

    With ``gmsh:geometrical`` tags the entities are those tags (each must carry one
    physical tag); without, one entity per (dimension, physical tag), numbered from 1.
    """
    ents: dict[tuple[int, int], int] = {}
    blocks = []
    for etype, dim, elems, tags, geom in groups:
        phys = np.zeros(len(elems), np.int64) if tags is None else tags
        if geom is None:  # one entity per physical tag of this dimension
            uniq, inv = np.unique(phys, return_inverse=True)
            known = {p: t for (d, t), p in ents.items() if d == dim}
            for p in uniq.tolist():
                if p not in known:
                    known[p] = max((t for d, t in ents if d == dim), default=0) + 1
                    ents[(dim, known[p])] = p
            ent = np.array([known[p] for p in uniq.tolist()], np.int64)[inv]
        else:
            ent = geom
        keys = np.stack([ent, phys], axis=1)
        for e, p in np.unique(keys, axis=0).tolist():
            have = ents.setdefault((dim, e), p)
            if have != p:
                raise WriteError(f"{path}: gmsh 4.1 entity {e} (dimension {dim}) has elements "
                                 f"with physical tags {have} and {p}; use --msh-version 2.2")
        for a, b, e in _runs(ent):
            blocks.append((dim, e, etype, elems[a:b]))
    return ents, blocks


def _runs(tags: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs ``(start, stop, tag)`` of equal consecutive tags."""
    if len(tags) == 0:
        return []
    cut = np.flatnonzero(np.diff(tags)) + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [len(tags)]])
    return [(int(a), int(b), int(tags[a])) for a, b in zip(starts, stops)]
