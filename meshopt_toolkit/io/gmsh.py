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
order in the mesh.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..errors import ReadError, WriteError
from ..mesh import TriangleMesh
from ._common import build_mesh, format_rows, points3d

logger = logging.getLogger(__name__)

TRIANGLE, LINE = 2, 1  # gmsh element types
VERSIONS = ("2.2", "4.1")


# ----------------------------------------------------------------------------- reading
def read(path: Path) -> TriangleMesh:
    """Read a gmsh file; triangles, tagged lines, physical tags and names are kept."""
    from meshio.gmsh import read as meshio_gmsh_read

    from ..conversions import from_meshio

    with open(path, "rb") as fh:
        head = fh.read(64).lstrip()
    if not (head.startswith(b"$MeshFormat") or head.startswith(b"$Comments")):
        raise ReadError(f"{path}: not a gmsh file (no $MeshFormat header)")
    if head.startswith(b"$MeshFormat\n4.1 1 8\n"):
        with open(path, "rb") as fh:
            parsed = _read_binary41(fh)
        if parsed is not None:
            return _build(path, *parsed)
    try:
        m = meshio_gmsh_read(path)
    except (Exception, SystemExit) as exc:  # meshio may sys.exit on failure
        detail = str(exc) or type(exc).__name__
        if isinstance(exc, (ValueError, EOFError, IndexError)) or "buffer" in detail:
            detail = f"truncated or corrupt ({detail})"
        raise ReadError(f"{path}: cannot read gmsh file: {detail}") from None
    return from_meshio(m, source=str(path))


def _build(path: Path, points, blocks, names: dict) -> TriangleMesh:
    """The mesh of parsed element ``blocks`` ``[(type, nodes (M, k) int64, phys or None)]``,
    as :func:`~meshopt_toolkit.conversions.from_meshio` builds it from meshio's reading."""
    from meshio.gmsh.common import _gmsh_to_meshio_type

    tris = [(e, t) for etype, e, t in blocks if etype == TRIANGLE]
    lines = [(e, t) for etype, e, t in blocks if etype == LINE]
    skipped = {_gmsh_to_meshio_type[etype] for etype, _, _ in blocks} - {"triangle", "line"}
    if skipped:
        logger.info("%s: skipped cells of type %s", path, ", ".join(sorted(skipped)))
    triangles = tris[0][0] if len(tris) == 1 else np.concatenate([e for e, _ in tris])
    tags: dict = {"triangle_tags": None, "tag_names": names}
    if tris[0][1] is not None:  # every block has a physical tag, or none has
        tt = np.concatenate([np.full(len(e), t, np.int64) for e, t in tris])
        if np.any(tt):
            tags["triangle_tags"] = tt
    if lines:
        tags["lines"] = np.concatenate([e for e, _ in lines])
        tags["line_tags"] = np.concatenate(
            [np.full(len(e), 0 if t is None else t, np.int64) for e, t in lines]
        )
    return build_mesh(points, triangles, source=path, **tags)


def _read_binary41(fh):
    """:func:`_parse_binary41`, or None where it fails (truncated or damaged data)."""
    try:
        return _parse_binary41(fh)
    except (ValueError, KeyError, OSError, MemoryError, UnicodeDecodeError):
        return None


def _parse_binary41(fh):
    """Parse a binary gmsh 4.1 file (size_t of 8 bytes, little-endian) with numpy.

    Returns
    -------
    (points (N, 3) float64, blocks, names) or None
        ``blocks`` lists ``(element type, nodes (M, k) int64 0-based, physical tag or
        None)`` in file order, ``names`` is ``{name: (tag, dim)}``. None when the file
        has anything this parser does not handle exactly like meshio (other sections,
        sparse or unordered node tags, parametric nodes, element nodes out of range,
        physical tags on some blocks only, no triangle): the caller then reads it with
        meshio.

    Raises
    ------
    ValueError
        Truncated or malformed data.
    """
    import shlex

    from meshio._common import num_nodes_per_cell
    from meshio.gmsh.common import _gmsh_to_meshio_type

    def take(dtype: str, count: int) -> np.ndarray:
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
                if etype not in _gmsh_to_meshio_type:
                    return None
                k = num_nodes_per_cell[_gmsh_to_meshio_type[etype]]
                data = take("<u8", m * (1 + k)).reshape(m, 1 + k)[:, 1:]
                if etype in (TRIANGLE, LINE):
                    if m and (int(data.min()) < 1 or int(data.max()) > len(points)):
                        return None  # meshio's node-tag map decides what that means
                    nodes = np.subtract(data, 1, dtype=np.int64, casting="unsafe")
                else:
                    nodes = np.zeros((0, k), np.int64)
                if physical is not None and (dim, tag) not in physical:
                    return None
                phys = physical.get((dim, tag)) if physical is not None else None
                blocks.append((etype, nodes, phys[0] if phys else None))
            end(b"Elements")
        else:
            return None  # any other section (or a repeated one): meshio's business
    if points is None or not blocks or not any(b[0] == TRIANGLE for b in blocks):
        return None
    if len({b[2] is None for b in blocks}) > 1:
        return None  # physical tags on some blocks only: keep meshio's reading of that
    return points, blocks, names


