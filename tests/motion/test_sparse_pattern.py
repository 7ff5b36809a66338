"""The one sort of the per-cell block assemblers (motion/engine/sparse_pattern.py): the whole
matrix, its transpose, and the lower triangle of the free block against dense sums."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.motion.engine.sparse_pattern import CellPattern, FreePattern, pattern_slots
from meshopt_toolkit.motion.surface.normal_equations import FreePattern as UpperProductPattern
from meshopt_toolkit.motion.surface.normal_equations import upper_products


def dense_sum(columns, blocks, diagonal, n):
    A = np.diag(np.asarray(diagonal, float))
    for cols, block in zip(columns, blocks):
        A[np.ix_(cols, cols)] += block
    return A


def random_cells(rng, n_vertices, n_cells, k, d):
    cells = np.array([rng.choice(n_vertices, k, replace=False) for _ in range(n_cells)])
    columns = (d * cells[:, :, None] + np.arange(d)).reshape(n_cells, k * d)
    return cells, columns


def test_pattern_slots_sums_repeats_into_one_slot():
    s = pattern_slots(np.array([2, 0, 2, 1]), np.array([1, 0, 1, 2]), 3)
    assert s.nnz == 3 and s.slot_of_entry[0] == s.slot_of_entry[2]
    np.testing.assert_array_equal(s.indptr, [0, 1, 2, 3])
    np.testing.assert_array_equal(s.indices, [0, 2, 1])


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10**6), k=st.sampled_from([2, 3, 4]), d=st.sampled_from([2, 3]))
def test_cell_pattern_and_free_pattern_equal_the_dense_sums(seed, k, d):
    rng = np.random.default_rng(seed)
    N = 9
    _, columns = random_cells(rng, N, 7, k, d)
    m = k * d
    B = rng.normal(size=(7, m, m))
    blocks = B + B.transpose(0, 2, 1)
    diagonal = rng.random(N * d) + 1.0
    A = dense_sum(columns, blocks, diagonal, N * d)
    whole = CellPattern(columns, N * d)
    values = whole.values(blocks, diagonal)
    np.testing.assert_allclose(whole.matrix(values).toarray(), A, atol=1e-12)
    np.testing.assert_allclose(whole.matrix(values, transpose=True).toarray(), A.T, atol=1e-12)
    free = rng.random(N * d) < 0.7
    lower = FreePattern(columns, free).matrix(blocks, diagonal[free])
    np.testing.assert_allclose(lower.toarray(), np.tril(A[np.ix_(free, free)]), atol=1e-12)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10**6))
def test_the_surface_pattern_of_upper_products_equals_the_dense_lower_triangle(seed):
    rng = np.random.default_rng(seed)
    N, d = 8, 3
    # every vertex in a triangle (the surface motion's free vertices are)
    cells = np.r_[[[0, 1, 2], [3, 4, 5], [6, 7, 0]], random_cells(rng, N, 3, 3, d)[0]]
    columns = (d * cells[:, :, None] + np.arange(d)).reshape(6, 9)
    J = rng.normal(size=(6, 4, 9))
    free = rng.random(N * d) < 0.7
    index = np.full(N * d, -1)
    index[free] = np.arange(int(free.sum()))
    diagonal = rng.random(int(free.sum())) + 1.0
    pattern = UpperProductPattern([columns], index, int(free.sum()))
    lower = pattern.matrix([upper_products(J)], diagonal)
    A = dense_sum(columns, np.matmul(J.transpose(0, 2, 1), J), np.zeros(N * d), N * d)
    expected = np.tril(A[np.ix_(free, free)]) + np.diag(diagonal)
    np.testing.assert_allclose(lower.toarray(), expected, atol=1e-12)
