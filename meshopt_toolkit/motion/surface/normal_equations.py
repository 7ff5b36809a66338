"""The normal equations ``JᵀJ + M`` of the surface motion's Gauss–Newton
(:mod:`.move`) at the free coordinates, from the residuals' Jacobian blocks: the
lower triangle assembled into a fixed pattern (:class:`FreePattern`) and a kept factor
turned with the surface as a preconditioner (:func:`turned_solve`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ..engine.sparse_pattern import pattern_slots


def upper_products(J: FloatArray) -> FloatArray:
    """The upper triangles of ``JᵀJ`` per block: (B, k(k+1)/2) from rows (B, m, k) (or
    (B, k), one row), in ``np.triu_indices(k)`` order (row-major), without the full k×k."""
    J = J[:, None, :] if J.ndim == 2 else J
    k = J.shape[2]
    out = np.empty((len(J), k * (k + 1) // 2))
    at = 0
    for a in range(k):  # row a of the upper triangle: entries (a, a…k−1)
        out[:, at:at + k - a] = np.einsum("bi,bic->bc", J[:, :, a], J[:, :, a:])
        at += k - a
    return out


class FreePattern:
    """The lower triangle of the normal matrix at the free coordinates as a fixed CSR
    pattern: the upper-triangle entries of per-block products (:func:`upper_products`,
    (B, k(k+1)/2)) over block columns (B, k) are summed into it by one ``bincount`` per
    block (CHOLMOD reads the lower triangle only). The pattern and each entry's place in
    it are found once, by one sort of the entries' keys
    (:func:`..engine.sparse_pattern.pattern_slots`); entries at a handle go to a slot
    past the end, so the products are read as they are (no gather of the kept ones)."""

    def __init__(self, block_columns: list, free_index: IntArray, n_free: int) -> None:
        self.n = n_free
        keys, take, sizes = [], [], []
        for C in block_columns:
            a, b = np.triu_indices(C.shape[1])
            r, c = free_index[C[:, a]].ravel(), free_index[C[:, b]].ravel()
            keep = np.flatnonzero((r >= 0) & (c >= 0))
            r, c = r[keep], c[keep]
            keys.append(np.maximum(r, c) * n_free + np.minimum(r, c))
            take.append(keep)  # place of each kept entry in the flattened products
            sizes.append(len(C) * len(a))
        keys = np.concatenate(keys)
        s = pattern_slots(keys // n_free, keys % n_free, n_free)
        self.slots, at = [], 0  # each flattened product's place in the data
        for keep, size in zip(take, sizes):
            slot = np.full(size, s.nnz, np.int64)
            slot[keep] = s.slot_of_entry[at:at + len(keep)]
            self.slots.append(slot)
            at += len(keep)
        self.indices, self.indptr = s.indices, s.indptr
        self.diagonal = np.searchsorted(s.keys, np.arange(n_free) * (n_free + 1))

    def matrix(self, products: list, diagonal: FloatArray) -> sp.csr_matrix:
        """The lower triangle from the blocks' upper products (B, k(k+1)/2) and the
        diagonal added."""
        data = np.zeros(len(self.indices) + 1)
        for P, slot in zip(products, self.slots):
            data += np.bincount(slot, P.ravel(), minlength=len(data))
        data = data[:-1]
        data[self.diagonal] += diagonal
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


def turned_solve(solve: Callable[[FloatArray], FloatArray], R: FloatArray
                 ) -> Callable[[FloatArray], FloatArray]:
    """``r ↦ R F⁻¹ Rᵀ r`` for a factor's ``solve`` (``F⁻¹``) over vertex coordinates (3 per
    vertex) and per-vertex rotations ``R`` (V, 3, 3): the factor of ``A`` turned to the
    matrix ``R A Rᵀ`` of a rotated surface (φ and the bending are rotation invariant, so
    ``J(Q R) = J(Q) Rᵀ``), SPD where ``F`` is."""

    def apply(r: FloatArray) -> FloatArray:
        y = solve(np.einsum("vji,vj->vi", R, r.reshape(-1, 3)).ravel())
        return np.einsum("vij,vj->vi", R, y.reshape(-1, 3)).ravel()

    return apply
