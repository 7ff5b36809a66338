"""CHOLMOD's supernodal Cholesky (:class:`CholeskyFactor`), called through ``ctypes``
where it can be, so that factorizations and solves release the GIL and run in threads
side by side.

``cvxopt.cholmod`` (the wheel's CHOLMOD) holds the GIL for the whole factorization or
solve, and its options live in one process-wide ``cholmod_common``: frames' factors were
factorized and solved one after another. Here each factor has its own ``cholmod_common``
and the calls go through :mod:`ctypes` (which releases the GIL), to the same library that
``cvxopt`` loaded, with ``cvxopt``'s settings (supernodal, nothing printed): the same
factors, and the same solutions to the last bit for one right-hand side (several are
solved together here, where ``cvxopt`` solves them one by one; the gain is in
docs/design-notes.md, "Morph solver").

The library is the one bundled with ``cvxopt`` (found next to it); its ``cholmod_common``
is opaque here except for the two options set, whose offsets are checked against
CHOLMOD's documented defaults before anything is written. Where the library is not found
or the check fails, :func:`library` is None and :class:`CholeskyFactor` (the factor the
rest of the package uses, through :mod:`.solvers`) calls ``cvxopt.cholmod`` itself.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
import threading

import numpy as np
import scipy.sparse as sp

from ._typing import FloatArray, IntArray

_COMMON_BYTES = 1 << 16  # more than any CHOLMOD's cholmod_common (about 3 kB)
# byte offsets in cholmod_common (CHOLMOD ≥ 2: the struct's leading fields), each with
# its default after cholmod_l_start, checked before use
_DEFAULTS_F8 = {8: 1.2, 16: 1.2, 40: 40.0, 80: 0.8, 88: 0.1, 96: 0.05}  # grow0/1, switch, zrelax
_DEFAULTS_U8 = {24: 5, 32: 8, 104: 4, 112: 16, 120: 48}  # grow2, maxrank, nrelax
_SUPERNODAL, _SUPERNODAL_DEFAULT = 48, 1  # CHOLMOD_AUTO
_PRINT, _PRINT_DEFAULT = 144, 3
_SUPERNODAL_ALWAYS = 2
_LONG, _REAL, _DOUBLE, _SYSTEM_A = 2, 1, 0, 0  # itype, xtype, dtype, sys


class _Sparse(ctypes.Structure):
    _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t),
                ("nzmax", ctypes.c_size_t), ("p", ctypes.c_void_p), ("i", ctypes.c_void_p),
                ("nz", ctypes.c_void_p), ("x", ctypes.c_void_p), ("z", ctypes.c_void_p),
                ("stype", ctypes.c_int), ("itype", ctypes.c_int), ("xtype", ctypes.c_int),
                ("dtype", ctypes.c_int), ("sorted", ctypes.c_int), ("packed", ctypes.c_int)]


class _Dense(ctypes.Structure):
    _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t),
                ("nzmax", ctypes.c_size_t), ("d", ctypes.c_size_t), ("x", ctypes.c_void_p),
                ("z", ctypes.c_void_p), ("xtype", ctypes.c_int), ("dtype", ctypes.c_int)]


class _FactorHead(ctypes.Structure):
    """The first fields of ``cholmod_factor``: its order, after a failed factorization
    the column where it failed (``minor < n``), and the analysis' column counts of ``L``
    (``ColCount``, n integers of the factor's ``itype``)."""

    _fields_ = [("n", ctypes.c_size_t), ("minor", ctypes.c_size_t),
                ("perm", ctypes.c_void_p), ("col_count", ctypes.c_void_p)]


def _find() -> str | None:
    try:
        import cvxopt
        import cvxopt.cholmod  # noqa: F401  (loads the library and what it links)
    except ImportError:
        return None
    package = os.path.dirname(cvxopt.__file__)
    for folder in (package + ".libs", os.path.join(package, ".dylibs"), package):
        found = sorted(glob.glob(os.path.join(folder, "libcholmod*")))
        if found:
            return found[0]
    return None


@functools.lru_cache(maxsize=1)
def library() -> ctypes.CDLL | None:
    """The CHOLMOD library bundled with ``cvxopt``, its functions declared, where found
    and its ``cholmod_common`` has the expected layout; else None."""
    path = _find()
    if path is None:
        return None
    try:
        lib = ctypes.CDLL(path)
        common = ctypes.c_void_p
        lib.cholmod_l_start.argtypes = [common]
        lib.cholmod_l_finish.argtypes = [common]
        lib.cholmod_l_analyze_p.restype = ctypes.c_void_p
        lib.cholmod_l_analyze_p.argtypes = [ctypes.POINTER(_Sparse), ctypes.c_void_p,
                                            ctypes.c_void_p, ctypes.c_size_t, common]
        lib.cholmod_l_factorize.argtypes = [ctypes.POINTER(_Sparse), ctypes.c_void_p, common]
        lib.cholmod_l_solve.restype = ctypes.POINTER(_Dense)
        lib.cholmod_l_solve.argtypes = [ctypes.c_int, ctypes.c_void_p,
                                        ctypes.POINTER(_Dense), common]
        lib.cholmod_l_free_dense.argtypes = [ctypes.POINTER(ctypes.POINTER(_Dense)), common]
        lib.cholmod_l_free_factor.argtypes = [ctypes.POINTER(ctypes.c_void_p), common]
    except (OSError, AttributeError):
        return None
    buffer = ctypes.create_string_buffer(_COMMON_BYTES)
    lib.cholmod_l_start(buffer)
    try:
        expected = (all(ctypes.c_double.from_buffer(buffer, o).value == v
                        for o, v in _DEFAULTS_F8.items())
                    and all(ctypes.c_size_t.from_buffer(buffer, o).value == v
                            for o, v in _DEFAULTS_U8.items())
                    and ctypes.c_int.from_buffer(buffer, _SUPERNODAL).value == _SUPERNODAL_DEFAULT
                    and ctypes.c_int.from_buffer(buffer, _PRINT).value == _PRINT_DEFAULT)
    finally:
        lib.cholmod_l_finish(buffer)
    return lib if expected else None


class _NativeFactor:
    """``PAPᵀ = LLᵀ`` of a sparse SPD matrix (its lower triangle, CSC with sorted int64
    indices, read in place) by CHOLMOD, the GIL released; one factorization or solve at a
    time per factor (a lock), any number of factors at once.

    Raises RuntimeError (here and in :meth:`refactorize`) where the matrix is not
    positive definite.
    """

    def __init__(self, indptr: IntArray, indices: IntArray, values: FloatArray,
                 ordering: IntArray | None = None) -> None:
        lib = library()
        if lib is None:
            raise RuntimeError("CHOLMOD is not available through ctypes")
        self._lib = lib
        self._lock = threading.Lock()
        self._common = ctypes.create_string_buffer(_COMMON_BYTES)
        lib.cholmod_l_start(self._common)
        ctypes.c_int.from_buffer(self._common, _SUPERNODAL).value = _SUPERNODAL_ALWAYS
        ctypes.c_int.from_buffer(self._common, _PRINT).value = 0
        n = len(indptr) - 1
        self.n = n
        # CHOLMOD reads these arrays in place: they live as long as the factor
        self._indptr = np.ascontiguousarray(indptr, dtype=np.int64)
        self._indices = np.ascontiguousarray(indices, dtype=np.int64)
        self._values = np.array(values, dtype=np.float64)
        self._matrix = _Sparse(n, n, self._values.size, self._indptr.ctypes.data,
                               self._indices.ctypes.data, None, self._values.ctypes.data,
                               None, -1, _LONG, _REAL, _DOUBLE, 1, 1)
        permutation = None if ordering is None else np.ascontiguousarray(ordering, np.int64)
        self._factor = ctypes.c_void_p(lib.cholmod_l_analyze_p(
            ctypes.byref(self._matrix),
            None if permutation is None else permutation.ctypes.data, None, 0, self._common))
        if not self._factor.value:
            raise RuntimeError("CHOLMOD's analysis failed (an invalid ordering, or out of memory)")
        self.refactorize(self._values)

    def refactorize(self, values: FloatArray) -> None:
        """Factorize the matrix of the same pattern with these values (of the lower
        triangle, in CSC order)."""
        with self._lock:
            self._values[:] = values
            self._lib.cholmod_l_factorize(ctypes.byref(self._matrix), self._factor,
                                          self._common)
            head = _FactorHead.from_address(self._factor.value)
            if head.minor < head.n:
                raise RuntimeError(f"CHOLMOD: the matrix is not positive definite "
                                   f"(column {head.minor})")

    def column_counts(self) -> IntArray:
        """The nonzeros of each column of ``L`` (diagonal included), from the analysis."""
        head = _FactorHead.from_address(self._factor.value)
        values = ctypes.cast(head.col_count, ctypes.POINTER(ctypes.c_int64))
        return np.ctypeslib.as_array(values, (self.n,)).copy()

    def __call__(self, b: FloatArray) -> FloatArray:
        rhs = np.array(b, dtype=np.float64, order="F").reshape(self.n, -1, order="F")
        dense = _Dense(self.n, rhs.shape[1], rhs.size, self.n, rhs.ctypes.data, None,
                       _REAL, _DOUBLE)
        with self._lock:
            solution = self._lib.cholmod_l_solve(_SYSTEM_A, self._factor, ctypes.byref(dense),
                                                 self._common)
            if not solution:
                raise MemoryError("CHOLMOD's solve failed (out of memory)")
            try:
                values = ctypes.cast(solution.contents.x, ctypes.POINTER(ctypes.c_double))
                x = np.ctypeslib.as_array(values, (rhs.size,)).copy()
            finally:
                self._lib.cholmod_l_free_dense(ctypes.byref(solution), self._common)
        return x.reshape(rhs.shape, order="F").reshape(np.shape(b))

    def __del__(self) -> None:
        try:
            if getattr(self, "_factor", None) is not None and self._factor.value:
                self._lib.cholmod_l_free_factor(ctypes.byref(self._factor), self._common)
            if getattr(self, "_common", None) is not None:
                self._lib.cholmod_l_finish(self._common)
        except Exception:  # noqa: BLE001  (interpreter shutdown: nothing left to free)
            pass


class CholeskyFactor:
    """CHOLMOD's supernodal Cholesky factorization ``PAPᵀ = LLᵀ`` (double precision) of an
    SPD matrix; calling it solves (``(n,)`` or ``(n, k)`` right-hand sides).

    Supernodal: dense BLAS-3 kernels on the factor's column blocks, where SuperLU's
    symmetric mode computes an LU with twice the flops (``benchmarks/bench_solvers.py``).

    :meth:`refactorize` factorizes another matrix of the same pattern on the kept
    analysis (symbolic factorization and the matrix's conversion), a large part of a
    factorization's time.

    The calls go to the library through ``ctypes``, the GIL released
    (``releases_gil``), where :func:`library` loads it, else through ``cvxopt.cholmod``:
    the same factors, and the same solutions to the last bit for one right-hand side
    (tested).

    Parameters
    ----------
    A : (n, n) sparse SPD matrix (only its lower triangle is read)
    ordering : (n,) int array, optional
        A fill-reducing permutation (new → old, :func:`nested_dissection`); default
        CHOLMOD's own (approximate minimum degree).

    Raises
    ------
    RuntimeError
        Where ``A`` is not positive definite (numerically).
    """

    def __init__(self, A: sp.spmatrix, ordering: IntArray | None = None) -> None:
        self.n = A.shape[0]
        self.ordering = ordering
        self._factor = None
        self._failed = False
        #: counts the factorizations: a holder of an earlier one sees it replaced
        self.generation = 0
        #: whether factorizing and solving release the GIL (:mod:`._cholmod`): then
        #: several factors are worth factorizing and solving in threads
        self.releases_gil = library() is not None
        self.refactorize(A)

    def refactorize(self, A: sp.spmatrix) -> None:
        """Factorize ``A`` (same size), on the kept analysis where its pattern is the
        same. Raises RuntimeError where ``A`` is not positive definite."""
        if A.shape != (self.n, self.n):
            raise ValueError(f"expected a {self.n}×{self.n} matrix, got {A.shape}")
        self.generation += 1
        if self.n == 0:  # nothing to factorize (CHOLMOD refuses an empty matrix)
            return
        lower = sp.tril(A, format="csc")
        lower.sort_indices()
        same = (self._factor is not None and np.array_equal(lower.indptr, self._indptr)
                and np.array_equal(lower.indices, self._indices))
        if not same:  # int64: the native factor reads them in place (no second copy)
            self._indptr = lower.indptr.astype(np.int64)
            self._indices = lower.indices.astype(np.int64)
        if self.releases_gil:
            self._failed = True  # until the numeric factorization succeeds
            if not same:
                self._factor = None
                self._factor = _NativeFactor(self._indptr, self._indices, lower.data,
                                             self.ordering)
            else:  # a failure keeps the analysis: the next values reuse it
                self._factor.refactorize(lower.data)
            self._failed = False
            return
        self._cvxopt_factorize(lower, same)

    def column_counts(self) -> IntArray | None:
        """The nonzeros of each column of ``L`` (diagonal included, ``(n,)``) where the
        factor is CHOLMOD's through ``ctypes``; else None (``cvxopt`` does not expose them)."""
        if not self.releases_gil or self._factor is None:
            return None
        return self._factor.column_counts()

    def _cvxopt_factorize(self, lower: sp.csc_matrix, same: bool) -> None:
        import cvxopt
        import cvxopt.cholmod as cholmod

        if same:
            self._matrix.V = cvxopt.matrix(lower.data.astype(float))
        else:
            columns = np.repeat(np.arange(self.n, dtype=np.intp), np.diff(lower.indptr))
            # cvxopt's indices are Py_ssize_t (np.intp)
            self._matrix = cvxopt.spmatrix(lower.data.astype(float),
                                           lower.indices.astype(np.intp), columns,
                                           (self.n, self.n))
        try:
            if not same:
                if self.ordering is None:
                    self._factor = cholmod.symbolic(self._matrix, uplo="L")
                else:
                    p = cvxopt.matrix(np.asarray(self.ordering, dtype=np.intp))
                    self._factor = cholmod.symbolic(self._matrix, p=p, uplo="L")
            cholmod.numeric(self._matrix, self._factor)
        except ArithmeticError as exc:  # CHOLMOD: a non-positive pivot
            self._factor = None  # analysed again next time
            raise RuntimeError(f"CHOLMOD: the matrix is not positive definite ({exc})") from exc

    def __call__(self, b: FloatArray) -> FloatArray:
        if self.n == 0:
            return np.array(b, dtype=float)
        if self._factor is None or self._failed:
            raise RuntimeError("the last factorization failed")
        if self.releases_gil:
            return self._factor(b)
        import cvxopt
        import cvxopt.cholmod as cholmod

        x = cvxopt.matrix(np.ascontiguousarray(b, dtype=float).reshape(self.n, -1))
        cholmod.solve(self._factor, x)
        return np.array(x).reshape(np.shape(b))
