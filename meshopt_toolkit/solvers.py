"""The one sparse-solver layer: SPD factorizations, preconditioned CG and the "auto" rule.

Every sparse symmetric positive definite solve of the library goes through here: the P1
Poisson solver (:class:`.fem.PoissonSolver`), the elasticity metric
(:func:`.elasticity.factorize`), as-rigid-as-possible interpolation, and the motion
package's path and continuation systems; the Stokes saddle-point systems by CG on the
Schur complement over a factor of the velocity block, or block-preconditioned MINRES. Factorize once, reuse the returned solve.
"""

from __future__ import annotations

import hashlib
import importlib.util
import logging
import threading
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ._cholmod import CholeskyFactor
from ._linalg import dot
from ._typing import FloatArray, IntArray
from .errors import MeshoptError

logger = logging.getLogger(__name__)

SOLVERS = ("auto", "direct", "amg")
#: a linear solve or preconditioner ``b ↦ x``
Solve = Callable[[FloatArray], FloatArray]
_ORDERINGS_LOCK = threading.Lock()  # nested_dissection may be called from threads


def choose_method(method: str, n_unknowns: int, amg_from: int) -> str:
    """The one "auto" rule: ``"amg"`` for systems of at least ``amg_from`` unknowns when
    pyamg is installed, ``"direct"`` otherwise; explicit choices are only validated.

    Parameters
    ----------
    method : "auto", "direct" or "amg"
    n_unknowns : size of the system
    amg_from : size from which AMG beats the direct solver for this kind of matrix
        (it differs between problems: scalar Poisson and vector elasticity)

    Returns
    -------
    "direct" or "amg"
    """
    if method not in SOLVERS:
        raise ValueError(f"solver must be one of {SOLVERS}, got {method!r}")
    if method != "auto":
        return method
    if n_unknowns < amg_from:
        return "direct"
    if importlib.util.find_spec("pyamg") is None:  # pragma: no cover - environment
        logger.info("pyamg not installed: using the direct solver")
        return "direct"
    return "amg"


def cholmod_available() -> bool:
    """Whether CHOLMOD (SuiteSparse's supernodal sparse Cholesky, as built into the
    ``cvxopt`` wheel) can be imported."""
    return importlib.util.find_spec("cvxopt") is not None


def cholesky_spd(A: sp.spmatrix, ordering: IntArray | None = None) -> CholeskyFactor:
    """CHOLMOD's Cholesky factorization of an SPD matrix (:class:`CholeskyFactor`), to
    call as its ``solve``."""
    return CholeskyFactor(A, ordering)


def factorize_spd(A: sp.spmatrix, ordering: IntArray | None = None, single: bool = False
                  ) -> Solve:
    """Factorization of an SPD matrix, returned as its ``solve``: CHOLMOD's Cholesky
    (:func:`cholesky_spd`) where it is installed and ``single`` is not asked for,
    SuperLU otherwise.

    SuperLU in symmetric mode, no pivoting (an SPD matrix needs none) and, without
    ``ordering``, minimum-degree ordering on ``A + Aᵀ``: about half the fill and time of
    SuperLU's general defaults. ``single`` keeps SuperLU because its float32 factors
    halve the memory traffic (CHOLMOD factorizes in double precision only).

    Parameters
    ----------
    A : (n, n) sparse SPD matrix
    ordering : (n,) int array, optional
        A fill-reducing permutation (new → old, e.g. from :func:`nested_dissection`) used
        instead of minimum degree: the factorization is of ``A[ordering][:, ordering]``.
    single : bool
        Factorize and solve in single precision (the solve takes and returns float64):
        for a preconditioner, where float32 accuracy is enough. Half the memory traffic:
        on the motion's Gauss–Newton matrices (42.6k triangles) factorization and
        triangular solves take about 25 % less time, with the same CG iterations.
        Falls back to double precision where rounding to float32 makes ``A`` singular.

    Raises
    ------
    RuntimeError
        Where ``A`` is exactly singular (SuperLU) or not positive definite (CHOLMOD).
    """
    if not single and cholmod_available():
        return cholesky_spd(A, ordering)
    return _superlu_spd(A, ordering, single)