# ----------------------------------------------------------------------------- writing
def _runs(tags: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs ``(start, stop, tag)`` of equal consecutive tags."""
    if len(tags) == 0:
        return []
    cut = np.flatnonzero(np.diff(tags)) + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [len(tags)]])
    return [(int(a), int(b), int(tags[a])) for a, b in zip(starts, stops)]


def _groups(mesh: TriangleMesh):
    """Element groups ``(type, elements (M, k), tags (M,) or None)``: lines, then triangles."""
    out = []
    if mesh.lines is not None:
        out.append((LINE, mesh.lines, mesh.line_tags))
    out.append((TRIANGLE, mesh.triangles, mesh.triangle_tags))
    return out


def _physical_names(mesh: TriangleMesh) -> bytes:
    names = mesh.tag_names
    if not names:
        return b""
    lines = [f"{int(dim)} {int(tag)} \"{name}\"" for name, (tag, dim) in names.items()]
    return ("$PhysicalNames\n%d\n%s\n$EndPhysicalNames\n" % (len(lines), "\n".join(lines))).encode()


def write(path: Path, mesh: TriangleMesh, binary: bool | None = None, version: str = "4.1") -> None:
    """Write ``mesh`` as gmsh ``version`` ("2.2" or "4.1"), binary unless ``binary=False``.

    Coordinates are exact: binary doubles, or ``repr`` (≤ 17 significant digits) in ASCII.
    """
    version = str(version)
    if version not in VERSIONS:
        raise WriteError(f"{path}: unsupported gmsh version {version!r}; use one of {VERSIONS}")
    binary = True if binary is None else bool(binary)
    with open(path, "wb") as fh:
        if version == "2.2":
            _write22(fh, mesh, binary)
        else:
            _write41(fh, mesh, binary)


def _header(fh, version: str, binary: bool) -> None:
    fh.write(f"$MeshFormat\n{version} {int(binary)} 8\n".encode())
    if binary:
        fh.write(np.array([1], "<i4").tobytes() + b"\n")
    fh.write(b"$EndMeshFormat\n")


def _write22(fh, mesh: TriangleMesh, binary: bool) -> None:
    _header(fh, "2.2", binary)
    fh.write(_physical_names(mesh))
    pts = points3d(mesh)
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
    groups = _groups(mesh)
    total = sum(len(e) for _, e, _ in groups)
    fh.write(f"$Elements\n{total}\n".encode())
    first = 1
    for etype, elems, tags in groups:
        m, k = elems.shape
        phys = np.zeros(m, np.int64) if tags is None else tags
        geom = np.where(phys > 0, phys, 1)
        table = np.column_stack([np.arange(first, first + m), phys, geom, elems + 1])
        first += m
        if binary:
            fh.write(np.array([etype, m, 2], "<i4").tobytes())
            fh.write(table.astype("<i4").tobytes())
        else:
            cols = np.column_stack([table[:, :1], np.full((m, 1), etype), np.full((m, 1), 2),
                                    table[:, 1:]])
            text = format_rows(cols, "%d")
            fh.write(text.encode())
    if binary:
        fh.write(b"\n")
    fh.write(b"$EndElements\n")


def _entities(mesh: TriangleMesh, pts: np.ndarray):
    """One entity per (dimension, physical tag): ``{dim: [(entity, phys or None, bbox)]}``
    and the entity of each element run."""
    ents: dict[int, list] = {1: [], 2: []}
    blocks = []
    coords = np.ascontiguousarray(pts.T)  # (3, N): reductions along contiguous rows
    for etype, elems, tags in _groups(mesh):
        dim = 1 if etype == LINE else 2
        tag_arr = np.zeros(len(elems), np.int64) if tags is None else np.asarray(tags)
        uniq = np.zeros(1, np.int64) if tags is None else np.unique(tag_arr)
        ent_of = {}
        for i, t in enumerate(uniq.tolist()):
            used = np.zeros(len(pts), bool)
            used[(elems if len(uniq) == 1 else elems[tag_arr == t]).ravel()] = True
            sel = coords[:, used]
            bbox = np.concatenate([sel.min(axis=1), sel.max(axis=1)])
            ent_of[t] = i + 1
            ents[dim].append((i + 1, t if t > 0 else None, bbox))
        for a, b, t in _runs(tag_arr):
            blocks.append((dim, ent_of[t], etype, elems[a:b]))
    return ents, blocks


def _write41(fh, mesh: TriangleMesh, binary: bool) -> None:
    _header(fh, "4.1", binary)
    fh.write(_physical_names(mesh))
    pts = points3d(mesh)
    n = len(pts)
    ents, blocks = _entities(mesh, pts)
    fh.write(b"$Entities\n")
    if binary:
        fh.write(np.array([0, len(ents[1]), len(ents[2]), 0], "<u8").tobytes())
        for dim in (1, 2):
            for tag, phys, bbox in ents[dim]:
                fh.write(np.array([tag], "<i4").tobytes() + bbox.astype("<f8").tobytes())
                if phys is None:
                    fh.write(np.array([0], "<u8").tobytes())
                else:
                    fh.write(np.array([1], "<u8").tobytes() + np.array([phys], "<i4").tobytes())
                fh.write(np.array([0], "<u8").tobytes())
        fh.write(b"\n")
    else:
        fh.write(f"0 {len(ents[1])} {len(ents[2])} 0\n".encode())
        for dim in (1, 2):
            for tag, phys, bbox in ents[dim]:
                box = " ".join(repr(float(v)) for v in bbox)
                ph = "0" if phys is None else f"1 {phys}"
                fh.write(f"{tag} {box} {ph} 0\n".encode())
    fh.write(b"$EndEntities\n")
    # all nodes in one block on the first surface entity
    fh.write(b"$Nodes\n")
    if binary:
        fh.write(np.array([1, n, 1, n], "<u8").tobytes())
        fh.write(np.array([2, 1, 0], "<i4").tobytes() + np.array([n], "<u8").tobytes())
        fh.write(np.arange(1, n + 1, dtype="<u8").tobytes())
        fh.write(pts.astype("<f8").tobytes())
        fh.write(b"\n")
    else:
        fh.write(f"1 {n} 1 {n}\n2 1 0 {n}\n".encode())
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
