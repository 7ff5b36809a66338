"""``scatter_corners``: the sum of per-corner vectors onto the vertices, against
``np.add.at`` and as the transpose of gathering ``points[cells]``."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.kernels.cell_maps import scatter_corners


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 30), cells=st.integers(0, 40),
       k=st.integers(2, 4), d=st.integers(1, 3))
def test_scatter_corners_sums_like_add_at_and_is_the_gathers_transpose(seed, n, cells, k, d):
    rng = np.random.default_rng(seed)
    C = rng.integers(0, n, (cells, k))
    W = rng.normal(size=(cells, k, d))
    expected = np.zeros((n, d))
    np.add.at(expected, C.ravel(), W.reshape(-1, d))
    out = scatter_corners(C, W, n)
    assert out.shape == (n, d)
    np.testing.assert_allclose(out, expected, rtol=1e-13, atol=1e-13)
    X = rng.normal(size=(n, d))  # <scatter(W), X> = <W, X[C]>
    np.testing.assert_allclose(np.vdot(out, X), np.vdot(W, X[C]), rtol=1e-12, atol=1e-12)


def test_scatter_corners_leaves_unused_vertices_zero():
    out = scatter_corners(np.array([[0, 2, 3]]), np.ones((1, 3, 2)), 5)
    np.testing.assert_array_equal(out, [[1, 1], [0, 0], [1, 1], [1, 1], [0, 0]])