def _superlu_spd(A: sp.spmatrix, ordering: IntArray | None, single: bool) -> Solve:
    """:func:`factorize_spd` by SuperLU (symmetric mode, no pivoting)."""
    from scipy.sparse.linalg import splu

    options = {"diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}
    p = np.arange(A.shape[0]) if ordering is None else np.asarray(ordering)
    spec = "MMD_AT_PLUS_A" if ordering is None else "NATURAL"
    permuted = sp.csc_matrix(A if ordering is None else sp.csr_matrix(A)[p][:, p])
    dtype = np.float32 if single else np.float64
    try:
        lu = splu(permuted.astype(dtype), permc_spec=spec, **options)
    except RuntimeError:  # exactly singular (in float32: a double-precision fallback)
        if not single:
            raise
        return factorize_spd(A, ordering)  # double precision, by CHOLMOD where installed

    def solve(b: FloatArray) -> FloatArray:
        x = np.empty_like(b)
        x[p] = lu.solve(b[p].astype(dtype, copy=False))
        return x

    return solve


def refined_spd_solve(A: sp.spmatrix, ordering: IntArray, rtol: float, max_iterations: int = 50
                      ) -> tuple[Solve, Solve]:
    """A solve of an SPD system to the relative residual ``rtol`` from a float32
    factorization: :func:`pcg` preconditioned by ``factorize_spd(A, ordering, single=True)``
    (a few iterations: the float32 factor is ``A``'s own up to rounding).

    Less factor memory and time than a double-precision factorization
    (``docs/benchmarks.md``, "Solver choices"). Where CG does not converge within
    ``max_iterations`` (the float32 factor too far off), the matrix is factorized in double
    precision once and that factor preconditions from then on.

    Returns
    -------
    solve : ``b ↦ x`` with ``‖b − Ax‖ ≤ rtol ‖b‖``
    precondition : the factor's own (approximate) solve, for preconditioning nearby
        matrices
    """
    csr = sp.csr_matrix(A)
    factor = {"solve": factorize_spd(A, ordering, single=True), "single": True}

    def solve(b: FloatArray) -> FloatArray:
        try:
            x, _, residual = pcg(csr, b, factor["solve"], rtol, max_iterations)
        except FloatingPointError:
            residual = np.inf
        if residual <= rtol:
            return x
        if factor["single"]:
            factor.update(solve=factorize_spd(A, ordering), single=False)
            return solve(b)
        raise MeshoptError(f"CG preconditioned by a double-precision factorization did not "
                           f"reach the relative residual {rtol:.1e} ({residual:.1e})")

    return solve, lambda b: factor["solve"](b)


_ORDERINGS: dict = {}  # the last few nested-dissection orderings, by their inputs


def nested_dissection(points: FloatArray, graph: sp.spmatrix, block: int = 1, leaf: int = 16
                      ) -> IntArray:
    """Geometric nested dissection of a mesh graph: a fill-reducing ordering for
    :func:`factorize_spd`.

    The vertices are split at the median of their longer extent; the vertices of the
    first half adjacent to the second separate them and are numbered last, after both
    halves (ordered the same way, down to ``leaf`` vertices). On planar meshes this
    gives less fill than minimum degree and faster factorizations
    (``docs/benchmarks.md``, "Solver choices"). The result depends only on the inputs and is kept
    for the next calls with the same ones (the rounds of a computation).

    Parameters
    ----------
    points : (n, 2) float array
        Vertex positions (any embedding of the graph that is close to planar).
    graph : (block·n, block·n) sparse matrix
        Its nonzero pattern is the (symmetric) adjacency; with ``block > 1``, of the
        vertices' unknowns, ``block`` consecutive ones per vertex (``x, y`` interleaved).
    block : int
        Unknowns per vertex: they are kept together, in their order.
    leaf : int
        Parts of at most this many vertices are not split further.

    Returns
    -------
    (block·n,) int array: the ordering of the unknowns, new → old.
    """
    points = np.asarray(points, float)
    adjacency = sp.csr_matrix(graph)[::block, ::block]
    key = hashlib.blake2b(points.tobytes() + adjacency.indptr.tobytes()
                          + adjacency.indices.tobytes() + bytes(f"{block} {leaf}", "ascii")
                          ).digest()
    with _ORDERINGS_LOCK:
        cached = _ORDERINGS.get(key)
    if cached is not None:
        return cached
    vertices = _dissection_order(points, adjacency, leaf)
    order = (block * vertices[:, None] + np.arange(block)).ravel()
    with _ORDERINGS_LOCK:
        if len(_ORDERINGS) >= 4:
            _ORDERINGS.pop(next(iter(_ORDERINGS)))
        _ORDERINGS[key] = order
    return order


def _dissection_order(points: FloatArray, adjacency: sp.csr_matrix, leaf: int) -> IntArray:
    """The vertex order of :func:`nested_dissection`, one level of the recursion at a time
    over all parts at once (numpy over the vertices and edges, no Python loop over parts).

    Recursively, a part is split at the median of its longer extent (ties by index), the
    first half's vertices adjacent to the second half form the separator, and the order
    is: the first half without the separator, the second half (both ordered the same
    way), the separator (by the coordinate). Here each vertex carries the digits of its
    path down the recursion (0 first half, 1 second half, 2 separator) as a sort key, kept
    dense after every level; a leaf (≤ ``leaf`` vertices) is ordered by index.
    """
    n = points.shape[0]
    coo = sp.triu(adjacency, k=1).tocoo()  # each edge once (the pattern is symmetric)
    u, v = coo.row.astype(np.int64), coo.col.astype(np.int64)
    key = np.zeros(n, np.int64)
    tiebreak = np.arange(n)  # leaves: by index; separators: by their rank in the split
    part = np.zeros(n, np.int64)  # the part of each vertex still being split, else -1
    while True:
        active = np.flatnonzero(part >= 0)
        if active.size == 0:
            break
        p = part[active]
        counts = np.bincount(p)
        splits = counts[p] > leaf
        part[active[~splits]] = -1  # leaves: done
        key *= 3
        active, p = active[splits], p[splits]
        if active.size == 0:
            break
        counts[counts <= leaf] = 0  # the parts split at this level only
        m = counts.size
        low, high = np.full((m, 2), np.inf), np.full((m, 2), -np.inf)
        for axis in (0, 1):
            np.minimum.at(low[:, axis], p, points[active, axis])
            np.maximum.at(high[:, axis], p, points[active, axis])
        longer = np.argmax(high - low, axis=1)
        lowest = low[np.arange(m), longer]
        span = np.maximum(high[np.arange(m), longer] - lowest, np.finfo(float).tiny)
        # by part, then the coordinate along the part's longer extent, then index: one
        # stable sort of part + (coordinate's position in the part's extent) / 2 instead
        # of a lexsort of two keys (35 % less time at 429k triangles); coordinates closer
        # than ~1e-11 of their part's extent may then count as ties
        coordinate = points[active, longer[p]]
        ranked = np.argsort(p + 0.5 * (coordinate - lowest[p]) / span[p], kind="stable")
        starts = np.concatenate([[0], np.cumsum(counts)])
        rank = np.empty(active.size, np.int64)
        rank[ranked] = np.arange(active.size) - starts[p[ranked]]
        second = np.zeros(n, bool)
        second[active] = rank >= counts[p] // 2
        live = (part[u] == part[v]) & (part[u] >= 0)  # edges inside a part being split
        separator = np.zeros(n, bool)  # the first half's ends of edges to the second
        separator[u[live & ~second[u] & second[v]]] = True
        separator[v[live & ~second[v] & second[u]]] = True
        digit = np.where(separator[active], 2, second[active].astype(np.int64))
        key[active] += digit
        tiebreak[active[digit == 2]] = rank[digit == 2]
        part[active] = np.where(digit == 2, -1, 2 * p + digit)
        inside = (part[u] >= 0) & (part[u] == part[v])  # the edges still needed
        u, v = u[inside], v[inside]
        if key.max() > 2**60:  # keep the keys dense enough not to overflow (>38 levels)
            key = np.unique(key, return_inverse=True)[1].astype(np.int64)
    return np.lexsort((tiebreak, key))


def pcg(A, b: FloatArray, precondition: Solve, rtol: float,
        max_iterations: int) -> tuple[FloatArray, int, float]:
    """Preconditioned conjugate gradients from ``x = 0`` to ``‖b − Ax‖ ≤ rtol ‖b‖``.

    Inner products through :func:`._linalg.dot` (single-threaded): multi-threaded BLAS
    ``ddot`` wakes its threads on every call, which costs milliseconds per call on a busy
    machine — scipy's ``cg`` spent half of ``move``'s time there.

    Parameters
    ----------
    A : sparse matrix or anything with ``A @ p``, symmetric positive definite
    b : right-hand side
    precondition : ``r ↦ P⁻¹ r`` with ``P`` symmetric positive definite
    rtol : relative residual to reach
    max_iterations : iteration cap

    Returns
    -------
    x : the last iterate
    iterations : how many were done
    relative_residual : ``‖b − Ax‖ / ‖b‖`` (callers decide whether an unconverged ``x``
        is acceptable: an inexact Newton step is, a PDE solve is not)

    Raises
    ------
    FloatingPointError
        If the curvature ``pᵀAp`` is not positive (``A`` or ``P`` not SPD) or ``x`` stops
        being finite.
    """
    x = np.zeros_like(b)
    r = b.copy()
    bnorm = np.sqrt(dot(b, b))
    if bnorm == 0.0:
        return x, 0, 0.0
    z = precondition(r)
    p = z.copy()
    rz = dot(r, z)
    rnorm = bnorm
    iteration = 0
    for iteration in range(1, max_iterations + 1):
        q = A @ p
        curvature = dot(p, q)
        if not curvature > 0:
            raise FloatingPointError("conjugate gradients broke down (pᵀAp ≤ 0)")
        alpha = rz / curvature
        x += alpha * p
        r -= alpha * q
        rnorm = np.sqrt(dot(r, r))
        if rnorm <= rtol * bnorm:
            break
        z = precondition(r)
        rz_next = dot(r, z)
        p *= rz_next / rz
        p += z
        rz = rz_next
    if not np.all(np.isfinite(x)):
        raise FloatingPointError("conjugate gradients broke down (non-finite iterate)")
    return x, iteration, rnorm / bnorm


def import_pyamg():
    """The ``pyamg`` module, or a :class:`MeshoptError` saying how to get it."""
    try:
        import pyamg
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MeshoptError("solver='amg' needs pyamg (pip install pyamg); use "
                           "solver='direct' instead") from exc
    return pyamg


def _v_cycle(ml, lvl: int, x: FloatArray, b: FloatArray) -> None:
    """One V-cycle of a pyamg hierarchy on level ``lvl``, in place on ``x``.

    The same cycle as pyamg's ``solve(maxiter=1)`` without its residual-norm bookkeeping
    (a threaded BLAS call per application).
    """
    level = ml.levels[lvl]
    A = level.A
    level.presmoother(A, x, b)
    coarse_b = level.R @ (b - A @ x)
    if lvl == len(ml.levels) - 2:
        coarse_x = ml.coarse_solver(ml.levels[-1].A, coarse_b)
    else:
        coarse_x = np.zeros_like(coarse_b)
        _v_cycle(ml, lvl + 1, coarse_x, coarse_b)
    x += level.P @ coarse_x
    level.postsmoother(A, x, b)


def v_cycle_precondition(ml) -> Solve:
    """``r ↦`` one V-cycle of the pyamg hierarchy ``ml`` from zero (a symmetric
    preconditioner of the hierarchy's matrix)."""
    def precondition(r: FloatArray) -> FloatArray:
        x = np.zeros_like(r)
        _v_cycle(ml, 0, x, r)
        return x

    return precondition


def converged_pcg(A, b: FloatArray, precondition: Solve, rtol: float, max_iterations: int,
                  what: str) -> FloatArray:
    """:func:`pcg`'s ``x``, which must reach ``rtol`` (a linear solve, not an inexact step).

    Raises
    ------
    MeshoptError
        When CG does not reach ``rtol`` within ``max_iterations`` iterations (the message
        names ``what`` was solved).
    """
    x, iterations, residual = pcg(A, b, precondition, rtol, max_iterations)
    if residual > rtol:
        raise MeshoptError(f"{what} did not converge: relative residual {residual:.2e} > "
                           f"{rtol:.1e} after {iterations} iterations")
    logger.debug("%s: %d iterations, relative residual %.2e", what, iterations, residual)
    return x


def amg_pcg_solve(A, ml, rtol: float, max_iterations: int = 500) -> Solve:
    """``b ↦ x`` with ``‖b − Ax‖ ≤ rtol ‖b‖``: :func:`converged_pcg` preconditioned by one
    V-cycle of the pyamg hierarchy ``ml`` (built once for ``A``, reused for every
    right-hand side); its error where CG does not converge."""
    precondition = v_cycle_precondition(ml)
    return lambda b: converged_pcg(A, b, precondition, rtol, max_iterations,
                                   "AMG-preconditioned CG")


def schur_complement_solve(primal_solve: Solve, B: sp.spmatrix, dual_precondition: Solve,
                           rtol: float, max_iterations: int = 1000) -> Solve:
    """``b ↦ x`` for a saddle-point matrix ``[[A, Bᵀ], [B, 0]]`` with ``A`` SPD and ``B`` of
    full row rank: :func:`pcg` on the Schur complement ``S = B A⁻¹ Bᵀ`` preconditioned by
    ``dual_precondition`` (an SPD ``r ↦ D⁻¹ r`` with ``D`` spectrally equivalent to ``S``:
    for Stokes the pressure mass over the viscosity), each product one solve with ``A``'s
    factor ``primal_solve`` (:func:`factorize_spd`); then ``u = A⁻¹(f − Bᵀp)``. The CG is
    :func:`converged_pcg`, with its error where it does not converge.
    """
    from scipy.sparse.linalg import LinearOperator

    B = sp.csr_matrix(B)
    n_dual, n_primal = B.shape
    BT = B.T.tocsr()
    S = LinearOperator((n_dual, n_dual), matvec=lambda q: B @ primal_solve(BT @ q), dtype=float)

    def solve(b: FloatArray) -> FloatArray:
        f, g = b[:n_primal], b[n_primal:]
        p = converged_pcg(S, B @ primal_solve(f) - g, dual_precondition, rtol,
                          max_iterations, "CG on the Schur complement")
        return np.concatenate([primal_solve(f - BT @ p), p])

    return solve


def minres_block_solve(M: sp.spmatrix, n_primal: int, primal_precondition: Solve,
                       dual_precondition: Solve, rtol: float, max_iterations: int = 2000
                       ) -> Solve:
    """``b ↦ x`` for a symmetric saddle-point matrix ``M = [[A, Bᵀ], [B, 0]]`` by MINRES
    with the block-diagonal SPD preconditioner ``P⁻¹ = diag(primal_precondition,
    dual_precondition)``: ``≈ A⁻¹`` on the first ``n_primal`` unknowns (a factor of a
    spectrally equivalent matrix, a V-cycle) and ``≈ S⁻¹`` on the rest, ``S`` the Schur
    complement (for Stokes the pressure mass over the viscosity).

    MINRES (scipy's) stops on the residual in the preconditioner's norm ``‖r‖_{P⁻¹}``, the
    one that weighs the two blocks alike (the Euclidean norm mixes velocity and pressure
    residuals of different units), at ``rtol`` relative to its estimate of
    ``‖M‖‖x‖ + ‖b‖``.

    Raises
    ------
    MeshoptError
        When MINRES does not reach ``rtol`` within ``max_iterations`` iterations.
    """
    import inspect

    from scipy.sparse.linalg import LinearOperator, minres

    def precondition(r: FloatArray) -> FloatArray:
        return np.concatenate([primal_precondition(r[:n_primal]),
                               dual_precondition(r[n_primal:])])

    P = LinearOperator(M.shape, matvec=precondition, dtype=float)
    key = "rtol" if "rtol" in inspect.signature(minres).parameters else "tol"

    def solve(b: FloatArray) -> FloatArray:
        x, info = minres(M, b, M=P, maxiter=max_iterations, **{key: rtol})
        if info != 0 or not np.all(np.isfinite(x)):
            raise MeshoptError(f"block-preconditioned MINRES did not converge (info {info})")
        return x

    return solve
