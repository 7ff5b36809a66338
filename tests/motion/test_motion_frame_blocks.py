"""The frames' kept factorizations (motion/planar/frame_blocks.py): orderings, precision,
threads, stale and failed factors.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from motion_helpers import _random_admissible, _straight_path

from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.motion.planar.path import GraphPath


def test_time_coupled_solve_on_stale_factors_goes_on_with_fresh_ones(disc, rng, monkeypatch):
    """Factors of a far-away matrix (heavily damped) do not bring the time-coupled CG
    to its tolerance within ``STALE_CG_LIMIT`` iterations: the solve goes on from its
    iterate on fresh factors and still reaches the tolerance."""
    import meshopt_toolkit.motion.planar.frame_blocks as frame_blocks

    frames, free, metric = _straight_path(disc, rng, K=6)
    path = GraphPath(metric, frames, free, None)
    _, g, H, d = path.normal_equations(frames)
    blocks = frame_blocks.FrameBlocks(path.frame_indices())
    blocks.factorize(H.damped(10.0 * d))  # kept factors of another matrix
    iterations = []
    pcg = frame_blocks.pcg

    def counting(*args, **kwargs):
        out = pcg(*args, **kwargs)
        iterations.append((out[1], kwargs["max_iterations"]))
        return out

    monkeypatch.setattr(frame_blocks, "pcg", counting)
    x = blocks.solve(H, g, 1e-8)
    assert iterations[0] == (frame_blocks.STALE_CG_LIMIT, frame_blocks.STALE_CG_LIMIT)
    assert len(iterations) == 2 and iterations[1][1] > frame_blocks.STALE_CG_LIMIT
    assert np.linalg.norm(H @ x - g) <= 1e-8 * np.linalg.norm(g)


def test_frame_blocks_in_nested_dissection_order_solve_the_path_system(disc, rng):
    """The frames' blocks factorized in nested-dissection order (``points`` given) are the
    same preconditioner as in minimum-degree order: PCG reaches the direct solution."""
    from scipy.sparse.linalg import spsolve

    from meshopt_toolkit.motion.planar.frame_blocks import FrameBlocks

    P, K = disc.points, 3
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    free[:, np.unique(disc.boundary_edges)] = False
    free[2, :4] = False  # frames of different sizes
    path = GraphPath(GraphMetric(P, disc.triangles), frames, free, None)
    _, g, H, _ = path.normal_equations(frames)
    exact = spsolve(H.tocsr().tocsc(), g)
    for points in (None, path.frame_points()):
        blocks = FrameBlocks(path.frame_indices(), points)
        x = blocks.solve(H, g, 1e-10)
        assert np.abs(x - exact).max() <= 1e-8 * np.abs(exact).max()
        assert (blocks.orderings is None) == (points is None)
    with pytest.raises(ValueError, match="one vertex per two columns"):
        FrameBlocks(path.frame_indices(), path.frame_points()[1:] + [P[:1]])


def test_frame_blocks_refuse_an_indefinite_matrix_and_refactorize_after(rng):
    """An indefinite matrix (a Newton matrix may be one) raises FloatingPointError; the
    next solve, of a positive definite matrix, factorizes afresh and succeeds."""
    from meshopt_toolkit.motion.planar.frame_blocks import FrameBlocks

    n = 200
    laplacian = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n)).tocsr()
    b = rng.standard_normal(n)
    blocks = FrameBlocks([np.arange(n)])
    with pytest.raises(FloatingPointError):
        blocks.solve((laplacian - 0.5 * sp.eye(n)).tocsr(), b, 1e-8)
    assert blocks.stale
    spd = (laplacian + 0.1 * sp.eye(n)).tocsr()
    x = blocks.solve(spd, b, 1e-10)
    assert np.linalg.norm(spd @ x - b) <= 1e-9 * np.linalg.norm(b)


def test_frame_blocks_redo_a_failed_single_precision_solve_in_double(monkeypatch):
    """Where CG does not converge on the float32 factors, the solve is redone (and the
    next ones made) on double-precision factors."""
    import meshopt_toolkit.motion.planar.frame_blocks as frame_blocks
    from meshopt_toolkit.solvers import factorize_spd

    def float32_is_useless(A, ordering=None, single=False):  # stands for a bad float32 factor
        return (lambda v: v.copy()) if single else factorize_spd(A, ordering)

    monkeypatch.setattr(frame_blocks, "factorize_spd", float32_is_useless)
    monkeypatch.setattr(frame_blocks, "cholmod_available", lambda: False)  # SuperLU's case
    n = 2000
    A = (sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n)) + 1e-8 * sp.eye(n)).tocsr()
    b = np.random.default_rng(4).standard_normal(n)
    blocks = frame_blocks.FrameBlocks([np.arange(n)])
    assert blocks.single
    x = blocks.solve(A, b, 1e-10)
    assert not blocks.single
    assert np.linalg.norm(A @ x - b) <= 1e-9 * np.linalg.norm(b)


def test_frame_blocks_factorize_in_double_precision_with_cholmod(monkeypatch):
    """With CHOLMOD the blocks are its double-precision factors (never float32), in
    threads for large frames where its calls release the GIL (:mod:`._cholmod`), else one
    frame after another; without it, SuperLU's float32 factors, in threads."""
    import meshopt_toolkit._cholmod as native
    import meshopt_toolkit.motion.planar.frame_blocks as frame_blocks
    import meshopt_toolkit.motion.engine.frame_threads as frame_threads

    pool = frame_threads.frame_pool()

    n = frame_blocks.PARALLEL_FROM
    A = (sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(2 * n, 2 * n)) + 1e-2 * sp.eye(2 * n)
         ).tocsr()
    b = np.random.default_rng(5).standard_normal(2 * n)
    frames = [np.arange(n), np.arange(n, 2 * n)]
    blocks = frame_blocks.FrameBlocks(frames)
    assert not blocks.single
    assert blocks.threaded == (pool is not None and native.library() is not None)
    assert (blocks._map is map) != blocks.threaded
    exact = blocks.solve(A, b, 1e-12)
    assert np.linalg.norm(A @ exact - b) <= 1e-12 * np.linalg.norm(b)
    kept = list(blocks.factors)
    blocks.factorize((A + 0.5 * sp.eye(2 * n)).tocsr())  # refactorized on the analyses
    assert all(a is b for a, b in zip(blocks.factors, kept))
    assert np.linalg.norm(A @ blocks.solve(A, b, 1e-12) - b) <= 1e-12 * np.linalg.norm(b)
    monkeypatch.setattr(native, "library", lambda: None)  # CHOLMOD through cvxopt only
    serial = frame_blocks.FrameBlocks(frames)
    assert not serial.single and not serial.threaded and serial._map is map
    np.testing.assert_array_equal(serial.solve(A, b, 1e-12), exact)
    monkeypatch.setattr(frame_blocks, "cholmod_available", lambda: False)
    superlu = frame_blocks.FrameBlocks(frames)
    assert superlu.single and (superlu._map is map) == (pool is None)
    np.testing.assert_allclose(superlu.solve(A, b, 1e-12), exact, rtol=0,
                               atol=1e-9 * np.abs(exact).max())
