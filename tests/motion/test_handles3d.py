"""Handles of the 3D solvers: checks, each handle once, the vertices a solver sees."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.motion.engine.handles import SolvedVertices, check_handles, distinct_handles


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(0, 9), min_size=1, max_size=30))
def test_distinct_handles_keep_each_once_with_its_first_target(raw):
    h = np.array(raw, np.int64)
    tg = np.column_stack([h, 2.0 * h, -h]).astype(float)  # a vertex's targets agree
    out_h, out_t = distinct_handles(h, tg)
    uniq, first = np.unique(h, return_index=True)
    assert np.array_equal(out_h, uniq) and np.array_equal(out_t, tg[first])


def test_distinct_handles_refuse_two_targets_for_one_vertex():
    with pytest.raises(InvalidMeshError, match="twice with different targets"):
        distinct_handles(np.array([3, 1, 3]), np.array([[0.0, 0, 0], [1, 1, 1], [0, 0, 1]]))


@pytest.mark.parametrize("handles, targets, message", [
    (np.array([], np.int64), np.zeros((0, 3)), "non-empty"),
    (np.array([0.5]), np.zeros((1, 3)), "non-empty"),
    (np.array([7]), np.zeros((1, 3)), "out of range"),
    (np.array([1, 2]), np.zeros((2, 2)), r"shape \(2, 3\)"),
])
def test_check_handles_names_what_is_wrong(handles, targets, message):
    with pytest.raises(InvalidMeshError, match=message):
        check_handles(handles, targets, 5)


def test_solved_vertices_leave_out_vertices_in_no_cell():
    P = np.arange(18, dtype=float).reshape(6, 3)
    cells = np.array([[0, 2, 3, 5]])  # vertices 1 and 4 are in no cell
    h = np.array([1, 3, 4])
    tg = np.array([[9.0, 9, 9], [8, 8, 8], [7, 7, 7]])
    s = SolvedVertices(P, cells, h, tg)
    assert np.array_equal(s.points, P[[0, 2, 3, 5]]) and np.array_equal(s.cells, [[0, 1, 2, 3]])
    assert np.array_equal(s.handles, [2]) and np.array_equal(s.targets, [[8.0, 8, 8]])
    Q = s.points + 100.0
    full = s.full(Q)
    assert np.array_equal(full[[0, 2, 3, 5]], Q)
    assert np.array_equal(full[[1, 4]], [[9.0, 9, 9], [7, 7, 7]])
