"""Gmsh files as gmsh writes them: version, encoding, entities and node classification.

:func:`parse41` reads a 4.1 file (ASCII or binary, one numpy parser for both) into
points, element blocks, physical names and a :class:`GmshLayout`: the file's entities
(tags, bounding boxes, physical tags, bounding entities), the entity of each node block
(the node classification, with parametric coordinates) and of each element block, and
the node and element tags. :func:`write41` writes such a layout; :mod:`.gmsh` writes a
cell mesh read from a gmsh file in its own layout (:meth:`GmshLayout.fits`), so that a
file read and written back with new points keeps its version, encoding, entities and
classification, and only coordinates and bounding boxes change.
"""

from __future__ import annotations

import shlex
import warnings
from dataclasses import dataclass, replace

import numpy as np

from .cells import GEOMETRICAL, PHYSICAL

#: the part a writer refuses for parametric node coordinates that no longer fit the nodes
PARAMETRIC = "gmsh:parametric"


@dataclass(frozen=True)
class Entity:
    """One gmsh entity: ``bbox`` (3,) for a point, (6,) min then max otherwise."""

    dim: int
    tag: int
    bbox: np.ndarray
    physical: tuple[int, ...] = ()
    bounding: tuple[int, ...] = ()


@dataclass(frozen=True, eq=False)
class GmshLayout:
    """What a gmsh file holds beyond its cells and data.

    Attributes
    ----------
    version : {"2.2", "4.1"}
    binary : bool
    entities : tuple of Entity (4.1), by dimension then file order
    node_blocks : tuple of (dim, tag, count), in file order (the points' order)
    node_tags : (N,) int64 array, or None (2.2: the writer numbers the nodes)
    parametric : tuple of (count, dim) float arrays or None, one per node block
    element_blocks : tuple of (dim, tag, gmsh type), one per cell block
    element_tags : tuple of (M_b,) int64 arrays
    cells : tuple of (M_b, k) arrays, the cell blocks as read (meshio node order)
    points : (N, 3) array, the points as read
    """

    version: str
    binary: bool
    entities: tuple = ()
    node_blocks: tuple = ()
    node_tags: np.ndarray | None = None
    parametric: tuple = ()
    element_blocks: tuple = ()
    element_tags: tuple = ()
    cells: tuple = ()
    points: np.ndarray | None = None

    def fits(self, cm) -> bool:
        """Whether ``cm`` has this layout's cell blocks (equal connectivity, the physical
        and geometrical tags of their entities) and one point per node."""
        if self.version == "2.2":
            return True
        if self.node_tags is None or len(cm.points) != len(self.node_tags) \
                or len(cm.cells) != len(self.cells):
            return False
        physical = {(e.dim, e.tag): e.physical or (0,) for e in self.entities}
        for i, ((_, c), read, (dim, tag, _)) in enumerate(
                zip(cm.cells, self.cells, self.element_blocks)):
            if c is not read and not np.array_equal(c, read):
                return False
            for key, allowed in ((PHYSICAL, physical.get((dim, tag), (0,))),
                                 (GEOMETRICAL, (tag,))):
                values = cm.cell_data.get(key)
                if values is not None and not np.isin(values[i], allowed).all():
                    return False
        return True

    def moved(self, points: np.ndarray) -> bool:
        """Whether ``points`` (N, 3) differ from the points read."""
        return self.points is None or not np.array_equal(points, self.points)

    def has_parametric(self) -> bool:
        return any(p is not None for p in self.parametric)

    def without(self, parts) -> "GmshLayout":
        """This layout without the parametric coordinates if ``parts`` names them."""
        if ("point", PARAMETRIC) in parts:
            return replace(self, parametric=(None,) * len(self.node_blocks))
        return self


