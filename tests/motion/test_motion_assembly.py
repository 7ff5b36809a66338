"""The path matrix (motion/planar/assembly.py): the mesh pattern, symmetric assembly and the
block-tridiagonal matrix kept as its frame blocks.
"""

from __future__ import annotations

import numpy as np
from motion_helpers import _random_admissible

from meshopt_toolkit.motion.planar.assembly import upper_to_blocks
from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.motion.planar.path import GraphPath


def test_mesh_pattern_is_the_sorted_coordinate_pattern(disc):
    """The pattern built from vertex pairs is the sorted set of the coordinate entries,
    each triangle entry and diagonal entry lands on its own (row, col), and ``transposed``
    maps every slot to the slot of (col, row)."""
    from meshopt_toolkit.motion.planar.assembly import MeshPattern

    n = 2 * disc.n_vertices
    cols = (2 * disc.triangles[:, :, None] + np.arange(2)).reshape(-1, 6)
    rows6 = np.broadcast_to(cols[:, :, None], (len(cols), 6, 6)).ravel()
    cols6 = np.broadcast_to(cols[:, None, :], (len(cols), 6, 6)).ravel()
    keys = np.unique(np.concatenate([rows6 * n + cols6, np.arange(n) * (n + 1)]))
    pattern = MeshPattern(disc.triangles, disc.n_vertices)
    assert np.array_equal(pattern.rows * n + pattern.cols, keys)
    slots = pattern.slot_of_entry
    assert np.array_equal(pattern.rows[slots], np.concatenate([rows6, np.arange(n)]))
    assert np.array_equal(pattern.cols[slots], np.concatenate([cols6, np.arange(n)]))
    assert np.array_equal(pattern.rows[pattern.transposed], pattern.cols)
    assert np.array_equal(pattern.cols[pattern.transposed], pattern.rows)


def test_symmetric_assembly_is_the_full_one(disc, rng):
    """Symmetric blocks assembled from their 21 upper entries (one bincount and the
    transpose) equal the full blocks' assembly."""
    from meshopt_toolkit.motion.planar.assembly import MeshPattern, symmetric_products

    pattern = MeshPattern(disc.triangles, disc.n_vertices)
    a = rng.standard_normal((6, 3, disc.n_triangles))
    full = np.einsum("ict,jct->tij", a, a)
    upper = symmetric_products(a)
    assert np.abs(upper_to_blocks(upper) - full).max() <= 1e-14 * np.abs(full).max()
    diagonal = rng.random(2 * disc.n_vertices)
    expected = pattern.values(full, diagonal)
    assert np.abs(pattern.symmetric_values(upper, diagonal) - expected).max() \
        <= 1e-13 * np.abs(expected).max()


def test_block_tridiagonal_products_match_the_assembled_matrix(disc, rng):
    """The path matrix kept as frame blocks multiplies, damps and gives its diagonal
    blocks as the assembled matrix does, with frames that fix different vertices and a
    frame that fixes all (no coupling across it)."""
    P, K = disc.points, 5
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    free[3] = False  # no unknowns: frames 1–2 and 4–5 are two separate chains
    free[2, rng.choice(disc.n_vertices, 9, replace=False)] = False
    path = GraphPath(GraphMetric(P, disc.triangles), frames, free, None)
    _, _, H, _ = path.normal_equations(frames)
    dense = H.tocsr().toarray()
    assert len(H.blocks) == 4 and sorted(H.upper) == [0, 2]
    np.testing.assert_array_equal(dense, dense.T)
    v = rng.standard_normal(path.n_unknowns)
    shift = rng.random(path.n_unknowns)
    scale = np.abs(dense).max() * np.abs(v).max()
    assert np.abs(H @ v - dense @ v).max() <= 1e-13 * scale
    damped = H.damped(shift).damped(shift)
    assert np.abs(damped @ v - (dense @ v + 2 * shift * v)).max() <= 1e-13 * scale
    for B, (start, stop) in zip(damped.diagonal_blocks(), H.ranges):
        expected = dense[start:stop, start:stop] + np.diag(2 * shift[start:stop])
        np.testing.assert_allclose(B.toarray(), expected, rtol=0, atol=1e-14 * scale)
    assert H.shift is None  # damping made a new matrix
    from concurrent.futures import ThreadPoolExecutor

    from meshopt_toolkit.motion.planar.assembly import BlockTridiagonal

    with ThreadPoolExecutor(2) as pool:  # frames in threads: the same products, bitwise
        threaded = BlockTridiagonal(H.ranges, H.blocks, H.upper, H.lower, shift,
                                    frames_map=pool.map)
        np.testing.assert_array_equal(threaded @ v, H.damped(shift) @ v)
