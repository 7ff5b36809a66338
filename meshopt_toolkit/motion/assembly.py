"""Assembly of the path's Gauss–Newton matrix: block tridiagonal over the frames, every
block on the mesh's vertex-coordinate pattern.

The structure is computed once from the mesh pattern (one sort of the ``36 T`` per-triangle
entries) and the frames' free coordinates, without sorting the whole matrix: in CSR
order a row of frame ``k`` holds, in this order, its entries in the blocks of frames
``k − 1``, ``k`` and ``k + 1``, each in the mesh row's order. Each assembly is then one
``bincount`` per block onto the mesh pattern and one gather.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray

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
        halved, in place in ``upper``) and the sum with its transpose (measured at 106k
        triangles with :func:`symmetric_products`: 26 ms against 31 ms for the full
        blocks' products and :meth:`values`; the layout is what makes the Newton term
        cheap)."""
        upper[UPPER_DIAGONAL] *= 0.5
        out = np.bincount(self.upper_slots, upper.ravel(), minlength=self.nnz)
        out += out[self.transposed]
        out[self.diagonal_slots] += diagonal
        return out


class PathPattern:
    """CSR structure of the path matrix in the free coordinates.

    Parameters
    ----------
    mesh : MeshPattern
    col : (K+1, 2N) int array
        Column (unknown) index of each frame's coordinates, −1 where fixed; increasing in
        frame, then coordinate.
    """

    def __init__(self, mesh: MeshPattern, col: IntArray) -> None:
        self.mesh = mesh
        self.n = int(col.max(initial=-1)) + 1
        K = col.shape[0] - 1
        self.pairs = [(k, k) for k in range(1, K + 1)] + [(k, k + 1) for k in range(1, K)] \
            + [(k + 1, k) for k in range(1, K)]
        block_of = {pair: b for b, pair in enumerate(self.pairs)}
        counts = np.zeros(self.n, np.int64)
        pieces = []  # per block: kept slots, their global rows and columns
        for k, l in self.pairs:
            rk, cl = col[k][mesh.rows], col[l][mesh.cols]
            kept = np.flatnonzero((rk >= 0) & (cl >= 0))
            pieces.append((kept, rk[kept], cl[kept]))
        # entries per global row, by block: rows of frame k take blocks (k, k−1), (k, k), (k, k+1)
        per_block_rows = [np.bincount(g_rows, minlength=self.n) for _, g_rows, _ in pieces]
        counts = np.sum(per_block_rows, axis=0) if pieces else counts
        self.indptr = np.concatenate([[0], np.cumsum(counts)])
        nnz = int(self.indptr[-1])
        self.indices = np.empty(nnz, np.int64)
        self.source = np.empty(nnz, np.int64)
        before = np.zeros(self.n, np.int64)  # entries already placed in each row
        for k in range(1, K + 1):
            for l in (k - 1, k, k + 1):
                b = block_of.get((k, l))
                if b is None:
                    continue
                kept, g_rows, g_cols = pieces[b]
                first = np.searchsorted(g_rows, g_rows)  # kept slots are in row order
                pos = self.indptr[g_rows] + before[g_rows] + np.arange(kept.size) - first
                self.indices[pos] = g_cols
                self.source[pos] = b * mesh.nnz + kept
                before += per_block_rows[b]

    def matrix(self, diagonal_blocks: list[FloatArray], coupling_blocks: list[FloatArray]
               ) -> sp.csr_matrix:
        """The matrix from slot values of its blocks: ``diagonal_blocks[k − 1]`` for frame
        ``k`` (k = 1 … K), ``coupling_blocks[k − 1]`` for frames ``(k, k + 1)``; the block
        ``(k + 1, k)`` is its transpose."""
        t = self.mesh.transposed
        stacked = np.concatenate([*diagonal_blocks, *coupling_blocks,
                                  *(c[t] for c in coupling_blocks)])
        return sp.csr_matrix((stacked[self.source], self.indices, self.indptr),
                             shape=(self.n, self.n))