# ----------------------------------------------------------------------------- reading
class _Reader:
    """Numbers from a gmsh file: binary (little-endian, size_t of 8) or ASCII."""

    def __init__(self, fh, binary: bool):
        self.fh, self.binary = fh, binary

    def take(self, dtype: str, count: int) -> np.ndarray:
        count = int(count)
        if count < 0 or count > 1 << 40:
            raise ValueError("bad count")
        if count == 0:
            return np.zeros(0, np.float64 if dtype == "<f8" else np.int64)
        if self.binary:
            a = np.fromfile(self.fh, dtype=dtype, count=count)
        else:
            with warnings.catch_warnings():  # a short read is checked below
                warnings.simplefilter("ignore")
                a = np.fromfile(self.fh, dtype=np.float64 if dtype == "<f8" else np.int64,
                                count=count, sep=" ")
        if len(a) != count:
            raise ValueError("truncated")
        return a

    def int(self, dtype: str = "<i4") -> int:
        return int(self.take(dtype, 1)[0])

    def end(self, name: bytes) -> None:
        line = self.fh.readline()
        while line and not line.strip():
            line = self.fh.readline()
        if line.strip() != b"$End" + name:
            raise ValueError(f"unclosed section ${name.decode()}")


@dataclass
class Parsed:
    """What :func:`parse41` read; ``complete`` is false when the file had sections it
    skipped (data, periodic links...), which meshio then reads; ``layout`` is None when
    node blocks lie on entities that ``$Entities`` does not list (a partitioned mesh)."""

    points: np.ndarray
    blocks: list  # (meshio type, nodes (M, k) int64, physical tag or None, entity tag)
    names: dict  # name → (tag, dim)
    layout: GmshLayout | None
    complete: bool


def parse41(fh) -> Parsed | None:
    """Parse a gmsh 4.1 file, or None when it is another version (or big-endian binary,
    or its element types or node references are meshio's business).

    Raises
    ------
    ValueError
        Truncated or malformed data.
    """
    from meshio.gmsh.common import _gmsh_to_meshio_order, _gmsh_to_meshio_type
    from meshio._common import num_nodes_per_cell

    rd = None
    names: dict = {}
    entities: list[Entity] | None = None
    nodes = elements = None
    complete = True
    while True:
        line = fh.readline()
        if not line:
            break
        section = line.strip()
        if not section:
            continue
        if section == b"$MeshFormat" and rd is None:
            head = fh.readline().split()
            if len(head) < 3 or head[0] != b"4.1" or (head[1] == b"1" and head[2] != b"8"):
                return None
            rd = _Reader(fh, head[1] == b"1")
            if rd.binary and rd.int() != 1:
                return None
            rd.end(b"MeshFormat")
        elif rd is None:
            return None
        elif section == b"$PhysicalNames" and not names:
            for _ in range(int(fh.readline())):
                dim, tag, name = shlex.split(fh.readline().decode())[:3]
                names[name] = (int(tag), int(dim))
            rd.end(b"PhysicalNames")
        elif section == b"$Entities" and entities is None:
            entities = _entities(rd)
        elif section == b"$Nodes" and nodes is None:
            nodes = _nodes(rd)
        elif section == b"$Elements" and nodes is not None and elements is None:
            elements = _elements(rd, _gmsh_to_meshio_type, num_nodes_per_cell)
            if elements is None:
                return None
        elif section.startswith(b"$") and not section.startswith(b"$End"):
            complete = False  # meshio reads what this parser skips
            name = section[1:]
            while (line := fh.readline()) and line.strip() != b"$End" + name:
                pass
        else:
            raise ValueError(f"unexpected line {section[:40]!r}")
    if rd is None or nodes is None or elements is None:
        return None
    points, node_blocks, tags, params = nodes
    index = _node_index(tags)
    physical = None if entities is None else {(e.dim, e.tag): e.physical for e in entities}
    blocks, cells = [], []
    for dim, tag, etype, _, data in elements:
        if index is None:
            idx = data - 1
        else:
            pos = np.clip(np.searchsorted(index[0], data), 0, len(tags) - 1)
            if not np.array_equal(index[0][pos], data):
                return None  # a node that is not in $Nodes: meshio's message
            idx = index[1][pos]
        if idx.size and (idx.min() < 0 or idx.max() >= len(points)):
            return None
        ctype = _gmsh_to_meshio_type[etype]
        idx = np.ascontiguousarray(_gmsh_to_meshio_order(ctype, idx), dtype=np.int64)
        if physical is not None and (dim, tag) not in physical:
            return None
        phys = physical.get((dim, tag)) if physical is not None else None
        blocks.append((ctype, idx, phys[0] if phys else None, tag))
        cells.append(idx)
    known = {(e.dim, e.tag) for e in entities or ()}
    if not all((d, t) in known for d, t, _ in node_blocks):
        return Parsed(points, blocks, names, None, complete)  # partitioned: meshio's
    layout = GmshLayout(
        "4.1", rd.binary, tuple(entities), tuple(node_blocks), tags, tuple(params),
        tuple((d, t, e) for d, t, e, _, _ in elements),
        tuple(etags for _, _, _, etags, _ in elements), tuple(cells), points)
    return Parsed(points, blocks, names, layout, complete)


