"""Initial inverse Hessians ``H_0`` of the L-BFGS two-loop recursion.

The two-loop recursion of :class:`~.directions.LBFGSMemory` runs on covectors (the
derivatives ``P``, pairs ``(s, ŷ = ΔP)``) and applies ``H_0 = γ B⁻¹`` to the innermost
covector, ``γ = s·ŷ / ŷ·B⁻¹ŷ`` from the latest pair. The default ``B = G_Q`` (the metric)
makes it the Riemannian two-loop in the metric's inner product with ``H_0 = γ id``. Any
other SPD ``B`` keeps every ``H_k`` SPD (the pairs satisfy ``s·ŷ > 0``), so ``−H_k P`` is
a descent direction; the metric still defines the gradient norm (the stopping test), the
first step length and the line search's retraction. A ``B`` close to the Hessian of
``F = j + f2`` is a better ``H_0``: near the optimum the complete metric ``I + ∇f∇fᵀ`` is
almost Euclidean, and ``∇²F`` has condition number 888 there in both (disc_146), against
86 relative to ``B`` = the penalty's Hessian below.

* :class:`PenaltyHessian` (``"penalty"``): ``B = Σ_k Π₊ ∇²(β1 term)_k + (β4/N + a) I``,
  the Hessian of the objective's penalty f2 (``β^penalty``, not the metric's ``β^metric``)
  with each triangle's 6×6 block projected onto the PSD cone, the anchor term's ``β4/N``
  and a floor ``a = FLOOR · mean diag``; sparse, factorized every
  :data:`REFACTOR_EVERY` iterations (the total-area and boundary terms are left out: a
  dense rank-one block and a non-local pair term).
* :class:`ElasticityInverse` (``"elasticity"``): ``B = K + δM`` at the iterate (the
  elasticity metric's Riesz map, its factorization kept between iterates).
"""

from __future__ import annotations

import numpy as np

from .._options import check_choice
from .._typing import FloatArray
from ..errors import OptimizationError, OptionError

#: values of ``optimize(lbfgs_preconditioner=...)``; "auto": "penalty" for the complete-*
#: variants when the objective's penalty has β1 > 0, else "none" (``B = G_Q``)
PRECONDITIONERS = ("auto", "none", "penalty", "elasticity")
DEFAULT_PRECONDITIONER = "auto"

#: :class:`PenaltyHessian` is refactorized at every REFACTOR_EVERY-th iterate
REFACTOR_EVERY = 5
#: :class:`PenaltyHessian`'s floor ``a`` as a fraction of the mean diagonal
FLOOR = 0.1

_SQRT3 = np.sqrt(3.0)
_HS = 2.0 * np.kron(np.array([[2.0, -1, -1], [-1, 2, -1], [-1, -1, 2]]), np.eye(2))
_HA = np.zeros((6, 6))
for _a, _b, _v in ((0, 3, 0.5), (0, 5, -0.5), (2, 5, 0.5), (2, 1, -0.5), (4, 1, 0.5), (4, 3, -0.5)):
    _HA[_a, _b] = _HA[_b, _a] = _v


def quality_hessian_blocks(Q: FloatArray, triangles: np.ndarray, coef: float) -> FloatArray:
    """Per-triangle Hessians ``(T, 6, 6)`` of ``coef · S/A`` (``S = Σ|e_l|²``, ``A`` the
    signed area; local dofs ``x0, y0, x1, y1, x2, y2``): ``S = ½xᵀH_S x`` and
    ``A = ½xᵀH_A x`` are quadratic, so
    ``∇²(S/A) = H_S/A − (∇S∇Aᵀ + ∇A∇Sᵀ)/A² + 2S ∇A∇Aᵀ/A³ − S H_A/A²``."""
    x = np.asarray(Q, dtype=float)[triangles].reshape(-1, 6)
    gS, gA = x @ _HS, x @ _HA
    S = 0.5 * np.einsum("ti,ti->t", gS, x)
    iA = 1.0 / (0.5 * np.einsum("ti,ti->t", gA, x))
    cross = np.einsum("ti,tj->tij", gS, gA)
    H = (_HS * iA[:, None, None]
         - (cross + cross.transpose(0, 2, 1)) * (iA * iA)[:, None, None]
         + np.einsum("ti,tj->tij", gA, gA) * (2.0 * S * iA ** 3)[:, None, None]
         - _HA * (S * iA * iA)[:, None, None])
    return coef * H


