"""Riemannian metrics on the manifold of planar meshes ``M+`` (SPEC §4, thesis §5–6).

Every metric has the same small interface, in the ``vec`` chart (points and tangent vectors
are ``(N, d)`` arrays, ``vec V = V.ravel()``; ``d = 2`` for planar meshes, 3 for surfaces
and tetrahedra):

- ``inner(Q, U, V) -> float``: the metric ``g_Q(U, V)``;
- ``norm(Q, V) -> float``: ``sqrt(g_Q(V, V))``;
- ``riesz(Q, P) -> (N, d)``: the Riesz map turning a derivative ``P = dF(Q)`` (an
  ``(N, d)`` array of partial derivatives) into the gradient ``grad F = g_Q⁻¹ P``, so that
  ``inner(Q, riesz(Q, P), V) == P · V`` for every ``V``. With ``free`` (an (N,) bool
  mask) it is the Riesz map of the metric restricted to the tangent vectors that vanish
  on the fixed vertices: the result vanishes there and the identity holds for such ``V``;
- ``exp(Q, V, time=1.0) -> (N, d)``: the exponential map (or the retraction the thesis pairs
  with the metric); optional, missing ones raise :class:`MetricNotImplementedError`
  naming the class and the method.

Optional capabilities, declared by the metric and used by the layer's algorithms:

- a ``penalty`` (the complete metric of ``f``) or ``is_flat``: the exponential map of
  :mod:`.geodesics` and the Newton–CG discrete geodesic of :mod:`.newton_cg`;
- ``path_model(frames, free, boundary_edges, anchor)``: the discrete path energy as a
  least-squares problem (:class:`.levenberg_marquardt.PathModelMetric`), minimized by
  Levenberg–Marquardt (:mod:`.levenberg_marquardt`).

Metrics: :class:`EuclideanMetric` (5.2, any ``d``), :class:`ElasticityMetric` (6.24) and
:class:`CompleteMetric` ``g = I + ∇f∇fᵀ`` (5.17, 5.34) here (both planar, ``d = 2``); the
distortion metrics ``M + w² JᵀJ`` live with the motions built on them and implement the
same protocol through :class:`.assembled.AssembledMetric`: planar
(``motion.planar.metric.GraphMetric``, with ``path_model``), tetrahedra
(``motion.tets.metric.TetGraphMetric``) and surfaces (``motion.surface.metric``). Each
cell kind's default is ``cells.registry.metric_for(mesh)`` (``mt.metric_for``).
"""

from __future__ import annotations

import logging
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp

from .._linalg import dot
from .._options import require_shape
from .._typing import FloatArray
from ..fem.elasticity import (BlockPattern, SPDSolve, assemble, factorize, kept_ordering,
                             lame_parameters, solver_method)
from ..solvers import SOLVERS, pcg
from .kept_factor import FactorOf, KeptFactorCosts, owned_factor
from ..errors import InvalidMeshError, MeshoptError

__all__ = [
    "Metric",
    "MetricNotImplementedError",
    "EuclideanMetric",
    "ElasticityMetric",
    "CompleteMetric",
]

logger = logging.getLogger(__name__)


class MetricNotImplementedError(MeshoptError, NotImplementedError):
    """An optional metric method (e.g. ``exp``) is not available for this metric."""


@runtime_checkable
class Metric(Protocol):
    """The interface shared by all metrics on ``(N, d)`` points (see the module docstring);
    ``isinstance(m, Metric)`` checks that ``m`` has every member.

    ``is_flat`` declares the Euclidean metric (straight lines are its geodesics), so code
    that needs geodesics asks the metric instead of comparing class names. ``exp`` is
    optional: where a metric has none it raises :class:`MetricNotImplementedError` naming
    its class and the method. The optional capabilities (``penalty``, ``path_model``) are
    in the module docstring.
    """

    is_flat: bool

    def inner(self, Q: FloatArray, U: FloatArray, V: FloatArray) -> float: ...

    def norm(self, Q: FloatArray, V: FloatArray) -> float: ...

    def riesz(self, Q: FloatArray, P: FloatArray, free: np.ndarray | None = None) -> FloatArray: ...

    def exp(self, Q: FloatArray, V: FloatArray, time: float = 1.0) -> FloatArray: ...