def _entities(rd: _Reader) -> list[Entity]:
    out = []
    for dim, count in enumerate(rd.take("<u8", 4).tolist()):
        for _ in range(count):
            tag = rd.int()
            bbox = rd.take("<f8", 3 if dim == 0 else 6)
            phys = tuple(rd.take("<i4", rd.int("<u8")).tolist())
            bounding = tuple(rd.take("<i4", rd.int("<u8")).tolist()) if dim else ()
            out.append(Entity(dim, tag, bbox, phys, bounding))
    rd.end(b"Entities")
    return out


def _nodes(rd: _Reader):
    n_blocks, n_nodes = rd.take("<u8", 4)[:2].tolist()
    coords, blocks, tags, params = [], [], [], []
    for _ in range(n_blocks):
        dim, tag, parametric = rd.take("<i4", 3).tolist()
        m = rd.int("<u8")
        tags.append(rd.take("<u8", m).astype(np.int64))
        width = 3 + (dim if parametric else 0)
        xyz = rd.take("<f8", m * width).reshape(m, width)
        coords.append(xyz[:, :3])
        params.append(np.ascontiguousarray(xyz[:, 3:]) if parametric else None)
        blocks.append((dim, tag, m))
    rd.end(b"Nodes")
    if sum(len(t) for t in tags) != n_nodes:
        raise ValueError("node count")
    points = np.concatenate(coords) if coords else np.zeros((0, 3))
    all_tags = np.concatenate(tags) if tags else np.zeros(0, np.int64)
    return np.ascontiguousarray(points), blocks, all_tags, params


def _elements(rd: _Reader, types: dict, nodes_per_cell: dict):
    n_blocks = rd.int("<u8")
    rd.take("<u8", 3)
    out = []
    for _ in range(n_blocks):
        dim, tag, etype = rd.take("<i4", 3).tolist()
        m = rd.int("<u8")
        if etype not in types or types[etype] not in nodes_per_cell:
            return None
        k = nodes_per_cell[types[etype]]
        data = rd.take("<u8", m * (1 + k)).astype(np.int64).reshape(m, 1 + k)
        out.append((dim, tag, etype, data[:, 0].copy(), data[:, 1:]))
    rd.end(b"Elements")
    return out


def _node_index(tags: np.ndarray):
    """None when the tags are ``1..N`` in order, else (sorted tags, their positions)."""
    if np.array_equal(tags, np.arange(1, len(tags) + 1)):
        return None
    order = np.argsort(tags, kind="stable")
    ordered = tags[order]
    if len(ordered) > 1 and not np.all(np.diff(ordered)):
        raise ValueError("repeated node tag")
    return ordered, order


# ----------------------------------------------------------------------------- writing
def bounding_boxes(layout: GmshLayout, points: np.ndarray) -> list[np.ndarray]:
    """Each entity's bounding box at ``points`` (N, 3): the nodes classified on it and
    those of its elements; the box read where it has neither, or where nothing moved."""
    if not layout.moved(points):
        return [e.bbox for e in layout.entities]
    used: dict[tuple[int, int], list[np.ndarray]] = {}
    start = 0
    for dim, tag, m in layout.node_blocks:
        used.setdefault((dim, tag), []).append(np.arange(start, start + m))
        start += m
    for (dim, tag, _), cells in zip(layout.element_blocks, layout.cells):
        used.setdefault((dim, tag), []).append(np.asarray(cells).ravel())
    out = []
    for e in layout.entities:
        idx = used.get((e.dim, e.tag))
        sel = points[np.unique(np.concatenate(idx))] if idx else points[:0]
        if not len(sel):
            out.append(e.bbox)
        elif e.dim == 0:
            out.append(sel[0])
        else:
            out.append(np.concatenate([sel.min(axis=0), sel.max(axis=0)]))
    return out