class PenaltyHessian:
    """``P ↦ B⁻¹P`` with ``B`` the PSD-projected Hessian of f2's triangle term plus
    ``(β4/N + a) I`` (module docstring); ``n_factorizations`` counts the work."""

    def __init__(self, mesh, penalty, free: np.ndarray | None = None,
                 every: int = REFACTOR_EVERY, floor: float = FLOOR) -> None:
        b1, _, _, b4 = penalty.beta
        self.triangles = np.asarray(mesh.triangles)
        self.n_vertices = int(mesh.n_vertices)
        self.coef = b1 / (4.0 * _SQRT3 * len(self.triangles))
        self.anchor = b4 / self.n_vertices
        self.free = free
        self.every, self.floor = int(every), float(floor)
        dofs = (2 * self.triangles[:, :, None] + np.arange(2)).reshape(-1, 6)
        self._rows = np.repeat(dofs, 6, axis=1).ravel()
        self._cols = np.tile(dofs, (1, 6)).ravel()
        self._dof = np.ones(2 * self.n_vertices, bool) if free is None else np.repeat(free, 2)
        self._solve = None
        self._orderings: dict = {}  # the direct factorization's ordering, computed once
        self._last: FloatArray | None = None
        self._iterates = 0
        self.n_factorizations = 0

    def matrix(self, Q: FloatArray):
        """``B`` at ``Q`` on the free dofs (SPD, CSR)."""
        import scipy.sparse as sp  # not at import: the filter registry reads PRECONDITIONERS

        H = quality_hessian_blocks(Q, self.triangles, self.coef)
        w, V = np.linalg.eigh(H)
        H = np.einsum("tij,tj,tkj->tik", V, np.maximum(w, 0.0), V)
        n = 2 * self.n_vertices
        B = sp.coo_matrix((H.ravel(), (self._rows, self._cols)), shape=(n, n)).tocsr()
        shift = self.anchor + self.floor * float(B.diagonal().mean())
        if not shift > 0:
            raise OptimizationError("the penalty preconditioner needs β1 > 0 or β4 > 0")
        B = B + shift * sp.identity(n, format="csr")
        return B[self._dof][:, self._dof] if self.free is not None else B

    def __call__(self, Q: FloatArray, P: FloatArray) -> FloatArray:
        if self._last is None or not np.array_equal(self._last, Q):
            if self._iterates % self.every == 0:
                import scipy.sparse as sp

                from ..fem.elasticity import factorize, kept_ordering, solver_method

                pts = Q if self.free is None else Q[self.free]
                B = sp.bsr_matrix(self.matrix(Q), blocksize=(2, 2))
                method = solver_method("auto", B.shape[0])
                ordering = kept_ordering(self._orderings, None, B, pts, method)
                self._solve = factorize(B, pts, method, ordering=ordering).solve
                self.n_factorizations += 1
            self._last = np.array(Q, dtype=float)
            self._iterates += 1
        out = np.zeros(P.size)
        out[self._dof] = self._solve(np.ravel(P)[self._dof])
        return out.reshape(P.shape)


class ElasticityInverse:
    """``P ↦ (K + δM)(Q)⁻¹ P``: the elasticity metric's Riesz map at the iterate."""

    def __init__(self, mesh, free: np.ndarray | None = None) -> None:
        from ..riemannian.metrics import ElasticityMetric

        self.metric = ElasticityMetric(mesh)
        self.free = free

    def __call__(self, Q: FloatArray, P: FloatArray) -> FloatArray:
        return self.metric.riesz(Q, P, free=self.free)


def make_preconditioner(kind: str, *, metric_kind: str, method: str, mesh, penalty, free):
    """The ``H_0`` operator ``(Q, P) ↦ B⁻¹P`` asked for, or None (``B = G_Q``)."""
    check_choice(kind, PRECONDITIONERS, "lbfgs_preconditioner", error=OptionError)
    has_penalty = penalty is not None and penalty.beta[0] > 0
    if kind == "auto":
        kind = "penalty" if method == "lbfgs" and metric_kind == "complete" and has_penalty \
            else "none"
    if kind == "none":
        return None
    if method != "lbfgs":
        raise OptionError(f"lbfgs_preconditioner={kind!r} applies to method='lbfgs' only")
    if kind == "penalty":
        if not has_penalty:
            raise OptionError("lbfgs_preconditioner='penalty' needs a penalty with β1 > 0")
        return PenaltyHessian(mesh, penalty, free)
    return ElasticityInverse(mesh, free)
