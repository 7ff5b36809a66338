"""The one sparse-solver layer: SPD factorizations, preconditioned CG and the "auto" rule.

Every sparse symmetric positive definite solve of the library goes through here: the P1
Poisson solver (:class:`.fem.PoissonSolver`), the elasticity metric
(:func:`.elasticity.factorize`), as-rigid-as-possible interpolation, and the motion
package's path and continuation systems. Factorize once, reuse the returned solve.
"""

from __future__ import annotations

import importlib.util
import logging
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ._linalg import dot
from .errors import MeshoptError
from ._typing import FloatArray

logger = logging.getLogger(__name__)

SOLVERS = ("auto", "direct", "amg")


def choose_method(method: str, n_unknowns: int, amg_from: int) -> str:
    """The one "auto" rule: ``"amg"`` for systems of at least ``amg_from`` unknowns when
    pyamg is installed, ``"direct"`` otherwise; explicit choices are only validated.

    Parameters
    ----------
    method : "auto", "direct" or "amg"
    n_unknowns : size of the system
    amg_from : size from which AMG beats the direct solver for this kind of matrix
        (measured per problem: scalar Poisson and vector elasticity differ)

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


def factorize_spd(A: sp.spmatrix) -> Callable[[FloatArray], FloatArray]:
    """SuperLU factorization of an SPD matrix, returned as its ``solve``.

    Symmetric mode, no pivoting (an SPD matrix needs none) and minimum-degree ordering on
    ``A + Aᵀ``: about half the fill and time of SuperLU's general defaults.
    """
    from scipy.sparse.linalg import splu

    lu = splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
              options={"SymmetricMode": True})
    return lu.solve


def pcg(A, b: FloatArray, precondition: Callable[[FloatArray], FloatArray], rtol: float,
        maxiter: int) -> tuple[FloatArray, int, float]:
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
    maxiter : iteration cap

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
    for iteration in range(1, maxiter + 1):
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


def amg_pcg_solve(A, ml, rtol: float, maxiter: int = 500) -> Callable[[FloatArray], FloatArray]:
    """``b ↦ x`` with ``‖b − Ax‖ ≤ rtol ‖b‖``: :func:`pcg` preconditioned by one V-cycle of
    the pyamg hierarchy ``ml`` (built once for ``A``, reused for every right-hand side).

    Raises
    ------
    MeshoptError
        When CG does not reach ``rtol`` within ``maxiter`` iterations.
    """
    def precondition(r: FloatArray) -> FloatArray:
        x = np.zeros_like(r)
        _v_cycle(ml, 0, x, r)
        return x

    def solve(b: FloatArray) -> FloatArray:
        x, iterations, residual = pcg(A, b, precondition, rtol, maxiter)
        if residual > rtol:
            raise MeshoptError(f"AMG-preconditioned CG did not converge: relative residual "
                               f"{residual:.2e} > {rtol:.1e} after {iterations} iterations")
        logger.debug("AMG-PCG: %d iterations, relative residual %.2e", iterations, residual)
        return x

    return solve
