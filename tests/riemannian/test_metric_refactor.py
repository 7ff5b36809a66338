"""The elasticity metric's choice between its kept factor (CG) and a new factorization
(:func:`refactorize_pays`, by operation counts) and the solves either choice gives."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from conftest import grid_mesh
from hypothesis import given, settings
from hypothesis import strategies as st

import meshopt_toolkit.riemannian.metrics as metrics
from meshopt_toolkit.riemannian.kept_factor import (FACTORIZATION_SPEED, PROBE_EVERY,
                                                    KeptFactorCosts, refactorize_pays)
from meshopt_toolkit.riemannian.metrics import ElasticityMetric
from meshopt_toolkit._cholmod import library
from meshopt_toolkit.solvers import factorize_spd, pcg

needs_counts = pytest.mark.skipif(
    library() is None, reason="needs CHOLMOD through ctypes (the factor's column counts)")


def _stop(factorization, costs):
    """The cycle length (iterates since the factorization's, included) after which the
    rule, told each next iterate's CG cost, refactorizes; None: not within ``costs``."""
    for k in range(2, len(costs) + 1):
        if refactorize_pays(factorization + sum(costs[:k - 1]), k, costs[k - 1]):
            return k
    return None


@settings(max_examples=200, deadline=None)
@given(st.floats(1e-3, 1e3), st.lists(st.floats(0.0, 1e2), min_size=1, max_size=30))
def test_the_rule_ends_the_cycle_of_least_average_cost(factorization, steps):
    """For CG costs that grow with the factor's age, the rule ends the cycle (one
    factorization, then kept iterates; one kept iterate at least, to measure CG) of least
    average cost per iterate, against a brute-force search over the cycle lengths."""
    costs = list(np.cumsum(steps))  # non-decreasing
    average = {k: (factorization + sum(costs[:k - 1])) / k for k in range(2, len(costs) + 2)}
    stop = _stop(factorization, costs)
    stop = len(costs) + 1 if stop is None else stop
    best = min(average.values())
    assert average[stop] <= best * (1 + 1e-12)
    assert all(average[k] > best * (1 - 1e-12) for k in range(2, stop))


def test_the_rule_on_synthetic_costs():
    """Counts from which the decision follows by hand: a cycle of 4 iterates that cost 10
    in all ends when the last iterate's CG cost reaches the average 2.5."""
    assert not refactorize_pays(10.0, 4, 2.4)
    assert refactorize_pays(10.0, 4, 2.5)
    assert not refactorize_pays(0.0, 1, 1e9)  # the factorization's own iterate: keep
    assert not refactorize_pays(np.inf, 50, 1e300)  # a factorization too costly to pay


def test_a_first_kept_iterate_dearer_than_a_factorization_makes_the_next_ones_factorize():
    """Counts by hand (column counts (2, 2): a factorization 8 / FACTORIZATION_SPEED, a CG
    iteration 8): a first kept iterate of one CG iteration costs more than a
    factorization and ends its cycle, and at the iterate after each of the next
    PROBE_EVERY factorizations that estimate says factorize again; then CG is measured
    once more. A first kept iterate cheaper than a factorization is kept."""
    counts = np.array([2.0, 2.0])
    costs = KeptFactorCosts(counts, 0)
    assert (costs.factorization, costs.cg_iteration) == (8.0 / FACTORIZATION_SPEED, 8.0)
    assert not costs.start_iterate()  # nothing measured yet: keep, and measure CG
    costs.add_cg(1)
    assert costs.start_iterate()  # the cycle's average (F + 8)/2 ≤ 8
    for _ in range(PROBE_EVERY):
        costs = KeptFactorCosts(counts, 0, costs)
        assert costs.start_iterate()
    costs = KeptFactorCosts(counts, 0, costs)
    assert not costs.start_iterate()  # measured again
    costs.add_cg(0)
    assert not costs.start_iterate()  # a first kept iterate that cost nothing ...
    costs = KeptFactorCosts(counts, 0, costs)
    assert not costs.start_iterate()  # ... is worth keeping the next factor for


def test_a_refactorization_reuses_the_analysis_and_solves_as_a_fresh_one(mesh, rng):
    """The metric factorizes a new iterate on its kept factor's analysis (the same
    factor object, refactorized in place): each solve equals, to the bit, that of a
    fresh factorization in the same ordering."""
    metric = ElasticityMetric(mesh, solver="direct")
    P = rng.standard_normal(mesh.points.shape)
    metric.riesz(mesh.points, P)
    factor = metric._kept[None].precondition
    for far in (mesh.points * [3.0, 0.2], mesh.points * [0.2, 3.0]):  # CG fails: refactorize
        G = metric.riesz(far, P)
        fresh = factorize_spd(metric.matrix(far), metric._orderings[None])
        assert np.array_equal(G, fresh(P.ravel()).reshape(P.shape))
    assert metric.n_factorizations == 3 and metric._kept[None].precondition is factor


def test_a_solve_handed_out_before_a_refactorization_still_solves_its_own_matrix(mesh, rng):
    """The metric refactorizes its factor in place for a far iterate; the solver it
    returned for the first iterate still solves the first matrix (against SuperLU), and
    the new one the new matrix."""
    metric = ElasticityMetric(mesh, solver="direct")
    b = rng.standard_normal(2 * len(mesh.points))
    first = metric._solver(mesh.points, None)
    far = mesh.points * [3.0, 0.2]
    second = metric._solver(far, None)
    second.solve(b)  # CG on the kept factor fails this far: refactorized in place
    assert metric.n_factorizations == 2 and metric._kept[None].precondition is first.precondition
    for Q, solver in ((mesh.points, first), (far, second)):
        exact = spla.spsolve(metric.matrix(Q).tocsc(), b)
        assert np.linalg.norm(solver.solve(b) - exact) <= 1e-8 * np.linalg.norm(exact)


def _path(mesh, rng, n):
    step = 2e-3 * rng.standard_normal((n,) + mesh.points.shape)
    return [mesh.points + s for s in np.cumsum(step, axis=0)]


@pytest.fixture
def mesh():
    return grid_mesh(8, jitter=0.2, seed=3)


def test_without_counts_the_kept_factor_solves_as_before(mesh, rng, monkeypatch):
    """Where the factor reports no counts (``cvxopt``, SuperLU) the metric keeps the
    factor of the first iterate for all the later ones: each solve equals, to the bit,
    CG preconditioned by that factor, replayed here from the public pieces."""
    monkeypatch.setattr(metrics.KeptFactorCosts, "of", classmethod(lambda cls, s, nnz, previous=None: None))
    metric = ElasticityMetric(mesh, solver="direct")
    path = _path(mesh, rng, 6)
    P = rng.standard_normal(mesh.points.shape)
    first = metric.riesz(path[0], P)
    factor = factorize_spd(metric.matrix(path[0]), metric._orderings[None])
    assert np.array_equal(first, factor(P.ravel()).reshape(P.shape))
    for Q in path[1:]:
        x, _, residual = pcg(metric.matrix(Q), P.ravel(), factor, metric.rtol,
                             ElasticityMetric.REFACTOR_AFTER_CG)
        assert residual <= metric.rtol
        assert np.array_equal(metric.riesz(Q, P), x.reshape(P.shape))
    assert metric.n_factorizations == 1


@needs_counts
def test_the_metric_refactorizes_as_the_rule_says(mesh, rng, monkeypatch):
    """Along a path, the metric factorizes exactly where :func:`refactorize_pays` on the
    recorded CG iterations and the factor's column counts says so, and every solve meets
    the metric's tolerance (checked on the residual)."""
    iterations = []
    real_pcg = metrics.pcg

    def recording(*args, **kwargs):
        out = real_pcg(*args, **kwargs)
        iterations.append(out[1])
        return out

    monkeypatch.setattr(metrics, "pcg", recording)
    metric = ElasticityMetric(mesh, solver="direct")
    P = rng.standard_normal(mesh.points.shape)
    expected = 0
    cycle = iterates = last = factorization = first_kept = None
    estimated = 0
    for Q in _path(mesh, rng, 12):
        A = metric.matrix(Q)
        if cycle is None:
            refactor = True
        elif (iterates == 1 and first_kept is not None and estimated < PROBE_EVERY
              and first_kept >= factorization):
            refactor, estimated = True, estimated + 1
        else:
            estimated = 0 if iterates == 1 else estimated
            first_kept = last if iterates == 2 else first_kept
            refactor = refactorize_pays(cycle, iterates, last)
        if refactor:
            expected += 1
            cycle, iterates, last = None, 1, 0.0
        else:
            iterates, last = iterates + 1, 0.0
        before = len(iterations)
        G = metric.riesz(Q, P)
        assert metric.n_factorizations == expected
        assert np.linalg.norm(P.ravel() - A @ G.ravel()) <= metric.rtol * np.linalg.norm(P)
        counts = metric._kept[None].solve.column_counts()
        per_cg = 2.0 * counts.sum() + A.nnz
        if cycle is None:
            cycle = factorization = float(counts @ counts) / FACTORIZATION_SPEED
        for it in iterations[before:]:
            cycle += it * per_cg
            last += it * per_cg
    assert 1 < metric.n_factorizations < 12  # both choices were made along the path