def _vdot(U: FloatArray, V: FloatArray) -> float:
    """``vec U · vec V`` of two tangent vectors of equal shape (:func:`_linalg.dot`)."""
    U = np.asarray(U, dtype=np.float64)
    V = np.asarray(V, dtype=np.float64)
    if U.shape != V.shape:
        raise ValueError(f"tangent vectors have shapes {U.shape} and {V.shape}")
    return dot(U, V)


class _LastQCache:
    """Remember one value computed at the last ``Q`` (and optional mask), keyed on bytes.

    The key is a private copy of ``Q``; a lookup compares the raw 64-bit words of ``Q``
    with it (exact: ``-0.0`` differs from ``0.0`` and a NaN matches itself), one read
    pass over two arrays and no allocation of ``Q``'s size.
    """

    __slots__ = ("_q", "_mask", "_value")

    def __init__(self) -> None:
        self._q: np.ndarray | None = None
        self._mask: np.ndarray | None = None
        self._value = None

    def get(self, Q: np.ndarray, mask: np.ndarray | None = None):
        """The cached value if ``Q`` (C-contiguous float64) and ``mask`` match the key."""
        q = self._q
        if q is None or q.shape != Q.shape:
            return None
        if (mask is None) != (self._mask is None):
            return None
        if mask is not None and not np.array_equal(mask, self._mask):
            return None
        if not np.array_equal(Q.view(np.uint64), q.view(np.uint64)):
            return None
        return self._value

    def put(self, Q: np.ndarray, value, mask: np.ndarray | None = None) -> None:
        self._q = np.array(Q, dtype=np.float64, order="C")
        self._mask = None if mask is None else mask.copy()
        self._value = value

    def clear(self) -> None:
        self._q = self._mask = self._value = None


def _derivative(P, shape: tuple) -> FloatArray:
    """``P`` as a float array of ``shape`` (ValueError for another)."""
    return require_shape("derivative", np.asarray(P, dtype=np.float64), shape)


def _free_mask(free, n: int) -> np.ndarray | None:
    """Validate an optional per-vertex ``free`` mask (N,) bool; None if all are free."""
    if free is None:
        return None
    free = require_shape("free mask", np.ascontiguousarray(free, dtype=bool), (n,))
    return None if free.all() else free


def _as_points(Q) -> FloatArray:
    Q = np.ascontiguousarray(Q, dtype=np.float64)
    if Q.ndim != 2 or Q.shape[1] != 2:
        raise InvalidMeshError(f"node positions must have shape (N, 2), got {Q.shape}")
    return Q


class EuclideanMetric:
    """The Euclidean metric ``(U, V) = vec U · vec V`` (5.2); ``exp_Q(tV) = Q + tV``.

    It does not depend on ``Q``; the Riesz map is the identity (a copy of ``P``).
    """

    is_flat = True

    def inner(self, Q: FloatArray, U: FloatArray, V: FloatArray) -> float:
        """``vec U · vec V``. ``Q, U, V`` : (N, 2)."""
        return _vdot(U, V)

    def norm(self, Q: FloatArray, V: FloatArray) -> float:
        """``‖vec V‖₂``. ``V`` : (N, 2)."""
        return float(np.linalg.norm(np.ravel(V)))

    def riesz(self, Q: FloatArray, P: FloatArray, free: np.ndarray | None = None) -> FloatArray:
        """The gradient of a derivative ``P`` (N, 2) is ``P`` itself (returned as a copy).

        With an (N,) bool mask ``free``, the rows of fixed vertices are zeroed.
        """
        P = np.array(P, dtype=np.float64)
        mask = _free_mask(free, P.shape[0])
        if mask is not None:
            P[~mask] = 0.0
        return P

    def exp(self, Q: FloatArray, V: FloatArray, time: float = 1.0) -> FloatArray:
        """Straight line ``Q + time V`` (N, 2) (the Euclidean retraction of §6.4)."""
        return np.asarray(Q, dtype=np.float64) + time * np.asarray(V, dtype=np.float64)

    def __repr__(self) -> str:
        return "EuclideanMetric()"


def _block_submatrix(A: sp.bsr_matrix, keep: np.ndarray) -> sp.bsr_matrix:
    """Principal submatrix of a 2×2-block matrix on the vertices ``keep`` (N,) bool."""
    dof = np.repeat(keep, 2)
    sub = A.tocsr()[dof][:, dof]
    return sp.bsr_matrix(sub, blocksize=(2, 2))


