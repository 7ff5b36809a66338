"""The graph metric M + w²JᵀJ (motion/planar/metric.py): its products and the bound of
every triangle by the path length.
"""

from __future__ import annotations

import numpy as np
from conftest import grid_mesh
from hypothesis import given
from hypothesis import strategies as st
from motion_helpers import FAST, _random_admissible

from meshopt_toolkit.kernels.triangles import inverse_shape_quality
from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.motion.planar.distortion import shape_quality_bound


@FAST
@given(seed=st.integers(0, 2**16), amplitude=st.floats(0.05, 0.5), weight=st.floats(0.2, 5))
def test_path_bounds_every_triangle_by_its_length(seed, amplitude, weight):
    """Along any discrete path, |φ_t(Q_k) − φ_t(Q_0)| ≤ ℓ_k/w, hence the 1/ψ bound."""
    mesh = grid_mesh(3, jitter=0.3, seed=seed)
    rng = np.random.default_rng(seed)
    frames = np.array([mesh.points] + [_random_admissible(mesh, rng, amplitude)
                                       for _ in range(4)])
    metric = GraphMetric(mesh.points, mesh.triangles, weight)
    ell = np.concatenate([[0.0], np.cumsum(metric.segment_lengths(frames))])
    q0 = inverse_shape_quality(mesh.points, mesh.triangles)
    for k, Q in enumerate(frames):
        change = np.linalg.norm(metric.strain.values(Q), axis=1)
        # rounding only: φ at the reference itself evaluates to a few ulps, not to 0
        assert (change <= ell[k] / weight * (1 + 1e-12) + 64 * np.finfo(float).eps).all()
        bound = shape_quality_bound(q0, np.full(len(q0), ell[k] / weight))
        assert (inverse_shape_quality(Q, mesh.triangles) <= bound * (1 + 1e-12)).all()


def test_metric_applied_triangle_by_triangle_is_the_matrix(disc, rng):
    """``GraphMetric.apply`` is ``(M + w² JᵀJ) V`` with the assembled sparse Jacobian."""
    import scipy.sparse as sp

    metric = GraphMetric(disc.points, disc.triangles, 1.7,
                         triangle_weights=1 + rng.random(disc.n_triangles))
    Q = _random_admissible(disc, rng, 0.3)
    V = rng.standard_normal(Q.shape)
    _, blocks = metric.strain.values_and_jacobian(Q)
    J = sp.diags(metric.row_weights) @ metric.strain.jacobian_matrix(blocks)
    expected = (J.T @ (J @ V.ravel())).reshape(V.shape) + metric.mass[:, None] * V
    assert np.abs(metric.apply(Q, V) - expected).max() <= 1e-12 * np.abs(expected).max()
