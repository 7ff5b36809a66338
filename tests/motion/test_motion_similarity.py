"""Similarities z ↦ az + b (motion/engine/similarity.py), the planar screw motion and the one
handle grouping of every cell kind.
"""

from __future__ import annotations

import numpy as np
from conftest import grid_mesh
from hypothesis import given
from hypothesis import strategies as st
from motion_helpers import FAST, _similar

from meshopt_toolkit.motion.engine.similarity import (
    HandlePath,
    Similarity,
    fit_similarity,
    handle_groups,
)


@FAST
@given(angle=st.floats(-3.1, 3.1), scale=st.floats(0.1, 10), shift=st.tuples(
    st.floats(-10, 10), st.floats(-10, 10)))
def test_fit_similarity_recovers_a_similarity(angle, scale, shift):
    P = grid_mesh(3, jitter=0.3).points
    S = fit_similarity(P, _similar(P, angle, scale, shift))
    np.testing.assert_allclose(S(P), _similar(P, angle, scale, shift), atol=1e-9 * (1 + scale))
    np.testing.assert_allclose(S.inverse(S(P)), P, atol=1e-9)


@FAST
@given(angle=st.floats(-3.0, 3.0).filter(lambda a: abs(a) > 1e-3), log_scale=st.floats(-1, 1),
       pivot=st.tuples(st.floats(-5, 5), st.floats(-5, 5)), t=st.floats(0, 1),
       u=st.floats(0, 1))
def test_planar_screw_turns_about_the_fixed_point_and_is_a_group(angle, log_scale, pivot, t, u):
    """``screw(t)`` of a similarity with fixed point ``p`` is ``p + a^t (z − p)`` (closed
    form), ``screw(t)∘screw(u) = screw(t + u)``, ``screw(1)`` is the similarity itself."""
    p = complex(*pivot)
    a = np.exp(log_scale + 1j * angle)
    center = 0.3 - 0.7j
    S = Similarity(center, (p - center) * (1 - a), log_scale, angle)  # fixes p
    P = grid_mesh(3, jitter=0.3).points
    z = P[:, 0] + 1j * P[:, 1]
    expected = p + np.exp(t * (log_scale + 1j * angle)) * (z - p)
    np.testing.assert_allclose(S.screw(t)(P), np.c_[expected.real, expected.imag], atol=1e-9)
    np.testing.assert_allclose(S.screw(t)(S.screw(u)(P)), S.screw(t + u)(P), atol=1e-8)
    assert S.screw(1.0) is S


def test_one_handle_grouping_for_edges_triangles_and_tets():
    """Handles joined by an edge of the given cells form one group, whatever the cells:
    boundary edges, triangles, tets (all six edges)."""
    handles = np.array([0, 1, 2, 5, 6, 9])
    edges = np.array([[0, 1], [1, 2], [2, 3], [5, 6], [7, 9]])
    assert [list(g) for g in handle_groups(handles, edges, 10)] == [[0, 1, 2], [3, 4], [5]]
    tris = np.array([[0, 1, 3], [5, 4, 6], [9, 8, 7]])
    assert [list(g) for g in handle_groups(handles, tris, 10)] == [[0, 1], [2], [3, 4], [5]]
    tets = np.array([[0, 3, 4, 2], [9, 6, 7, 8]])
    assert [list(g) for g in handle_groups(handles, tets, 10)] == [[0, 2], [1], [3], [4, 5]]


def test_planar_handle_path_screw_turns_a_hole_along_the_arc():
    """A group turned about a pivot moves along the arc with "screw" and its centroid
    along the chord with "chord"; both end bitwise at the targets."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(6, 2))
    pivot, theta = np.array([2.0, -1.0]), 2.0
    rot = lambda a: np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    targets = pivot + (X - pivot) @ rot(theta).T
    groups = [np.arange(6)]
    screw = HandlePath(X, targets, groups, motion="screw")
    chord = HandlePath(X, targets, groups)
    for t in (0.25, 0.5, 0.9):
        np.testing.assert_allclose(screw(t), pivot + (X - pivot) @ rot(t * theta).T, atol=1e-12)
        np.testing.assert_allclose(chord(t).mean(0), (1 - t) * X.mean(0) + t * targets.mean(0),
                                   atol=1e-12)
    assert np.array_equal(screw(1.0), targets) and np.array_equal(chord(1.0), targets)
