"""Admissible paths frame by frame (motion/continuation.py): the extension through
kept factors.
"""

from __future__ import annotations

import numpy as np
from motion_helpers import _random_admissible

from meshopt_toolkit.motion.graph_metric import GraphMetric


def test_extension_through_kept_factors_matches_a_fresh_factorization(disc, rng):
    """A continuation reuses one factorization across its steps: the extension solved by
    PCG on a factorization made at another mesh is the one of a fresh factorization."""
    from meshopt_toolkit.motion.continuation import extend
    from meshopt_toolkit.motion.frame_blocks import FrameBlocks

    P = disc.points
    metric = GraphMetric(P, disc.triangles)
    handles = np.unique(disc.boundary_edges)
    Q = _random_admissible(disc, rng, 0.3)
    new = Q[handles] + 0.01 * rng.standard_normal((handles.size, 2))
    factors = FrameBlocks([np.arange(2 * (disc.n_vertices - handles.size))])
    extend(metric, P, handles, P[handles], factors)  # factorized at the reference
    assert not factors.stale
    fresh = extend(metric, Q, handles, new)
    reused = extend(metric, Q, handles, new, factors)
    assert np.array_equal(reused[handles], new)
    scale = np.abs(fresh - Q).max()
    assert np.abs(reused - fresh).max() <= 1e-6 * scale
