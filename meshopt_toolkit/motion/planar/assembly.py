"""Assembly of the path's Gauss–Newton matrix: block tridiagonal over the frames, every
block on the mesh's vertex-coordinate pattern.

The structure is computed once from the mesh pattern (one sort of the ``36 T`` per-triangle
entries) and the frames' free coordinates. Each assembly is then one ``bincount`` per block
onto the mesh pattern (and a gather where a frame fixes coordinates); the blocks are kept
apart (:class:`BlockTridiagonal`), never assembled into one matrix.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ..engine.frame_threads import frame_map
from .time_coupling import FrameEmbedding

#: The 21 entries ``i ≤ j`` of a symmetric 6×6 block, row by row: symmetric per-triangle
#: blocks are kept as ``(21, T)`` arrays of these entries ("upper", one row per entry, so
#: that every operation on them is over all triangles at once).
UPPER_ROWS, UPPER_COLS = np.triu_indices(6)
#: the rows of an upper array that hold a block's diagonal
UPPER_DIAGONAL = np.flatnonzero(UPPER_ROWS == UPPER_COLS)


def symmetric_products(a: FloatArray) -> FloatArray:
    """``Σ_c a_ci a_cj`` per triangle as an upper array (21, T), from ``a`` (6, C, T)."""
    out = np.empty((len(UPPER_ROWS), a.shape[2]))
    for row, (i, j) in enumerate(zip(UPPER_ROWS, UPPER_COLS)):
        np.multiply(a[i, 0], a[j, 0], out=out[row])
        for c in range(1, a.shape[1]):
            out[row] += a[i, c] * a[j, c]
    return out


def block_products(a: FloatArray, b: FloatArray) -> FloatArray:
    """``aᵀb`` per triangle: (T, 3, 6) × (T, 3, 6) → (T, 6, 6)."""
    return np.matmul(a.transpose(0, 2, 1), b)


def upper_to_blocks(upper: FloatArray) -> FloatArray:
    """An upper array (21, T) as the full symmetric blocks (T, 6, 6)."""
    blocks = np.empty((upper.shape[1], 6, 6))
    blocks[:, UPPER_ROWS, UPPER_COLS] = upper.T
    blocks[:, UPPER_COLS, UPPER_ROWS] = upper.T
    return blocks


class MeshPattern:
    """The CSR pattern of a symmetric ``2N × 2N`` matrix with one dense 6×6 block per
    triangle (its vertices' coordinates ``x_0, y_0, x_1, …``) and the diagonal, built from
    the vertex pattern (a quarter of the entries to sort).

    Attributes
    ----------
    rows, cols : (nnz,) int arrays, in CSR order
    slot_of_entry : (36 T + 2N,) int array
        Where each per-triangle entry (``(T, 6, 6)`` raveled), then each diagonal entry,
        lands.
    transposed : (nnz,) int array
        The slot of ``(col, row)`` for each slot.
    upper_slots : (21 T,) int array
        The slots of an upper array's entries (:data:`UPPER_ROWS`, raveled row by row).
    diagonal_slots : (2N,) int array
        The slot of each diagonal entry.
    """

    def __init__(self, triangles: IntArray, n_vertices: int) -> None:
        # the vertex pattern (9 pairs per triangle and the diagonal), then each vertex
        # pair (a, b) as its four coordinate entries (2a + p, 2b + q): in CSR order, row
        # 2a + p holds (2b, 2b + 1) for each neighbour b of a in turn, so the entry of
        # the vertex pattern's e-th pair lands at 4·ptr[a] + 2p·deg(a) + 2(e − ptr[a]) + q
        T, N = len(triangles), n_vertices
        first = np.concatenate([np.repeat(triangles, 3, axis=1).ravel(), np.arange(N)])
        second = np.concatenate([np.tile(triangles, (1, 3)).ravel(), np.arange(N)])
        keys, pair_of_entry = np.unique(first * N + second, return_inverse=True)
        a, b = keys // N, keys % N
        ptr = np.searchsorted(a, np.arange(N + 1))
        degree = np.diff(ptr)[a]
        corner = (4 * ptr[a] + 2 * (np.arange(keys.size) - ptr[a]))[:, None, None]
        p = np.arange(2)
        slots = corner + 2 * p[None, :, None] * degree[:, None, None] + p[None, None, :]
        self.nnz = 4 * keys.size
        self.n_coords = 2 * N
        self.n_triangles = T
        self.rows = np.empty(self.nnz, np.int64)
        self.cols = np.empty(self.nnz, np.int64)
        self.rows[slots] = 2 * a[:, None, None] + p[None, :, None]
        self.cols[slots] = 2 * b[:, None, None] + p[None, None, :]
        mirror = np.searchsorted(keys, b * N + a)
        self.transposed = np.empty(self.nnz, np.int64)
        self.transposed[slots] = slots[mirror].transpose(0, 2, 1)
        pairs = pair_of_entry.ravel()
        by_triangle = slots[pairs[:9 * T]].reshape(T, 3, 3, 2, 2).transpose(0, 1, 3, 2, 4)
        by_triangle = by_triangle.reshape(T, 6, 6)
        self.diagonal_slots = slots[pairs[9 * T:]][:, p, p].ravel()
        self.slot_of_entry = np.concatenate([by_triangle.ravel(), self.diagonal_slots])
        self.upper_slots = np.ascontiguousarray(by_triangle[:, UPPER_ROWS, UPPER_COLS].T).ravel()

    def values(self, products: FloatArray, diagonal: FloatArray) -> FloatArray:
        """Slot values of ``Σ_t`` the 6×6 ``products`` (T, 6, 6) plus ``diag(diagonal)``."""
        weights = np.concatenate([products.ravel(), diagonal])
        return np.bincount(self.slot_of_entry, weights, minlength=self.nnz)

    def symmetric_values(self, upper: FloatArray, diagonal: FloatArray) -> FloatArray:
        """Slot values of ``Σ_t`` the symmetric blocks given by ``upper`` (21, T) plus
        ``diag(diagonal)``: one ``bincount`` of the 21 entries (the blocks' diagonal
        halved, in place in ``upper``) and the sum with its transpose: with
        :func:`symmetric_products`, less work than the full blocks' products and
        :meth:`values`; the layout is what makes the Newton term cheap."""
        upper[UPPER_DIAGONAL] *= 0.5
        out = np.bincount(self.upper_slots, upper.ravel(), minlength=self.nnz)
        out += out[self.transposed]
        out[self.diagonal_slots] += diagonal
        return out


class PathPattern:
    """The path matrix's structure in the free coordinates: per frame with unknowns, the
    mesh pattern restricted to that frame's free coordinates (and, for consecutive such
    frames, to the rows of one and the columns of the other).

    Parameters
    ----------
    mesh : MeshPattern
    col : (K+1, 2N) int array
        Column (unknown) index of each frame's coordinates, −1 where fixed; increasing in
        frame, then coordinate (each frame's unknowns are one contiguous range).
    """

    def __init__(self, mesh: MeshPattern, col: IntArray) -> None:
        self.mesh = mesh
        K = col.shape[0] - 1
        #: the frames (1 … K) with unknowns, and the range of columns of each
        self.frames = [k for k in range(1, K + 1) if (col[k] >= 0).any()]
        self.ranges = [(int(col[k][col[k] >= 0][0]), int(col[k].max()) + 1) for k in self.frames]
        #: each such frame's free coordinates (of 2N, in its unknowns' order) and the
        #: path's segments at it (2, or 1 for the last frame)
        self.columns = [np.flatnonzero(col[k] >= 0) for k in self.frames]
        self.segments = [2 if k < K else 1 for k in self.frames]
        local = [np.where(col[k] >= 0, col[k] - start, -1)
                 for k, (start, _) in zip(self.frames, self.ranges)]
        made: dict = {}  # by their maps: frames often free the same coordinates

        def restriction(rows: IntArray, cols: IntArray) -> tuple:
            key = (rows.tobytes(), cols.tobytes())
            if key not in made:
                made[key] = self._restriction(rows, cols)
            return made[key]

        self.diagonal = [restriction(a, a) for a in local]
        #: the indices ``i`` of ``frames`` whose frames ``i`` and ``i + 1`` are consecutive
        self.adjacent = [i for i in range(len(self.frames) - 1)
                         if self.frames[i + 1] == self.frames[i] + 1]
        #: per adjacent pair (i, i + 1) of ``frames``: its restrictions (i, i + 1), (i + 1, i)
        self.coupling = {i: (restriction(local[i], local[i + 1]),
                             restriction(local[i + 1], local[i])) for i in self.adjacent}

    def _restriction(self, rows: IntArray, cols: IntArray) -> tuple:
        """``(kept, indptr, indices)``: the mesh slots whose row and column are free
        (``kept`` None where all are) and the CSR structure they make, in local numbers."""
        mesh = self.mesh
        r, c = rows[mesh.rows], cols[mesh.cols]
        if (r >= 0).all() and (c >= 0).all():
            kept, r_kept, c_kept = None, r, c
        else:
            kept = np.flatnonzero((r >= 0) & (c >= 0))
            r_kept, c_kept = r[kept], c[kept]  # still in row order
        n_rows = int(rows.max()) + 1
        indptr = np.concatenate([[0], np.cumsum(np.bincount(r_kept, minlength=n_rows))])
        index = np.int32 if mesh.nnz < 2**31 else np.int64
        return kept, indptr.astype(index), c_kept.astype(index)

    def matrix(self, diagonal_blocks: list[FloatArray], coupling_blocks: list[FloatArray],
               embedding: FrameEmbedding | None = None) -> BlockTridiagonal:
        """The matrix from slot values of its blocks: ``diagonal_blocks[k − 1]`` for frame
        ``k`` (k = 1 … K), ``coupling_blocks[k − 1]`` for frames ``(k, k + 1)``; the block
        ``(k + 1, k)`` is its transpose. ``embedding`` is passed on."""

        def block(values: FloatArray, structure: tuple, n_cols: int) -> sp.csr_matrix:
            kept, indptr, indices = structure
            data = values if kept is None else values[kept]
            return sp.csr_matrix((data, indices, indptr), shape=(len(indptr) - 1, n_cols))

        sizes = [stop - start for start, stop in self.ranges]
        diagonal = [block(diagonal_blocks[k - 1], s, n)
                    for k, s, n in zip(self.frames, self.diagonal, sizes)]
        upper, lower = {}, {}
        for i, (forward, backward) in self.coupling.items():
            values = coupling_blocks[self.frames[i] - 1]
            upper[i] = block(values, forward, sizes[i + 1])
            lower[i] = block(values[self.mesh.transposed], backward, sizes[i])
        return BlockTridiagonal(self.ranges, diagonal, upper, lower, embedding=embedding,
                                frames_map=frame_map(self.mesh.n_triangles, len(diagonal)))


class BlockTridiagonal:
    """A symmetric block-tridiagonal matrix over frames, kept as its sparse blocks (never
    assembled: at 107k triangles and 7 frames the assembled path matrix has 29M entries,
    and building it, or a damped copy, cost more than a conjugate-gradient iteration),
    plus a diagonal ``shift`` (Levenberg–Marquardt's damping).

    Parameters
    ----------
    ranges : list of (start, stop)
        Each frame's columns.
    diagonal : list of sparse matrices
        Frame ``i``'s block.
    upper, lower : dict ``i →`` sparse matrix
        The blocks ``(i, i + 1)`` and ``(i + 1, i)`` of adjacent frames.
    shift : (n,) float array, optional
    embedding : FrameEmbedding, optional
        The factors ``H = K 𝔻ᵀ(T ⊗ I)𝔻`` of a path's Gauss–Newton part, for the
        time-coupled preconditioner (:mod:`.time_coupling`).
    frames_map : callable, optional
        ``map`` over the frames for products (:func:`..engine.frame_threads.frame_map`: scipy's
        sparse products release the GIL).
    """

    def __init__(self, ranges: list[tuple[int, int]], diagonal: list, upper: dict, lower: dict,
                 shift: FloatArray | None = None, embedding: FrameEmbedding | None = None,
                 frames_map: Callable = map) -> None:
        self.ranges, self.blocks, self.upper, self.lower = ranges, diagonal, upper, lower
        n = ranges[-1][1] if ranges else 0
        self.shape = (n, n)
        self.shift = shift
        self.embedding = embedding
        self.frames_map = frames_map

    def __matmul__(self, x: FloatArray) -> FloatArray:
        parts = [x[start:stop] for start, stop in self.ranges]

        def frame_product(i: int) -> FloatArray:
            y = self.blocks[i] @ parts[i]
            if i in self.upper:
                y += self.upper[i] @ parts[i + 1]
            if i - 1 in self.lower:
                y += self.lower[i - 1] @ parts[i - 1]
            return y

        out = np.empty(self.shape[0])
        for (start, stop), y in zip(self.ranges, self.frames_map(frame_product,
                                                                 range(len(self.ranges)))):
            out[start:stop] = y
        if self.shift is not None:
            out += self.shift * x
        return out

    def damped(self, shift: FloatArray) -> BlockTridiagonal:
        """This matrix plus ``diag(shift)`` (the blocks shared, not copied)."""
        total = shift if self.shift is None else self.shift + shift
        return BlockTridiagonal(self.ranges, self.blocks, self.upper, self.lower, total,
                                self.embedding, self.frames_map)

    def diagonal_blocks(self) -> list[sp.csr_matrix]:
        """Each frame's diagonal block, with its part of the shift."""
        if self.shift is None:
            return list(self.blocks)
        return [(B + sp.diags(self.shift[start:stop])).tocsr()
                for B, (start, stop) in zip(self.blocks, self.ranges)]

    def tocsr(self) -> sp.csr_matrix:
        """The assembled matrix (for tests and one-frame systems)."""
        if len(self.blocks) == 1:
            return self.diagonal_blocks()[0]
        grid = [[None] * len(self.blocks) for _ in self.blocks]
        for i, B in enumerate(self.diagonal_blocks()):
            grid[i][i] = B
        for i in self.upper:
            grid[i][i + 1], grid[i + 1][i] = self.upper[i], self.lower[i]
        return sp.bmat(grid, format="csr")
