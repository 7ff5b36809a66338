"""The sparse-solver layer: the one "auto" rule, the SPD factorization and PCG."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from meshopt_toolkit.solvers import choose_method, factorize_spd, pcg


def _laplacian(n: int, shift: float = 0.1) -> sp.csr_matrix:
    return (sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n)) + shift * sp.eye(n)).tocsr()


def test_auto_rule_and_validation():
    assert choose_method("auto", 10, 100) == "direct"
    assert choose_method("auto", 100, 100) == "amg"  # pyamg is a dependency
    assert choose_method("direct", 10**9, 100) == "direct"
    assert choose_method("amg", 1, 100) == "amg"
    with pytest.raises(ValueError, match="solver must be one of"):
        choose_method("cholmod", 10, 100)


def test_factorize_spd_matches_a_general_solve():
    rng = np.random.default_rng(0)
    A = _laplacian(300)
    b = rng.standard_normal(300)
    assert np.allclose(factorize_spd(A)(b), spsolve(A.tocsc(), b), rtol=1e-12, atol=1e-12)


def test_pcg_reaches_rtol_and_reports_an_unconverged_run():
    rng = np.random.default_rng(3)
    n = 400
    L = _laplacian(n)
    scale = sp.diags(10.0 ** rng.uniform(-2, 2, n))
    S = (scale @ L @ scale).tocsr()  # a badly scaled SPD matrix
    b = rng.standard_normal(n)
    d = S.diagonal()
    for A, precondition in ((L, lambda v: v.copy()), (S, lambda v: v / d)):
        x, iterations, residual = pcg(A, b, precondition, 1e-8, 200)
        assert iterations < 200 and residual <= 1e-8
        assert np.linalg.norm(A @ x - b) <= 1.01e-8 * np.linalg.norm(b)
    x, iterations, residual = pcg(S, b, lambda v: v.copy(), 1e-8, 200)
    assert iterations == 200 and residual > 1e-8 and np.all(np.isfinite(x))
    assert pcg(L, np.zeros(n), lambda v: v, 1e-8, 10)[1:] == (0, 0.0)


def test_pcg_refuses_an_indefinite_matrix():
    A = sp.diags([1.0, -1.0]).tocsr()
    with pytest.raises(FloatingPointError):
        pcg(A, np.array([0.0, 1.0]), lambda v: v, 1e-10, 10)


def test_amg_pcg_solve_reaches_rtol_or_says_it_did_not():
    """The one AMG path (Poisson and elasticity): a V-cycle-preconditioned CG reaching
    the relative residual asked for, or a one-line error when capped."""
    from meshopt_toolkit.errors import MeshoptError
    from meshopt_toolkit.solvers import amg_pcg_solve, import_pyamg

    rng = np.random.default_rng(5)
    n = 40
    grid = sp.kronsum(_laplacian(n, 0.0), _laplacian(n, 0.0)).tocsr() + 1e-3 * sp.eye(n * n)
    grid = grid.tocsr()
    b = rng.standard_normal(n * n)
    ml = import_pyamg().ruge_stuben_solver(grid)
    x = amg_pcg_solve(grid, ml, 1e-10)(b)
    assert np.linalg.norm(grid @ x - b) <= 1e-10 * np.linalg.norm(b)
    with pytest.raises(MeshoptError, match="did not converge"):
        amg_pcg_solve(grid, ml, 1e-14, maxiter=2)(b)
