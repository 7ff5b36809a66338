"""Half-edge tables and the exact planar-manifold test of a triangle list (SPEC §1).

Functions of the ``(T, 3)`` index array (and, for the fan walk, of a mesh's cached
tables): the corner table, the sorted half-edges, the fans around each vertex, and
:func:`_clean_manifold`, which recognises a clean planar-manifold mesh in one exact pass
over whole arrays (one sort of the half-edges, a breadth-first search, a walk around
every vertex). Only a mesh with a problem pays for the description of its first problem
(:mod:`.checks`).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .._lazy import lazy_module
from .._options import require_shape
from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError

sp = lazy_module("scipy.sparse")
_csgraph = lazy_module("scipy.sparse.csgraph")


class MeshTables(Protocol):
    """What the fan walk and the manifold test read of a mesh (a ``TriangleMesh`` has it):
    read-only ``triangles``, ``n_vertices`` and ``_edge_corners``."""

    triangles: IntArray
    n_vertices: int
    _edge_corners: IntArray


def new_points(points, shape: tuple[int, ...]) -> FloatArray:
    """``points`` as float64 for a mesh whose points have ``shape``; another shape is an
    InvalidMeshError naming both."""
    return require_shape("new points", np.asarray(points, dtype=np.float64), shape,
                         error=InvalidMeshError)


def physical_tag(tag: int | str, tag_names: dict) -> tuple[int, int | None]:
    """The number of the physical group ``tag`` (a number, or a name of ``tag_names``,
    ``{name: (tag, dim)}``) and the dimension a name fixes (None for a number).

    Raises
    ------
    InvalidMeshError
        No group of that name; the message lists the names.
    """
    if not isinstance(tag, str):
        return tag, None
    if tag not in tag_names:
        raise InvalidMeshError(f"no physical group named {tag!r}; known: {sorted(tag_names)}")
    number, dim = tag_names[tag]
    return number, dim


def tagged_vertices(tag: int | str, tag_names: dict, blocks) -> IntArray:
    """Sorted vertices of the elements carrying a physical tag (a number: every block) or
    name (only the blocks of its dimension); ``blocks`` are ``(dim, cells, tags)``, those
    without tags (None) skipped, ``tag_names`` is ``{name: (tag, dim)}``.

    Raises
    ------
    InvalidMeshError
        No group of that name (the message lists the names), or no element carries the tag.
    """
    tag, dim = physical_tag(tag, tag_names)
    parts = [np.asarray(cells)[np.asarray(tags) == tag].ravel() for d, cells, tags in blocks
             if tags is not None and dim in (None, d)]
    if not sum(len(p) for p in parts):
        raise InvalidMeshError(f"no element carries physical tag {tag}")
    return np.unique(np.concatenate(parts))


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def _corner_table(tri: IntArray) -> IntArray:
    """The triangles as a contiguous ``(3, T)`` array: row ``l`` holds local vertex ``l``.

    int32 when every index fits, which halves the memory traffic of the passes below.
    """
    small = tri.size < 2**31 - 1 and (tri.size == 0 or int(tri.max()) < 2**31 - 1)
    return np.ascontiguousarray(tri.T, dtype=np.int32 if small else np.int64)


def _sorted_half_edges(
    table: IntArray, n: int, dtype, step: int = 0
) -> tuple[IntArray, np.ndarray, int]:
    """Half-edges sorted by (smaller end, larger end, direction, corner).

    Corner ``c = 3 k + l`` stands for the half-edge of triangle ``k`` opposite local vertex
    ``l``, from ``i_{l+1}`` to ``i_{l+2}``. Its code is ``lo << (b + 1) | hi << 1 | dir``
    with ``lo < hi`` its ends, ``b`` bits per vertex index and ``dir = i_{l+1} > i_{l+2}``,
    so equal codes are the same directed half-edge and codes differing only in the last
    bit are the two directions of one edge. When code and corner fit together in 64 bits
    they are packed into one key and sorted by value (much faster than an argsort).

    Parameters
    ----------
    table : (3, T) int array
        :func:`_corner_table` of the triangles.
    n : int
        Number of vertices.
    dtype : numpy integer type of the returned corners.
    step : int
        Return corner ``3k + (l + step) % 3`` in place of ``3k + l`` (``step = 1``: the
        corner after it in its triangle).

    Returns
    -------
    corners : (3T,) array of ``dtype``
        Corners in sorted order (shifted by ``step`` within their triangle).
    codes : (3T,) uint64
        Their codes, non-decreasing.
    b : int
        Bits per vertex index in the codes.
    """
    nt = table.shape[1]
    nc = 3 * nt
    bits = max(int(n - 1).bit_length(), 1)
    shift = max(int(nc - 1).bit_length(), 1)
    packed = 2 * bits + 1 + shift <= 64
    key = np.empty((3, nt), dtype=np.uint64)
    tmp = np.empty(nt, dtype=np.uint64)
    if packed:
        base = np.arange(0, nc, 3, dtype=np.uint64)
    for l in range(3):
        s, d = table[(l + 1) % 3], table[(l + 2) % 3]
        row = key[l]
        up = shift if packed else 0
        np.left_shift(np.minimum(s, d), bits + 1 + up, out=row, dtype=np.uint64, casting="unsafe")
        np.left_shift(np.maximum(s, d), 1 + up, out=tmp, dtype=np.uint64, casting="unsafe")
        row |= tmp
        np.left_shift(s > d, up, out=tmp, dtype=np.uint64, casting="unsafe")
        row |= tmp
        if packed:
            row |= base
            if (l + step) % 3:
                row += (l + step) % 3  # the corner 3k + l' fits in the low bits, no carry
    key = key.ravel()
    if packed:
        key.sort()
        corners = np.empty(nc, dtype=dtype)
        np.bitwise_and(key, (1 << shift) - 1, out=corners, casting="unsafe")
        key >>= shift
        return corners, key, bits
    order = np.argsort(key)
    # argsort lists the corners row by row of ``table``: translate to 3k + l
    corners = (order % nt) * 3 + (order // nt + step) % 3
    return corners.astype(dtype), key[order], bits


def _edge_index(edges: IntArray, keys: IntArray) -> IntArray:
    """Row index of each sorted pair in ``keys`` within lexicographically sorted ``edges``.

    Returns -1 where a pair is not an edge.
    """
    n = int(max(edges.max(initial=0), keys.max(initial=0))) + 1
    code_e = edges[:, 0] * n + edges[:, 1]
    code_k = keys[:, 0] * n + keys[:, 1]
    pos = np.searchsorted(code_e, code_k)
    pos = np.clip(pos, 0, len(code_e) - 1)
    return np.where(code_e[pos] == code_k, pos, -1)



def _fans_per_vertex(mesh: MeshTables) -> IntArray:
    """Number of fans (edge-connected groups of incident triangles) at each vertex ``(N,)``.

    Needs an edge-manifold, consistently oriented mesh without repeated vertices. The
    triangle corners at a vertex ``v`` (corner ``3k + l`` is vertex ``l`` of triangle
    ``k``) are linked by a successor map: from triangle ``(v, a, b)`` across the edge
    ``(v, b)`` to the next triangle around ``v``. Each fan is a path (a boundary fan) or
    a cycle (an interior fan) of that map. Pointer doubling, ``⌈log2(max degree)⌉``
    rounds over all corners at once, labels each path by its last corner and each cycle
    by its smallest corner; the fans at ``v`` are the corners that are their own label.
    """
    tri = mesh.triangles
    flat = tri.ravel()  # corner c sits at vertex flat[c]
    nc = len(flat)
    # int32 corner ids halve the memory traffic of the random gathers below
    idx = np.int32 if nc < 2**31 - 1 else np.int64
    corner = np.arange(nc, dtype=idx)
    nxt1 = np.tile(np.array([1, 1, -2], dtype=idx), nc // 3)  # c -> 3k + (l + 1) % 3 - c
    nxt2 = np.tile(np.array([2, -1, -1], dtype=idx), nc // 3)  # c -> 3k + (l + 2) % 3 - c
    # edge-corner e = 3k + l names the edge opposite local vertex l of triangle k;
    # partner[e] is the same edge's edge-corner in the neighbouring triangle (or -1)
    ec = mesh._edge_corners
    two = ec[:, 1] >= 0
    partner = np.full(nc, -1, dtype=idx)
    partner[ec[two, 0]] = ec[two, 1]
    partner[ec[two, 1]] = ec[two, 0]
    # corner c = 3k + l at v in triangle (v, a, b): the edge (v, b) is opposite a = l + 1
    across = partner[corner + nxt1]
    succ = corner.copy()  # the end of a path points to itself
    has = np.flatnonzero(across >= 0)
    e = across[has]
    cand1 = e + nxt1[e]  # the two endpoints of that edge in the neighbour
    cand2 = e + nxt2[e]
    succ[has] = np.where(flat[cand1] == flat[has], cand1, cand2)
    return _count_fans(succ, flat, mesh.n_vertices)


def _count_fans(succ: IntArray, vertex: IntArray, n: int) -> IntArray:
    """Number of orbits (paths and cycles) of a successor map at each vertex ``(n,)``.

    ``succ`` maps each of a set of corners ``0..m-1`` (each at ``vertex[c]``) to the next
    corner around the same vertex, or to itself at the end of a path; it is injective.
    Pointer doubling, ``⌈log2(max corners per vertex)⌉`` rounds over all corners at once,
    labels each path by its last corner and each cycle by its smallest corner; the orbits
    at ``v`` are the corners that are their own label.
    """
    corner = np.arange(len(succ), dtype=succ.dtype)
    is_end = succ == corner
    label = corner.copy()
    rounds = int(np.ceil(np.log2(max(int(np.bincount(vertex).max(initial=0)), 2))))
    for _ in range(rounds):  # after r rounds: label = min over 2^r corners, succ = succ^(2^r)
        np.minimum(label, label[succ], out=label)
        succ = succ[succ]
    # 2^rounds >= corners at the vertex: every path corner has reached its end
    root = np.where(is_end[succ], succ, label)
    own = root == corner
    return np.bincount(vertex[own], minlength=n)


#: fans longer than this are checked by pointer doubling instead of a step-by-step walk
_WALK_STEPS = 64
#: meshes with at most this many triangles are checked for connectivity in numpy alone
#: (no scipy import; the boundary's own threshold is ``kernels.boundary._NUMPY_PAIRS``)
_NUMPY_CONNECTIVITY = 20000


def _clean_manifold(mesh: MeshTables) -> IntArray | None:
    """The boundary corners ``(B,)`` if ``mesh`` passes every planar-manifold check, else None.

    The fast path of :func:`check_mesh`: it decides exactly whether
    :func:`_manifold_problems` finds nothing (then the sorted corners ``3k + l`` of the
    boundary half-edges are returned), without building the edge list. Problems are
    described by :func:`_manifold_problems`, run only when this returns None.

    Every test is a pass over whole arrays:

    * unused vertex: a zero in the vertex degrees (triangles per vertex ``t_v``);
    * repeated vertex in a triangle;
    * edge in three or more triangles, or inconsistent orientation: both hold iff some
      directed half-edge occurs twice (a manifold, consistently oriented mesh has each
      interior edge once in each direction), seen as equal neighbours after one sort of
      the half-edge codes (:func:`_sorted_half_edges`);
    * 2-path connectivity: a breadth-first search over the triangle graph (three slots
      per triangle: its neighbour across each edge, itself at a boundary edge);
    * bow-ties: around each vertex the successor map ``succ(c) = next(twin(next(c)))``
      (corner ``c`` at ``v`` in triangle ``(v, a, b)`` → the corner at ``v`` across edge
      ``(v, b)``) is injective, so its orbits are paths (boundary fans) and cycles
      (interior fans). A path starts at ``next(e)`` for each boundary half-edge ``e``
      leaving ``v``; two starts mean two fans. Otherwise one walk per vertex from its
      path start (or any corner) must make ``t_v - 1`` steps without reaching the path's
      end or returning to the start: then the orbit has all ``t_v`` corners and is the
      only fan. All vertices walk together, the ones with more triangles first (``t_v`` steps in total);
      vertices with more than :data:`_WALK_STEPS` triangles are counted by pointer
      doubling (:func:`_count_fans`) instead.
    """
    tri = mesh.triangles
    n = mesh.n_vertices
    nt = len(tri)
    nc = 3 * nt
    table = _corner_table(tri)
    idx = table.dtype
    deg = np.bincount(tri.ravel(), minlength=n)
    if deg.min() == 0:
        return None  # an unused vertex
    a, b, c = table
    if ((a == b) | (b == c) | (a == c)).any():
        return None  # a repeated vertex
    # corners are labelled by their successor next(c) = 3k + (l + 1) % 3 from here on
    order, code, _ = _sorted_half_edges(table, n, idx, step=1)
    del table, a, b, c
    diff = code[1:] ^ code[:-1]
    if not diff.all():
        return None  # a directed half-edge twice: > 2 triangles or inconsistent orientation
    pair = np.flatnonzero(diff == 1)  # the two directions of one edge
    del diff, code
    p, q = order[pair], order[pair + 1]
    del order, pair
    # twin[next(e)] = next(e') for the two half-edges e, e' of an interior edge, else -1
    twin = np.full(nc, -1, dtype=idx)
    twin[p] = q
    twin[q] = p
    del p, q
    first = np.flatnonzero(twin < 0)  # next(e) of the boundary half-edges e, sorted
    # 2-path connectivity
    nbr = twin // 3
    nbr[first] = first // 3
    if nt <= _NUMPY_CONNECTIVITY:  # small meshes: numpy only, no scipy import
        from ..orientation import component_labels

        inner = np.flatnonzero(twin >= 0)
        if component_labels(nt, inner // 3, twin[inner] // 3).any():
            return None
    else:
        graph = sp.csr_matrix(
            (np.ones(nc), nbr, np.arange(0, nc + 1, 3, dtype=idx)), shape=(nt, nt)
        )
        reached = _csgraph.breadth_first_order(graph, 0, directed=True,
                                               return_predecessors=False)
        if len(reached) != nt:
            return None
        del graph, reached
    del nbr
    # bow-ties: succ(c) = next(twin(next(c))) = twin[prev(c)]
    tn = twin.reshape(nt, 3)
    succ = np.empty_like(tn)
    succ[:, 1:] = tn[:, :2]
    succ[:, 0] = tn[:, 2]
    succ = succ.ravel()
    del tn, twin
    flat = tri.ravel()
    start = np.empty(n, dtype=idx)
    start[flat] = np.arange(nc, dtype=idx)  # any corner at each vertex
    if len(first):
        # a boundary fan at v starts at next(e) for the boundary half-edge e leaving v
        at = flat[first]
        if np.bincount(at, minlength=n).max() > 1:
            return None  # two boundary fans at a vertex
        start[at] = first
    maxdeg = int(deg.max())
    if maxdeg > 1:
        key = maxdeg - deg
        by_degree = np.argsort(key.astype(np.uint16) if maxdeg < 2**16 else key, kind="stable")
        n_more = n - np.cumsum(np.bincount(deg))  # n_more[s]: vertices with > s triangles
        cur = start[by_degree]
        origin = cur.copy()
        for s in range(1, min(maxdeg, _WALK_STEPS + 1)):
            m = n_more[s]
            cur = succ[cur[:m]]
            if (cur < 0).any() or (cur == origin[:m]).any():
                return None  # a fan ended or closed before visiting every corner
    if maxdeg > _WALK_STEPS + 1:
        sel = np.flatnonzero(deg[flat] > _WALK_STEPS + 1)
        local = np.full(nc, -1, dtype=idx)
        local[sel] = np.arange(len(sel), dtype=idx)
        nxt = succ[sel]
        sub = np.where(nxt >= 0, local[nxt], np.arange(len(sel), dtype=idx))
        if _count_fans(sub, flat[sel], n).max() > 1:
            return None
    return np.sort(_prev_corner(first))


def _next_corner(c: IntArray) -> IntArray:
    """``next(3k + l) = 3k + (l + 1) % 3``."""
    out = c + 1
    out[c % 3 == 2] -= 3
    return out


def _prev_corner(c: IntArray) -> IntArray:
    """``prev(3k + l) = 3k + (l + 2) % 3``."""
    out = c - 1
    out[c % 3 == 0] += 3
    return out


def _boundary_edges_of(tri: IntArray, corners: IntArray) -> IntArray:
    """Directed boundary edges ``(B, 2)`` of the half-edges at ``corners`` (sorted)."""
    flat = tri.ravel()
    return np.stack([flat[_next_corner(corners)], flat[_prev_corner(corners)]], axis=1)

