"""The sparse patterns of the motions' matrices with one dense block per cell: the entries'
keys sorted once (:func:`pattern_slots`, the one sort every assembler of per-cell blocks
shares), then every assembly is one ``bincount`` of the blocks' entries onto the slots.

:class:`CellPattern` is the whole ``dN × dN`` matrix (CSR, with each slot's transpose),
:class:`FreePattern` the lower triangle of its block at the free coordinates (CSC, what
CHOLMOD reads); both for cells of any size ``k`` (block columns ``(C, k·d)``). The planar
path's vertex-level pattern is :class:`..planar.assembly.MeshPattern`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray


@dataclass
class Slots:
    """Where each entry lands (``slot_of_entry``) in the compressed rows ``indptr``,
    ``indices`` of ``n`` rows and ``nnz`` distinct entries; ``keys`` the sorted distinct
    ``row·n + col``."""

    slot_of_entry: IntArray
    indices: IntArray
    indptr: IntArray
    nnz: int
    keys: IntArray


def pattern_slots(rows: IntArray, cols: IntArray, n: int) -> Slots:
    """The compressed-row pattern of entries at ``(rows, cols)`` of an ``n × n`` matrix
    (repeats summed into one slot) and each entry's slot."""
    keys = np.asarray(rows).astype(np.int64) * n + np.asarray(cols)
    unique, slot = np.unique(keys, return_inverse=True)
    return Slots(slot.ravel(), (unique % n).astype(np.int32),
                 np.searchsorted(unique // n, np.arange(n + 1)).astype(np.int32),
                 len(unique), unique)


def _block_entries(columns: IntArray) -> tuple[IntArray, IntArray]:
    """Row and column of every entry of the blocks ``(C, m, m)`` over ``columns`` (C, m),
    raveled as the blocks are."""
    m = columns.shape[1]
    rows = np.broadcast_to(columns[:, :, None], columns.shape + (m,)).ravel()
    cols = np.broadcast_to(columns[:, None, :], columns.shape + (m,)).ravel()
    return rows, cols


class CellPattern:
    """The CSR pattern of an ``n × n`` matrix with one dense block per cell over the
    coordinates ``columns`` (C, m) (e.g. ``3·vertex + d`` of a tet's corners) and the
    diagonal; assembly is one ``bincount`` of the blocks' entries onto its slots.

    Parameters
    ----------
    columns : (C, m) int array
        Global coordinate of each block column.
    n : int
        Coordinates.
    """

    def __init__(self, columns: IntArray, n: int) -> None:
        rows, cols = _block_entries(columns)
        diag = np.arange(n)
        s = pattern_slots(np.concatenate([rows, diag]), np.concatenate([cols, diag]), n)
        self.n, self.nnz = n, s.nnz
        self.slot_of_entry, self.indices, self.indptr = s.slot_of_entry, s.indices, s.indptr
        #: the slot of (col, row) for each slot
        self.transposed = np.searchsorted(s.keys, (s.keys % n) * n + s.keys // n)

    def values(self, blocks: FloatArray, diagonal: FloatArray) -> FloatArray:
        """Slot values of ``Σ_c blocks[c]`` (C, m, m) ``+ diag(diagonal)``."""
        return np.bincount(self.slot_of_entry, np.concatenate([blocks.ravel(), diagonal]),
                           minlength=self.nnz)

    def matrix(self, values: FloatArray, transpose: bool = False) -> sp.csr_matrix:
        """The matrix of slot ``values`` (or its transpose)."""
        data = values[self.transposed] if transpose else values
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


class FreePattern:
    """Lower-triangular CSC pattern of the free × free block of ``Σ_c (m×m blocks) +
    diagonal``, with the map from block entries to its data (assembly = one bincount).

    Parameters
    ----------
    columns : (C, m) int array
        Global coordinate of each block column (``d·vertex + a``).
    free : (n,) bool array
        Free coordinates.
    """

    def __init__(self, columns: IntArray, free: FloatArray) -> None:
        self.free = np.asarray(free, bool)
        index = np.full(len(self.free), -1)
        index[self.free] = np.arange(int(self.free.sum()))
        self.n = n = int(self.free.sum())
        r, c = _block_entries(index[columns])
        self.select = np.flatnonzero((r >= 0) & (c >= 0) & (r >= c))
        r, c = r[self.select], c[self.select]
        diag = np.arange(n)
        # compressed columns of the lower triangle: the rows of its transpose
        s = pattern_slots(np.concatenate([c, diag]), np.concatenate([r, diag]), n)
        self.inverse, self.indices, self.indptr = s.slot_of_entry, s.indices, s.indptr
        self.n_entries = s.nnz

    def matrix(self, blocks: FloatArray, diagonal: FloatArray) -> sp.csc_matrix:
        """The lower triangle of the free block of ``Σ blocks + diag(diagonal)``
        (``diagonal`` over the free coordinates)."""
        values = np.concatenate([blocks.reshape(-1)[self.select], diagonal])
        data = np.bincount(self.inverse, values, minlength=self.n_entries)
        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
