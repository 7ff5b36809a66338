"""When the elasticity metric factorizes a new iterate instead of solving by CG on the
factor it keeps: :func:`refactorize_pays` on the operation counts of
:class:`KeptFactorCosts` (docs/design-notes.md, "Elasticity metric at scale"), and
:class:`FactorOf`, a solve that stays its matrix's when the factor is refactorized in place."""

from __future__ import annotations

import numpy as np

from .._linalg import dot
from .._typing import FloatArray
from ..fem.elasticity import SPDSolve

__all__ = ["FactorOf", "KeptFactorCosts", "owned_factor", "refactorize_pays"]

#: at the iterate after a factorization (no CG measured on it yet) the first kept
#: iterate's CG cost of the last cycle that had one stands for it; a factorization made
#: on that estimate at this many iterates in a row lets the next one measure CG again
PROBE_EVERY = 4

#: a supernodal factorization's multiply-adds run in dense blocks (BLAS-3), about this
#: many times faster than those of a triangular solve with one right-hand side, which
#: reads the whole factor for two multiply-adds per entry (measured with CHOLMOD on the
#: elasticity metric, ``benchmarks/bench_shape2d.py``)
FACTORIZATION_SPEED = 3.0


def refactorize_pays(cycle_cost: float, cycle_iterates: int, next_cost: float) -> bool:
    """Whether to factorize at a new iterate instead of solving by CG on the kept factor.

    A factorization at one iterate followed by CG solves preconditioned by it at the next
    ones costs ``cycle_cost`` over the ``cycle_iterates`` iterates since that
    factorization (its iterate included); CG's cost grows as the
    iterates move away from the factor. The average cost per iterate is least when the
    cycle ends as soon as the next iterate's CG cost, ``next_cost`` (estimated by the
    last iterate's), reaches the cycle's average so far: then a new factorization pays.
    """
    return cycle_iterates > 1 and next_cost * cycle_iterates >= cycle_cost


class KeptFactorCosts:
    """Operation counts (multiply-adds) of a kept Cholesky factor and of the CG solves it
    preconditions, for :func:`refactorize_pays`: the factorization ``Σ c_j²`` over the
    column counts ``c_j`` of ``L`` (divided by :data:`FACTORIZATION_SPEED`), a solve with
    the factor ``2 nnz(L)`` (two triangular solves), a CG iteration that solve and a
    product with ``A`` (``nnz(A)``)."""

    __slots__ = ("factorization", "cg_iteration", "cycle_cost", "cycle_iterates",
                 "iterate_cost", "first_kept", "estimated")

    def __init__(self, column_counts: np.ndarray, nnz_matrix: int,
                 previous: "KeptFactorCosts | None" = None) -> None:
        counts = np.asarray(column_counts, dtype=np.float64)
        self.factorization = float(dot(counts, counts)) / FACTORIZATION_SPEED
        self.cg_iteration = 2.0 * float(counts.sum()) + float(nnz_matrix)
        self.cycle_cost = self.factorization
        self.cycle_iterates = 1  # the factorization's iterate
        self.iterate_cost = 0.0  # CG at the last iterate
        # the CG cost of the first kept iterate of the last cycle that had one (None:
        # none yet), and how many factorizations in a row were made on it
        self.first_kept = None if previous is None else previous.first_kept
        self.estimated = 0 if previous is None else previous.estimated

    @classmethod
    def of(cls, solver, nnz_matrix: int,
           previous: "KeptFactorCosts | None" = None) -> "KeptFactorCosts | None":
        """The counts of a direct solver (``fem.elasticity.SPDSolve``) whose factor
        reports its column counts (``CholeskyFactor.column_counts``), with the first kept
        iterate's CG cost carried over from the ``previous`` factor's counts; None for
        another (SuperLU, AMG, ``cvxopt``'s CHOLMOD): such a factor is kept until CG
        needs more than ``REFACTOR_AFTER_CG`` iterations."""
        counts = getattr(solver.solve, "column_counts", None)
        counts = counts() if callable(counts) else None
        return None if counts is None else cls(counts, nnz_matrix, previous)

    def add_cg(self, iterations: int) -> None:
        """A CG solve of ``iterations`` at the current iterate."""
        self.iterate_cost += iterations * self.cg_iteration
        self.cycle_cost += iterations * self.cg_iteration

    def start_iterate(self) -> bool:
        """At a new iterate: whether a factorization pays (:func:`refactorize_pays`, the
        last iterate's CG cost as the estimate); if not, the iterate joins the cycle.

        Right after a factorization no CG cost is known: there a factorization pays when
        the last measured first kept iterate cost at least a factorization (a cycle of one
        iterate costs less on average than one of two), except after
        :data:`PROBE_EVERY` such factorizations in a row, when CG is measured again."""
        if self.cycle_iterates == 1:
            if (self.first_kept is not None and self.estimated < PROBE_EVERY
                    and self.first_kept >= self.factorization):
                self.estimated += 1
                return True
            self.estimated = 0
        elif self.cycle_iterates == 2:
            self.first_kept = self.iterate_cost
        if refactorize_pays(self.cycle_cost, self.cycle_iterates, self.iterate_cost):
            return True
        self.cycle_iterates += 1
        self.iterate_cost = 0.0
        return False


class FactorOf:
    """The direct solve of ``matrix`` by a CHOLMOD factor
    (:class:`~meshopt_toolkit._cholmod.CholeskyFactor`) that the metric may refactorize
    in place for a later ``Q``: a holder of this solve then gets a factor of its own
    ``matrix`` (made once, in the same ordering), never another matrix's solution."""

    def __init__(self, factor, matrix) -> None:
        self.factor, self.matrix = factor, matrix
        self.generation = factor.generation
        self.column_counts = factor.column_counts
        self._own = None

    def __call__(self, b: FloatArray) -> FloatArray:
        if self.factor.generation == self.generation:
            return self.factor(b)
        if self._own is None:
            self._own = type(self.factor)(self.matrix, self.factor.ordering)
        return self._own(b)


def owned_factor(solve: SPDSolve) -> SPDSolve:
    """``solve`` with a CHOLMOD factor wrapped in :class:`FactorOf` (others as they are)."""
    if not (solve.method == "direct" and solve.precondition is solve.solve
            and callable(getattr(solve.solve, "refactorize", None))):
        return solve
    return SPDSolve("direct", FactorOf(solve.solve, solve.matrix), solve.matrix,
                    solve.solve)