def _refactorizes(kept: SPDSolve, A) -> bool:
    """Whether ``kept``'s factor can factorize ``A`` on its own analysis: a CHOLMOD
    factor (:class:`FactorOf`) of a matrix of ``A``'s shape (one pattern per free mask)."""
    return isinstance(kept.solve, FactorOf) and kept.matrix.shape == A.shape


class ElasticityMetric:
    """Linear elasticity metric ``(U, V) = vec U · (K + δM) vec V`` (thesis (6.24)).

    ``K`` is the P1 vector stiffness of ``2μ ε(u):ε(v) + λ tr ε(u) tr ε(v)`` and ``M`` the
    consistent P1 vector mass matrix, both assembled on the *current* positions ``Q`` with
    the connectivity of ``mesh``. The matrix is SPD on ``M+`` (the mass term removes the
    rigid-motion kernel of ``K``).

    The matrix and its factorization (SuperLU or a pyamg hierarchy) are built once per
    ``Q`` and reused: the cache is keyed on the bytes of ``Q``; ``n_factorizations`` and
    ``n_assemblies`` count the work done.

    Parameters
    ----------
    mesh : TriangleMesh / PlanarMesh (its triangles are used; positions come with each call)
    E : Young's modulus (> 0)
    nu : Poisson ratio in (-1, 0.5)
    delta : mass weight ``δ``; the thesis uses ``δ = 0.2 E``
    solver : "auto" (direct below ``elasticity.CHOLMOD_AMG_MIN_DOFS`` dofs with CHOLMOD,
        ``elasticity.AUTO_AMG_MIN_DOFS`` without, AMG-PCG above),
        "direct" or "amg"
    rtol : relative residual of the AMG-preconditioned CG solve

    Notes
    -----
    There is no exponential map: the thesis pairs this metric with the Euclidean
    retraction (``EuclideanMetric().exp``); :meth:`exp` raises.
    """

    is_flat = False

    def __init__(
        self,
        mesh,
        E: float = 1.0,
        nu: float = 0.4,
        delta: float = 0.2,
        solver: str = "auto",
        rtol: float = 1e-10,
    ) -> None:
        self.lam, self.mu = lame_parameters(E, nu)
        if not delta > 0:
            raise ValueError(f"mass weight delta must be > 0 (K + δM is singular), got {delta}")
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
        self.E, self.nu, self.delta = float(E), float(nu), float(delta)
        self.solver, self.rtol = solver, float(rtol)
        self.triangles = np.ascontiguousarray(mesh.triangles, dtype=np.int64)
        self.n_vertices = int(np.asarray(mesh.points).shape[0])
        self.pattern = BlockPattern.from_triangles(self.triangles, self.n_vertices)
        self.n_assemblies = 0
        self.n_factorizations = 0
        self._matrix_cache = _LastQCache()
        self._solver_cache = _LastQCache()
        self._kept: dict = {}  # the last factorization, by free mask
        self._costs: KeptFactorCosts | None = None  # its operation counts, where known
        self._orderings: dict = {}  # the direct solver's ordering, by free mask
        self._element_blocks: FloatArray | None = None  # assembly buffer (T, 3, 3, 2, 2)

    # -- assembly and factorization -------------------------------------------------------

    def _points(self, Q) -> FloatArray:
        Q = _as_points(Q)
        if Q.shape[0] != self.n_vertices:
            raise InvalidMeshError(
                f"node positions have {Q.shape[0]} rows, the mesh has {self.n_vertices} vertices"
            )
        return Q

    def _bsr(self, Q: FloatArray) -> sp.bsr_matrix:
        A = self._matrix_cache.get(Q)
        if A is None:
            if self._element_blocks is None:  # kept: refilled at every new Q
                self._element_blocks = np.empty((len(self.triangles), 3, 3, 2, 2))
            A = assemble(Q, self.triangles, self.E, self.nu, self.delta, pattern=self.pattern,
                         out=self._element_blocks)
            self.n_assemblies += 1
            self._matrix_cache.put(Q, A)
        return A

    def matrix(self, Q: FloatArray) -> sp.csr_matrix:
        """The SPD matrix ``K + δM`` at ``Q`` (N, 2), as a (2N, 2N) CSR matrix.

        Dof ``2 i + c`` is component ``c`` of vertex ``i`` (``vec(Q) = Q.ravel()``).
        """
        return self._bsr(self._points(Q)).tocsr()

    #: CG iterations with a kept factorization after which the matrix is refactorized
    REFACTOR_AFTER_CG = 25

    def _solver(self, Q: FloatArray, free: np.ndarray | None) -> SPDSolve:
        """The solve at ``Q``: exact with a factorization made at ``Q``; else conjugate
        gradients to ``rtol`` preconditioned by the factorization kept from an earlier
        ``Q`` (an optimizer's consecutive iterates are close, so a few iterations do).
        A new ``Q`` is factorized where :func:`.kept_factor.refactorize_pays` finds it cheaper than
        keeping, on the operation counts of :class:`KeptFactorCosts` (known for CHOLMOD's
        factors); any ``Q`` is refactorized when CG does not converge within
        ``REFACTOR_AFTER_CG`` iterations. The decisions are by counts, so results do not
        depend on timing; ``SPDSolve.method`` is "kept" for a CG solve."""
        s = self._solver_cache.get(Q, free)
        if s is not None:
            return s
        A = self._bsr(Q)
        points = Q
        if free is not None:  # principal block submatrix of the free vertices
            A = _block_submatrix(A, free)
            points = Q[free]
        key = None if free is None else free.tobytes()
        kept = self._kept.get(key)

        def refactorize() -> SPDSolve:
            method = solver_method(self.solver, A.shape[0])
            if kept is not None and _refactorizes(kept, A):
                # the same pattern: the kept factor's analysis serves (numeric part only);
                # solves handed out earlier stay those of their own matrix (FactorOf)
                factor = kept.solve.factor
                factor.refactorize(A)
                fresh = SPDSolve("direct", FactorOf(factor, A), A, factor)
            else:
                fresh = owned_factor(factorize(A, points, method, rtol=self.rtol,
                                         ordering=kept_ordering(self._orderings, key, A,
                                                                points, method)))
            self.n_factorizations += 1
            logger.debug("elasticity metric: %s factorization #%d", fresh.method,
                         self.n_factorizations)
            self._kept = {key: fresh}
            self._costs = KeptFactorCosts.of(fresh, A.nnz, self._costs)
            self._solver_cache.put(Q, fresh, free)
            return fresh

        if kept is None or kept.matrix.shape != A.shape:
            return refactorize()
        costs = self._costs
        if costs is not None and costs.start_iterate():
            return refactorize()
        csr = A.tocsr()

        def solve(b: FloatArray) -> FloatArray:
            current = self._solver_cache.get(Q, free)
            if current is not None and current.method != "kept":
                return current.solve(b)  # refactorized at this Q meanwhile
            try:
                x, iterations, residual = pcg(csr, b, kept.precondition or kept.solve,
                                              self.rtol, max_iterations=self.REFACTOR_AFTER_CG)
            except FloatingPointError:  # the kept factor is too far off to precondition
                residual = np.inf
            if not residual <= self.rtol:
                return refactorize().solve(b)
            if costs is not None:
                costs.add_cg(iterations)
            return x

        s = SPDSolve("kept", solve, A)
        self._solver_cache.put(Q, s, free)
        return s

    # -- metric interface -------------------------------------------------------------------

    def inner(self, Q: FloatArray, U: FloatArray, V: FloatArray) -> float:
        """``vec U · (K + δM)(Q) vec V``. ``Q, U, V`` : (N, 2)."""
        A = self._bsr(self._points(Q))
        return _vdot(np.ravel(U), A @ np.ravel(np.asarray(V, dtype=np.float64)))

    def norm(self, Q: FloatArray, V: FloatArray) -> float:
        """``sqrt(inner(Q, V, V))``."""
        return float(np.sqrt(max(self.inner(Q, V, V), 0.0)))

    def riesz(self, Q: FloatArray, P: FloatArray, free: np.ndarray | None = None) -> FloatArray:
        """Gradient ``(K + δM)⁻¹ vec P`` of a derivative ``P`` (N, 2); returns (N, 2).

        The factorization at ``Q`` is computed on first use and reused for later calls
        (one factorization per distinct ``(Q, free)``). With an (N,) bool mask ``free`` the
        system is restricted to the free vertices' dofs; fixed rows of the result are 0.
        """
        Q = self._points(Q)
        P = _derivative(P, Q.shape)
        mask = _free_mask(free, Q.shape[0])
        solver = self._solver(Q, mask)
        if mask is None:
            return solver.solve(P.ravel()).reshape(Q.shape)
        out = np.zeros_like(Q)
        out[mask] = solver.solve(P[mask].ravel()).reshape(-1, 2)
        return out

    def exp(self, Q: FloatArray, V: FloatArray, time: float = 1.0) -> FloatArray:
        """Not available: use the Euclidean retraction with this metric (thesis §6.4)."""
        raise MetricNotImplementedError(
            "ElasticityMetric.exp is not implemented: the thesis pairs the elasticity metric "
            "with the Euclidean retraction, use EuclideanMetric().exp(Q, V, time)"
        )

    def __repr__(self) -> str:
        return (
            f"ElasticityMetric(E={self.E}, nu={self.nu}, delta={self.delta}, "
            f"solver={self.solver!r}, n_vertices={self.n_vertices})"
        )