def write41(fh, layout: GmshLayout, points: np.ndarray, names: bytes, binary: bool) -> None:
    """Write ``$MeshFormat``, ``names`` (the ``$PhysicalNames`` section), ``$Entities``,
    ``$Nodes`` and ``$Elements`` of ``layout`` with the coordinates ``points`` (N, 3)."""
    from meshio.gmsh.common import _meshio_to_gmsh_order, _gmsh_to_meshio_type

    fh.write(f"$MeshFormat\n4.1 {int(binary)} 8\n".encode())
    if binary:
        fh.write(np.array([1], "<i4").tobytes() + b"\n")
    fh.write(b"$EndMeshFormat\n" + names)
    out = _Out(fh, binary)
    fh.write(b"$Entities\n")
    out.row("<u8", [sum(e.dim == d for e in layout.entities) for d in range(4)])
    out.newline()
    for e, bbox in zip(layout.entities, bounding_boxes(layout, points)):
        out.row("<i4", [e.tag])
        out.row("<f8", bbox)
        out.row("<u8", [len(e.physical)], "<i4", e.physical)
        if e.dim:
            out.row("<u8", [len(e.bounding)], "<i4", e.bounding)
        out.newline()
    out.close(b"Entities")
    tags = layout.node_tags
    fh.write(b"$Nodes\n")
    out.row("<u8", [len(layout.node_blocks), len(tags), _min(tags), _max(tags)])
    out.newline()
    start = 0
    for (dim, tag, m), par in zip(layout.node_blocks, layout.parametric):
        out.row("<i4", [dim, tag, int(par is not None)], "<u8", [m])
        out.newline()
        out.table("<u8", tags[start:start + m, None])
        xyz = points[start:start + m]
        out.table("<f8", xyz if par is None else np.column_stack([xyz, par]))
        start += m
    out.close(b"Nodes")
    etags = np.concatenate(layout.element_tags) if layout.element_tags else tags[:0]
    fh.write(b"$Elements\n")
    cells = layout.cells
    out.row("<u8", [len(cells), len(etags), _min(etags), _max(etags)])
    out.newline()
    for (dim, tag, etype), et, c in zip(layout.element_blocks, layout.element_tags, cells):
        out.row("<i4", [dim, tag, etype], "<u8", [len(c)])
        out.newline()
        nodes = tags[_meshio_to_gmsh_order(_gmsh_to_meshio_type[etype], np.asarray(c))]
        out.table("<u8", np.column_stack([et, nodes]))
    out.close(b"Elements")


def _min(a: np.ndarray) -> int:
    return int(a.min()) if len(a) else 0


def _max(a: np.ndarray) -> int:
    return int(a.max()) if len(a) else 0


class _Out:
    """Rows of numbers in a gmsh file: binary records, or ASCII (``repr`` floats, exact)."""

    def __init__(self, fh, binary: bool):
        self.fh, self.binary = fh, binary
        self.line: list[str] = []

    def row(self, *pairs) -> None:
        """Append ``dtype, values`` pairs to the current record/line."""
        for dtype, values in zip(pairs[::2], pairs[1::2]):
            if self.binary:
                self.fh.write(np.asarray(values).astype(dtype).tobytes())
            else:
                fmt = repr if dtype == "<f8" else str
                self.line += [fmt(float(v) if dtype == "<f8" else int(v)) for v in values]

    def newline(self) -> None:
        if not self.binary:
            self.fh.write((" ".join(self.line) + "\n").encode())
            self.line = []

    def table(self, dtype: str, rows: np.ndarray) -> None:
        """One row per line (ASCII) or the rows' bytes (binary)."""
        if self.binary:
            self.fh.write(np.ascontiguousarray(rows, dtype=dtype).tobytes())
            return
        from ._common import format_rows

        self.fh.write(format_rows(rows, "%r" if dtype == "<f8" else "%d").encode())

    def close(self, name: bytes) -> None:
        if self.line:
            self.newline()
        self.fh.write(b"\n$End" + name + b"\n" if self.binary else b"$End" + name + b"\n")
