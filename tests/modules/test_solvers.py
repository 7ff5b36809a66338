"""The sparse-solver layer: the one "auto" rule, the SPD factorization and PCG."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
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


def test_cholesky_spd_matches_superlu_and_a_general_solve():
    """CHOLMOD's factor (default and nested-dissection order) solves one and several
    right-hand sides to the accuracy of SuperLU's double-precision factor and of a
    general sparse solve."""
    from meshopt_toolkit.solvers import _superlu_spd, cholesky_spd, nested_dissection

    rng = np.random.default_rng(5)
    points, A = _grid(30)
    B = rng.standard_normal((A.shape[0], 3))
    reference = spsolve(A.tocsc(), B)
    for ordering in (None, nested_dissection(points, A)):
        solve = cholesky_spd(A, ordering)
        np.testing.assert_allclose(solve(B), reference, rtol=0, atol=1e-11 * abs(reference).max())
        x = solve(B[:, 0])
        assert x.shape == (A.shape[0],)
        np.testing.assert_allclose(x, _superlu_spd(A, ordering, False)(B[:, 0]), rtol=0,
                                   atol=1e-11 * abs(x).max())


@pytest.fixture(params=["ctypes", "cvxopt"])
def cholmod_route(request, monkeypatch):
    """CHOLMOD called through :mod:`._cholmod` (GIL released) or through cvxopt's own
    interface (where the former does not load)."""
    import meshopt_toolkit._cholmod as native

    if request.param == "ctypes" and native.library() is None:
        pytest.skip("CHOLMOD does not load through ctypes here")
    if request.param == "cvxopt":
        monkeypatch.setattr(native, "library", lambda: None)
    return request.param


def test_cholesky_refactorization_reuses_the_analysis_and_recovers_from_failure(
        rng, cholmod_route):
    """A refactorization of the same pattern solves as a fresh factorization does; a
    different pattern is analysed again; after an indefinite matrix (RuntimeError, and
    the factor refuses to solve) the next SPD one factorizes."""
    from meshopt_toolkit.solvers import CholeskyFactor

    n = 30
    laplacian = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    grid = (sp.kron(laplacian, sp.eye(n)) + sp.kron(sp.eye(n), laplacian)).tocsr()
    b = rng.standard_normal(n * n)
    factor = CholeskyFactor(grid + 0.1 * sp.eye(n * n))
    analysis = factor._factor
    other = (grid + sp.diags(rng.random(n * n))).tocsr()
    factor.refactorize(other)
    assert factor._factor is analysis
    np.testing.assert_allclose(factor(b), CholeskyFactor(other)(b), rtol=0, atol=1e-12)
    assert np.linalg.norm(other @ factor(b) - b) <= 1e-12 * np.linalg.norm(b)
    wider = (other + sp.diags(np.ones(n * n - 2), 2) + sp.diags(np.ones(n * n - 2), -2)
             + 4 * sp.eye(n * n)).tocsr()
    factor.refactorize(wider)
    assert factor._factor is not analysis
    assert np.linalg.norm(wider @ factor(b) - b) <= 1e-12 * np.linalg.norm(b)
    kept = factor._factor
    with pytest.raises(RuntimeError, match="not positive definite"):
        factor.refactorize(wider - 20 * sp.eye(n * n))
    with pytest.raises(RuntimeError, match="failed"):
        factor(b)
    if factor.releases_gil:  # the same pattern again: the kept analysis serves
        factor.refactorize(wider)
        assert factor._factor is kept
        np.testing.assert_allclose(factor(b), CholeskyFactor(wider)(b), rtol=0, atol=1e-12)
    factor.refactorize(other)
    assert np.linalg.norm(other @ factor(b) - b) <= 1e-12 * np.linalg.norm(b)


def test_cholmod_through_ctypes_is_cvxopts_factor_bitwise(monkeypatch):
    """The same library, the same options: the same solutions to the last bit for one
    right-hand side, in minimum-degree and nested-dissection order (several are solved
    together here, column by column by cvxopt: equal to rounding)."""
    import meshopt_toolkit._cholmod as native
    from meshopt_toolkit.solvers import CholeskyFactor, nested_dissection

    if native.library() is None:
        pytest.skip("CHOLMOD does not load through ctypes here")
    rng = np.random.default_rng(3)
    points, A = _grid(40)
    A = (A + sp.diags(rng.random(A.shape[0]))).tocsr()
    B = rng.standard_normal((A.shape[0], 3))
    for ordering in (None, nested_dissection(points, A)):
        factor = CholeskyFactor(A, ordering)
        assert factor.releases_gil
        with monkeypatch.context() as patch:
            patch.setattr(native, "library", lambda: None)
            reference = CholeskyFactor(A, ordering)
        assert not reference.releases_gil
        for j in range(B.shape[1]):
            np.testing.assert_array_equal(factor(B[:, j]), reference(B[:, j]))
        np.testing.assert_allclose(factor(B), reference(B), rtol=0,
                                   atol=1e-13 * np.abs(reference(B)).max())
        assert factor(B[:, 1]).shape == (A.shape[0],)


def test_cholmod_factors_solve_in_threads_as_one_after_another():
    """Several factors factorized and solved at once in threads (and one factor from two
    threads: its lock) give what they give one at a time."""
    from concurrent.futures import ThreadPoolExecutor

    import meshopt_toolkit._cholmod as native
    from meshopt_toolkit.solvers import CholeskyFactor

    if native.library() is None:
        pytest.skip("CHOLMOD does not load through ctypes here")
    rng = np.random.default_rng(4)
    _, A = _grid(60)
    matrices = [(A + sp.diags(rng.random(A.shape[0]))).tocsr() for _ in range(4)]
    b = rng.standard_normal(A.shape[0])
    serial = [CholeskyFactor(M)(b) for M in matrices]
    with ThreadPoolExecutor(4) as pool:
        factors = list(pool.map(CholeskyFactor, matrices))
        for _ in range(3):
            threaded = list(pool.map(lambda f: f(b), factors))
            for x, y in zip(threaded, serial):
                np.testing.assert_array_equal(x, y)
        shared = list(pool.map(lambda _: factors[0](b), range(8)))
    for x in shared:
        np.testing.assert_array_equal(x, serial[0])


def test_cholesky_spd_refuses_an_indefinite_matrix_and_takes_an_empty_one(cholmod_route):
    from meshopt_toolkit.solvers import cholesky_spd

    indefinite = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]]))  # eigenvalues 3, −1
    with pytest.raises(RuntimeError, match="not positive definite"):
        cholesky_spd(indefinite)
    assert cholesky_spd(sp.csr_matrix((0, 0)))(np.zeros(0)).shape == (0,)


def test_factorize_spd_takes_cholmod_in_double_and_superlu_in_single(monkeypatch):
    """Double precision goes to CHOLMOD where it is installed and to SuperLU where not
    (the same solution); single precision always to SuperLU (float32 factors)."""
    import meshopt_toolkit.solvers as solvers

    rng = np.random.default_rng(6)
    A = _laplacian(200)
    b = rng.standard_normal(200)
    calls = []
    original = solvers.cholesky_spd
    monkeypatch.setattr(solvers, "cholesky_spd", lambda *a: calls.append(1) or original(*a))
    with_cholmod = factorize_spd(A)(b)
    assert calls == [1]
    factorize_spd(A, single=True)(b)
    assert calls == [1]
    monkeypatch.setattr(solvers, "cholmod_available", lambda: False)
    without = factorize_spd(A)(b)
    assert calls == [1]
    np.testing.assert_allclose(without, with_cholmod, rtol=1e-12, atol=1e-12)


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
        amg_pcg_solve(grid, ml, 1e-14, max_iterations=2)(b)


def _grid(n: int) -> tuple[np.ndarray, sp.csr_matrix]:
    """An ``n × n`` grid's vertices and its 5-point Laplacian (plus a shift)."""
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    points = np.c_[x.ravel(), y.ravel()]
    L1 = _laplacian(n, 0.0)
    A = sp.kron(sp.eye(n), L1) + sp.kron(L1, sp.eye(n)) + 0.01 * sp.eye(n * n)
    return points, A.tocsr()


