"""The time-coupled preconditioner of the path systems (motion/planar/time_coupling.py).
"""

from __future__ import annotations

import numpy as np
from motion_helpers import _random_admissible

from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.motion.planar.path import GraphPath


def test_time_coupled_preconditioner_is_exact_for_equal_frames(disc, rng):
    """``P⁻¹ = 𝔻⁺(T⁻¹ ⊗ I)𝔻⁺ᵀ/K`` inverts the Gauss–Newton matrix exactly where every
    frame has the same Jacobian (a path standing still at a random admissible mesh), with
    a free last frame (``T_KK = 1``): one CG iteration, to rounding."""
    from meshopt_toolkit.motion.planar.frame_blocks import FrameBlocks

    P, K = disc.points, 4
    Q = _random_admissible(disc, rng, 0.3)
    frames = np.array([P, *([Q] * K)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    path = GraphPath(GraphMetric(P, disc.triangles, 1.3), frames, free, None)
    _, _, H, _ = path.normal_equations(frames)
    assert H.embedding.coupled and H.embedding.segments == [2, 2, 2, 1]
    blocks = FrameBlocks(path.frame_indices())
    blocks.factorize(H)
    v = rng.standard_normal(path.n_unknowns)
    x = blocks.preconditioner(H)(H @ v)
    assert np.abs(x - v).max() <= 1e-8 * np.abs(v).max()


def test_time_coupled_preconditioner_is_symmetric_positive_definite(disc, rng):
    """On a moving path whose frames fix different vertices, split in two chains by a
    fixed frame, and damped: ``P⁻¹`` is symmetric and positive definite, and CG with it
    reaches the direct solution."""
    from scipy.sparse.linalg import spsolve

    from meshopt_toolkit.motion.planar.frame_blocks import FrameBlocks

    P, K = disc.points, 6
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = free[3] = False
    free[:, np.unique(disc.boundary_edges)[:6]] = False
    free[2, rng.choice(disc.n_vertices, 9, replace=False)] = False
    path = GraphPath(GraphMetric(P, disc.triangles), frames, free, None)
    _, g, H, d = path.normal_equations(frames)
    A = H.damped(1e-3 * d)
    assert A.embedding.neighbours == [0, 2, 3]  # frames (1, 2), (4, 5), (5, 6)
    blocks = FrameBlocks(path.frame_indices())
    blocks.factorize(A)
    apply = blocks.preconditioner(A)
    U = rng.standard_normal((path.n_unknowns, 5))
    PU = np.column_stack([apply(u) for u in U.T])
    gram = U.T @ PU
    np.testing.assert_allclose(gram, gram.T, rtol=1e-10, atol=0)
    assert np.linalg.eigvalsh(0.5 * (gram + gram.T)).min() > 0
    exact = spsolve(A.tocsr().tocsc(), g)
    x = FrameBlocks(path.frame_indices()).solve(A, g, 1e-11)
    assert np.abs(x - exact).max() <= 1e-8 * np.abs(exact).max()