class CompleteMetric:
    """Complete metric ``g = I + ∇f ∇fᵀ`` of a proper penalty ``f`` (5.17, 5.34).

    ``inner(Q, U, V) = U·V + (∇f·U)(∇f·V)``; the Riesz map has the closed form
    (Sherman–Morrison) ``grad = P − ∇f (∇f·P) / (1 + |∇f|²)``: O(N), no linear solve.
    The gradient ``∇f(Q)`` and ``|∇f(Q)|²`` are cached for the last ``Q`` (keyed on its
    bytes), so ``inner``/``norm``/``riesz`` at the same ``Q`` call ``penalty.gradient``
    once; ``n_gradient_evaluations`` counts the calls.

    Parameters
    ----------
    penalty : object with ``gradient(Q) -> (N, 2)`` (and ``value``, ``hvp`` for
        geodesics), e.g. ``QualityPenalty`` (f2) or ``HeightPenalty`` (f1)
    """

    is_flat = False

    def __init__(self, penalty) -> None:
        self.penalty = penalty
        self.n_gradient_evaluations = 0
        self._cache = _LastQCache()

    def gradient_of_penalty(self, Q: FloatArray) -> tuple[FloatArray, float]:
        """``(∇f(Q), |∇f(Q)|²)`` with ``∇f`` of shape (N, 2), cached for the last ``Q``."""
        Q = _as_points(Q)
        hit = self._cache.get(Q)
        if hit is None:
            g = require_shape("penalty gradient", np.ascontiguousarray(
                self.penalty.gradient(Q), dtype=np.float64), Q.shape)
            self.n_gradient_evaluations += 1
            hit = (g, _vdot(g, g))
            self._cache.put(Q, hit)
        return hit

    def inner(self, Q: FloatArray, U: FloatArray, V: FloatArray) -> float:
        """``U·V + (∇f·U)(∇f·V)``. ``Q, U, V`` : (N, 2)."""
        g, _ = self.gradient_of_penalty(Q)
        return _vdot(U, V) + _vdot(g, U) * _vdot(g, V)

    def norm(self, Q: FloatArray, V: FloatArray) -> float:
        """``sqrt(|V|² + (∇f·V)²)``."""
        g, _ = self.gradient_of_penalty(Q)
        return float(np.sqrt(_vdot(V, V) + _vdot(g, V) ** 2))

    def riesz(self, Q: FloatArray, P: FloatArray, free: np.ndarray | None = None) -> FloatArray:
        """Gradient ``P − ∇f (∇f·P) / (1 + |∇f|²)`` of a derivative ``P`` (N, 2) (5.34).

        With an (N,) bool mask ``free``, ``∇f`` and ``P`` are restricted to the free
        vertices first (the metric restricted to fields vanishing on fixed vertices).
        """
        g, gg = self.gradient_of_penalty(Q)
        P = _derivative(P, g.shape)
        mask = _free_mask(free, g.shape[0])
        if mask is not None:
            g = np.where(mask[:, None], g, 0.0)
            P = np.where(mask[:, None], P, 0.0)
            gg = _vdot(g, g)
        out = g * (-_vdot(g, P) / (1.0 + gg))
        out += P
        return out

    def exp(self, Q: FloatArray, V: FloatArray, time: float = 1.0, **options) -> FloatArray:
        """Exponential map ``γ(time)`` of this metric, ``γ(0) = Q``, ``γ'(0) = V`` (5.35).

        Delegates to :func:`meshopt_toolkit.riemannian.geodesics.exp_map` (imported on first use);
        ``options`` (integrator, tolerances, ...) are passed through.
        """
        from .geodesics import exp_map

        return exp_map(self, Q, V, time, **options)

    def __repr__(self) -> str:
        return f"CompleteMetric({self.penalty!r})"
