"""The one similarity of space (motion/engine/similarity_3d.py) that tets and surfaces share: its
two paths from the identity against closed forms, the screw motion a one-parameter group,
both paths ending bitwise at the similarity, the inverse, the fit, and the handle paths
built on it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from meshopt_toolkit.errors import OptionError
from meshopt_toolkit.motion.engine.similarity import (
    HandlePath,
    Similarity3,
    fit_similarity_3d,
    handle_groups,
)
from meshopt_toolkit.motion.engine.similarity_3d import global_similarity


def rodrigues(axis, angle: float) -> np.ndarray:
    """Rotation about the unit ``axis`` by ``angle``: I + sin K + (1 − cos) K² (an
    independent reference for scipy's rotation vectors)."""
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def random_similarity(rng, log_scale: float) -> Similarity3:
    rotvec = Rotation.random(random_state=int(rng.integers(2**31))).as_rotvec()
    return Similarity3(rng.normal(size=3), rng.normal(size=3), log_scale, rotvec)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(-1.0, 1.0), st.floats(-1.0, 1.5),
       st.floats(-1.0, 1.5))
def test_screw_is_a_one_parameter_group(seed, log_scale, a, b):
    """``screw(a)`` after ``screw(b)`` is ``screw(a + b)`` (with its spiral scale),
    ``screw(0)`` the identity, for random similarities."""
    rng = np.random.default_rng(seed)
    S = random_similarity(rng, log_scale)
    x = rng.normal(size=(5, 3))
    assert np.allclose(S.screw(a)(S.screw(b)(x)), S.screw(a + b)(x), atol=1e-9)
    assert np.allclose(S.screw(0.0)(x), x, atol=1e-12)
    assert np.allclose(S.screw(1.0 - 1e-13)(x), S(x), atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(-1.0, 1.0))
def test_both_paths_start_at_the_identity_and_end_at_the_similarity(seed, log_scale):
    """``at(1)`` and ``screw(1)`` are the similarity itself (bitwise), ``at(0)`` and
    ``screw(0)`` the identity; the map is ``x ↦ c + b + s R (x − c)`` with R by Rodrigues'
    formula."""
    rng = np.random.default_rng(seed)
    S = random_similarity(rng, log_scale)
    x = rng.normal(size=(7, 3))
    R = rodrigues(S.rotvec, S.angle)
    assert np.allclose(S(x), S.centre + S.shift + np.exp(log_scale) * (x - S.centre) @ R.T,
                       atol=1e-12)
    assert np.array_equal(S.at(1.0)(x), S(x)) and np.array_equal(S.screw(1.0)(x), S(x))
    assert np.allclose(S.at(0.0)(x), x, atol=1e-14)
    assert np.allclose(S.screw(0.0)(x), x, atol=1e-12)
    assert np.allclose(S.inverse(S(x)), x, atol=1e-12)
    assert np.allclose(S(S.inverse(x)), x, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.floats(0.0, 1.0),
       st.one_of(st.just(0.0), st.floats(-0.7, -0.05), st.floats(0.05, 0.7)),
       st.floats(-2.0, 2.0), st.floats(0.1, 3.0))
def test_paths_against_closed_forms(t, log_scale, lift, angle):
    """A spiral about the axis line through ``p`` (direction ``u``), scale ``s``, lift ``h``
    along ``u``: ``screw(t)`` is ``p + s^t R(θt)(x − p) + h (s^t − 1)/(s − 1) u`` and
    ``at(t)`` turns and scales by ``t`` about the centre, which moves along the chord."""
    u, p = np.array([1.0, 2.0, -2.0]) / 3.0, np.array([0.3, -1.1, 0.4])
    s, x = np.exp(log_scale), np.random.default_rng(1).normal(size=(6, 3))
    c = x.mean(axis=0)
    target = p + s * (x - p) @ rodrigues(u, angle).T + lift * u
    S = fit_similarity_3d(x, target)
    assert np.allclose(S(x), target, atol=1e-12)
    along = t if log_scale == 0.0 else (s**t - 1) / (s - 1)
    screw = p + s**t * (x - p) @ rodrigues(u, t * angle).T + along * lift * u
    assert np.allclose(S.screw(t)(x), screw, atol=1e-10)
    image = p + s * (c - p) @ rodrigues(u, angle).T + lift * u
    chord = c + t * (image - c) + s**t * (x - c) @ rodrigues(u, t * angle).T
    assert np.allclose(S.at(t)(x), chord, atol=1e-10)