def test_nested_dissection_is_a_kept_permutation_with_less_fill():
    from scipy.sparse.linalg import splu

    from meshopt_toolkit.solvers import nested_dissection

    points, A = _grid(40)
    order = nested_dissection(points, A)
    assert np.array_equal(np.sort(order), np.arange(len(points)))
    assert nested_dissection(points, A) is order  # kept for the same inputs
    permuted = sp.csc_matrix(A[order][:, order])
    nd = splu(permuted, permc_spec="NATURAL", diag_pivot_thresh=0.0,
              options={"SymmetricMode": True})
    natural = splu(A.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    assert nd.L.nnz < 0.5 * natural.L.nnz
    pairs = nested_dissection(points, sp.kron(A, np.ones((2, 2))), block=2)
    assert np.array_equal(pairs, np.stack([2 * order, 2 * order + 1], axis=1).ravel())


def _recursive_dissection(points, adjacency, leaf):
    """The definition of nested_dissection's order, written as the plain recursion."""
    side = np.zeros(len(points), np.int8)
    parts = []

    def dissect(nodes):
        if nodes.size <= leaf:
            parts.append(nodes)
            return
        P = points[nodes]
        axis = int(np.argmax(P.max(axis=0) - P.min(axis=0)))
        ranked = nodes[np.argsort(P[:, axis], kind="stable")]
        first, second = ranked[: nodes.size // 2], ranked[nodes.size // 2:]
        side[second] = 2
        touches = np.array([(side[adjacency[i].indices] == 2).any() for i in first], bool)
        side[second] = 0
        dissect(np.sort(first[~touches]))
        dissect(np.sort(second))
        parts.append(first[touches])

    dissect(np.arange(len(points)))
    return np.concatenate(parts)


@settings(max_examples=25, deadline=None)
@given(n=st.integers(3, 400), leaf=st.integers(1, 20), seed=st.integers(0, 2**16))
def test_nested_dissection_is_the_recursion(n, leaf, seed):
    """The level-at-a-time ordering equals the recursion on random point clouds (with
    ties in the coordinates) and their Delaunay graphs."""
    from scipy.spatial import Delaunay

    from meshopt_toolkit.solvers import nested_dissection

    rng = np.random.default_rng(seed)
    points = np.round(rng.random((n, 2)) * rng.choice([4, 1000]), 0) + rng.random((n, 2)) * 1e-3
    tri = Delaunay(points).simplices
    rows, cols = np.repeat(tri, 3, axis=1).ravel(), np.tile(tri, (1, 3)).ravel()
    A = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    points = np.round(points)  # ties in the split coordinate
    assert np.array_equal(nested_dissection(points, A, leaf=leaf),
                          _recursive_dissection(points, A, leaf))


def test_factorize_spd_with_an_ordering_matches_the_default():
    from meshopt_toolkit.solvers import nested_dissection

    rng = np.random.default_rng(1)
    points, A = _grid(25)
    b = rng.standard_normal(A.shape[0])
    x = factorize_spd(A, nested_dissection(points, A))(b)
    assert np.allclose(x, factorize_spd(A)(b), rtol=1e-12, atol=1e-12)
    assert np.allclose(A @ x, b, rtol=1e-10, atol=1e-10)


def test_factorize_spd_in_single_precision():
    """float32 factors solve to float32 accuracy (a preconditioner for PCG in double), also
    in nested-dissection order; a matrix that float32 rounding makes singular is factorized
    in double precision instead."""
    from meshopt_toolkit.solvers import nested_dissection

    rng = np.random.default_rng(2)
    points, A = _grid(20)
    b = rng.standard_normal(A.shape[0])
    exact = factorize_spd(A)(b)
    for ordering in (None, nested_dissection(points, A)):
        x = factorize_spd(A, ordering, single=True)(b)
        assert x.dtype == np.float64
        assert np.abs(x - exact).max() <= 1e-5 * np.abs(exact).max()
        y, iterations, _ = pcg(A, b, factorize_spd(A, ordering, single=True), 1e-12, 50)
        assert iterations <= 4 and np.allclose(y, exact, rtol=1e-10, atol=1e-10)
    near = sp.csr_matrix(np.array([[1.0, 1 - 1e-9], [1 - 1e-9, 1.0]]))  # all 1 in float32
    b2 = np.array([1.0, -1.0])
    assert np.allclose(factorize_spd(near, single=True)(b2), np.linalg.solve(near.toarray(), b2),
                       rtol=1e-6)


def test_refined_spd_solve_reaches_rtol_and_falls_back_to_double():
    """The float32 factor preconditions CG to ``rtol``; where it is too far off to get
    there within ``max_iterations``, the double-precision factor takes over (and stays)."""
    from meshopt_toolkit.solvers import nested_dissection, refined_spd_solve

    rng = np.random.default_rng(4)
    points, A = _grid(20)
    b = rng.standard_normal(A.shape[0])
    solve, precondition = refined_spd_solve(A, nested_dissection(points, A), rtol=1e-12)
    x = solve(b)
    assert np.linalg.norm(b - A @ x) <= 1e-12 * np.linalg.norm(b)
    assert np.allclose(x, spsolve(A.tocsc(), b), rtol=1e-9, atol=1e-9)
    assert np.abs(precondition(b) - x).max() <= 1e-5 * np.abs(x).max()  # float32 accuracy

    # eigenvalues 2 and 1e-6: float32 rounding of the off-diagonal is 6 % of the small one
    near = sp.csr_matrix(np.array([[1.0, 1 - 1e-6], [1 - 1e-6, 1.0]]))
    b2 = np.array([1.0, -0.5])
    _, _, single_residual = pcg(near, b2, factorize_spd(near, single=True), 1e-9, 1)
    assert single_residual > 1e-9  # one float32-preconditioned step is not enough ...
    solve2, precondition2 = refined_spd_solve(near, np.arange(2), rtol=1e-9, max_iterations=1)
    x2 = solve2(b2)  # ... so the double factor did it
    assert np.linalg.norm(b2 - near @ x2) <= 1e-9 * np.linalg.norm(b2)
    assert np.allclose(precondition2(b2), np.linalg.solve(near.toarray(), b2), rtol=1e-8)


def test_cholesky_column_counts_are_those_of_the_dense_factor(rng):
    """The factor's column counts (CHOLMOD's analysis) are the nonzeros of each column of
    NumPy's dense Cholesky factor of the matrix in the factor's permutation."""
    import ctypes

    from meshopt_toolkit import _cholmod as native

    if native.library() is None:
        pytest.skip("CHOLMOD does not load through ctypes here")
    n = 60
    for seed in range(3):
        B = sp.random(n, n, 0.05, random_state=seed)
        A = (B + B.T + 20 * sp.eye(n)).tocsc()
        factor = native.CholeskyFactor(A, rng.permutation(n))
        head = native._FactorHead.from_address(factor._factor._factor.value)
        perm = np.ctypeslib.as_array(ctypes.cast(head.perm, ctypes.POINTER(ctypes.c_int64)),
                                     (n,))
        L = np.linalg.cholesky(A.toarray()[np.ix_(perm, perm)])
        assert np.array_equal(factor.column_counts(), (L != 0).sum(axis=0))


def test_cholesky_column_counts_are_unknown_through_cvxopt(monkeypatch):
    from meshopt_toolkit import _cholmod as native

    monkeypatch.setattr(native, "library", lambda: None)
    assert native.CholeskyFactor(sp.eye(4, format="csc")).column_counts() is None
