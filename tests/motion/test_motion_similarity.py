"""Similarities z ↦ az + b (motion/similarity.py).
"""

from __future__ import annotations

import numpy as np
from conftest import grid_mesh
from hypothesis import given
from hypothesis import strategies as st
from motion_helpers import FAST, _similar

from meshopt_toolkit.motion.similarity import fit_similarity


@FAST
@given(angle=st.floats(-3.1, 3.1), scale=st.floats(0.1, 10), shift=st.tuples(
    st.floats(-10, 10), st.floats(-10, 10)))
def test_fit_similarity_recovers_a_similarity(angle, scale, shift):
    P = grid_mesh(3, jitter=0.3).points
    S = fit_similarity(P, _similar(P, angle, scale, shift))
    np.testing.assert_allclose(S(P), _similar(P, angle, scale, shift), atol=1e-9 * (1 + scale))
    np.testing.assert_allclose(S.inverse(S(P)), P, atol=1e-9)