def test_fit_without_scaling_and_degenerate_inputs():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(9, 3))
    R = rodrigues([0.0, 1.0, 1.0], 0.8)
    S = fit_similarity_3d(X, 2.5 * X @ R.T, scaling=False)
    assert S.log_scale == 0.0 and np.allclose(S.rotation, R, atol=1e-12)
    # two points or coincident ones: the translation of the centroid
    for src in (X[:2], np.repeat(X[:1], 4, axis=0)):
        S = fit_similarity_3d(src, src + [1.0, 2.0, 3.0])
        assert np.array_equal(S.rotvec, np.zeros(3)) and S.log_scale == 0.0
        assert np.allclose(S.shift, [1.0, 2.0, 3.0])
    assert Similarity3.identity().is_identity
    assert global_similarity(X, 0.5 * X @ R.T + 1.0, 1.0) is not None
    assert global_similarity(X, X + 1e-3 * rng.normal(size=X.shape), 1.0) is None
    assert global_similarity(X[:1] * np.arange(4)[:, None], X[:4], 1.0) is None  # collinear


def strip(n: int = 6):
    """A flat strip of 2n triangles along x and its vertices (2(n + 1), 3)."""
    V = np.array([[i, j, 0.0] for i in range(n + 1) for j in (0, 1)])
    F = np.array([f for i in range(n) for f in ([2 * i, 2 * i + 2, 2 * i + 1],
                                                 [2 * i + 1, 2 * i + 2, 2 * i + 3])])
    return V, F


def test_handle_groups_and_the_two_motions():
    """Both ends of a strip are groups; "chord" moves each group's centroid along the chord,
    "screw" turns a group about its hinge along the arc; a lone handle moves linearly
    (bitwise); the targets are reached bitwise."""
    V, F = strip()
    handles = np.array([0, 1, 2, 3, 10, 11, 12, 13, 6])
    groups = handle_groups(handles, F, len(V))
    assert [list(g) for g in groups] == [[0, 1, 2, 3], [4, 5, 6, 7], [8]]
    pivot, R = np.array([6.0, 0.0, 0.0]), rodrigues([0.0, 1.0, 0.0], 1.2)
    targets = V[handles].copy()
    targets[4:8] = pivot + (V[handles[4:8]] - pivot) @ R.T
    targets[8] += [0.1, 0.2, 0.3]
    chord = HandlePath(V[handles], targets, groups, motion="chord")
    screw = HandlePath(V[handles], targets, groups, motion="screw")
    for t in (0.3, 0.7):
        c0, c1 = V[handles[4:8]].mean(0), targets[4:8].mean(0)
        assert np.allclose(chord(t)[4:8].mean(0), (1 - t) * c0 + t * c1, atol=1e-12)
        arc = pivot + (V[handles[4:8]] - pivot) @ rodrigues([0.0, 1.0, 0.0], 1.2 * t).T
        assert np.allclose(screw(t)[4:8], arc, atol=1e-12)
        for path in (chord, screw):
            assert np.array_equal(path(t)[8], V[6] + t * (targets[8] - V[6]))
            assert np.allclose(path(t)[:4], V[handles[:4]], atol=1e-14)
    assert np.array_equal(chord(1.0), targets) and np.array_equal(screw(1.0), targets)
    assert chord.similarities[2] is None
    with pytest.raises(OptionError):
        HandlePath(V[handles], targets, groups, motion="spiral")
