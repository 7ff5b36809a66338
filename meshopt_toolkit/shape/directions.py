"""Search directions of the descent methods: steepest descent, Riemannian L-BFGS and
nonlinear conjugate gradients, one direction rule each (:data:`DIRECTION_RULES`) for the
one iteration of :mod:`.driver`.

Notation: ``P = dF(Q)`` is the derivative (a covector, an (N, 2) array), ``G_Q`` the
metric at ``Q`` and ``grad F = G_Q⁻¹ P`` its Riesz map (:meth:`ShapeProblem.riesz`).

Vector transport
----------------
``M+`` is an open subset of ``R^{2N}``: every tangent space is ``R^{2N}`` itself, so the
identity of the vec chart is a vector transport (linear, ``T_0 = id``, smooth) for every
retraction. We use it for steps and directions (``s_k = Q_{k+1} − Q_k``, ``d_k``) and for
derivatives (``ŷ_k = P_{k+1} − P_k``), and turn covectors into vectors with the Riesz map
of the *current* metric. Then the Riemannian two-loop recursion in the inner product
``g_{Q_k}`` with ``H_0 = γ_k id`` is exactly the Euclidean two-loop on covectors with
``H_0 = γ_k G_{Q_k}⁻¹``: ``g(s, G⁻¹ŷ) = s·ŷ`` needs no solve, the only solves are the Riesz
maps of ``q`` and of ``ŷ`` (for ``γ_k = s·ŷ / ŷ·G⁻¹ŷ``). With the straight-line
retraction this transport is also the differentiated retraction, and the Wolfe curvature
condition gives ``s·ŷ = t (φ'(t) − φ'(0)) ≥ (1 − c2) t |φ'(0)| > 0``: every pair is a
valid curvature pair and ``H_k`` stays positive definite. With the exponential map the
identity is not the differentiated retraction; pairs with ``s·ŷ ≤ ε |s·P_k|`` are
rejected (skipped, counted) so that ``H_k`` stays positive definite (cautious update).
``direction(..., h0=B⁻¹)`` replaces ``G_{Q_k}⁻¹`` in ``H_0`` by another SPD operator
(:mod:`.preconditioners`), a preconditioned L-BFGS with the metric kept everywhere else.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

import numpy as np

from .._linalg import dot
from .._typing import FloatArray

Riesz = Callable[[FloatArray], FloatArray]


class LBFGSMemory:
    """The last ``size`` curvature pairs ``(s, ŷ)`` and the two-loop recursion.

    Parameters
    ----------
    size : number of pairs kept (the L-BFGS memory ``m``)
    eps : a pair is rejected unless ``s·ŷ > eps · |s·P_k|`` (``P_k`` the derivative at
        the start of the step)
    """

    def __init__(self, size: int = 10, eps: float = 1e-8) -> None:
        if size < 1:
            raise ValueError(f"L-BFGS memory must be at least 1, got {size}")
        self.size = int(size)
        self.eps = float(eps)
        self.pairs: deque[tuple[FloatArray, FloatArray, float]] = deque(maxlen=self.size)
        self.rejected = 0

    def update(self, s: FloatArray, yhat: FloatArray, slope: float) -> bool:
        """Store the pair ``(s, ŷ)`` if ``s·ŷ > eps·|slope|`` (``slope = P_k·s``);
        returns whether it was stored."""
        sy = dot(s, yhat)
        if not (np.isfinite(sy) and sy > self.eps * abs(slope)):
            self.rejected += 1
            return False
        self.pairs.append((s, yhat, 1.0 / sy))
        return True

    def direction(self, P: FloatArray, riesz: Riesz, h0: Riesz | None = None) -> FloatArray:
        """``d = −H_k P`` by the two-loop recursion with ``H_0 = γ G⁻¹`` (``−G⁻¹ P`` while
        the memory is empty), or ``H_0 = γ B⁻¹`` with ``h0 = B⁻¹`` an SPD preconditioner
        (:mod:`.preconditioners`; ``γ = s·ŷ / ŷ·B⁻¹ŷ``, ``−B⁻¹P`` while empty): the
        Euclidean two-loop on covectors is valid with any SPD ``H_0``, and every ``H_k``
        is SPD since every stored pair has ``s·ŷ > 0``, so ``d`` is a descent direction."""
        if h0 is not None:
            riesz = h0
        if not self.pairs:
            return -riesz(P)
        q = np.array(P, dtype=float)
        alphas = []
        for s, y, rho in reversed(self.pairs):
            a = rho * dot(s, q)
            q -= a * y
            alphas.append(a)
        s, y, rho = self.pairs[-1]
        yGy = dot(y, riesz(y))
        gamma = (1.0 / rho) / yGy if yGy > 0 else 1.0
        r = gamma * riesz(q)
        for (s, y, rho), a in zip(self.pairs, reversed(alphas)):
            b = rho * dot(y, r)
            r += (a - b) * s
        return -r

    def clear(self) -> None:
        self.pairs.clear()


def hestenes_stiefel_plus(grad: FloatArray, yhat: FloatArray, d_prev: FloatArray) -> float:
    """``β = max(0, g(grad_{k+1}, G⁻¹ŷ) / g(d_k, G⁻¹ŷ)) = max(0, grad·ŷ / d_k·ŷ)`` (HS+).

    With ``ŷ = P_{k+1} − P_k`` no solve is needed: ``g(V, G⁻¹ŷ) = V·ŷ``. Returns 0
    (a restart) when the denominator is not positive.
    """
    den = dot(d_prev, yhat)
    if not (np.isfinite(den) and den > 0):
        return 0.0
    return max(0.0, dot(grad, yhat) / den)


class SteepestDescent:
    """``d = −grad F``: the thesis' steepest descent (algorithm 2, §6.4.1).

    The protocol of a direction rule: ``direction(Q, P, grad, riesz)``; ``has_history``
    (a step was taken: a failed direction may be restarted or retried along ``−grad``);
    ``unit_step`` (try ``t = 1`` first); ``restart()`` (forget the past);
    ``remember(s, P_new, P, d)`` after an accepted step ``s`` along ``d`` (returns whether
    its curvature pair was rejected); ``rejected`` (pairs rejected in all).
    """

    has_history = False
    unit_step = False
    rejected = 0

    def direction(self, Q: FloatArray, P: FloatArray, grad: FloatArray, riesz) -> FloatArray:
        return -grad

    def restart(self) -> None:
        pass

    def remember(self, s: FloatArray, P_new: FloatArray, P: FloatArray, d: FloatArray) -> bool:
        return False


class ConjugateGradient(SteepestDescent):
    """Nonlinear CG, ``d = β d_prev − grad F`` with Hestenes–Stiefel+ ``β``."""

    def __init__(self) -> None:
        self.d_prev: FloatArray | None = None
        self.P_prev: FloatArray | None = None

    @property
    def has_history(self) -> bool:
        return self.d_prev is not None

    def direction(self, Q, P, grad, riesz):
        if self.d_prev is None:
            return -grad
        return hestenes_stiefel_plus(grad, P - self.P_prev, self.d_prev) * self.d_prev - grad

    def remember(self, s, P_new, P, d):
        self.d_prev, self.P_prev = d, P
        return False


class LBFGS(SteepestDescent):
    """Riemannian L-BFGS: ``d = −H_k P`` by :class:`LBFGSMemory`'s two-loop recursion,
    ``H_0 = γ G⁻¹`` or ``γ B⁻¹`` with ``h0(Q, X) = B⁻¹X`` a preconditioner."""

    def __init__(self, memory: int = 10, h0=None) -> None:
        self.memory = LBFGSMemory(memory)
        self.h0 = h0
        self.has_history = False

    @property
    def unit_step(self) -> bool:
        return bool(self.memory.pairs) or self.h0 is not None

    @property
    def rejected(self) -> int:
        return self.memory.rejected

    def direction(self, Q, P, grad, riesz):
        h0 = None if self.h0 is None else (lambda X: self.h0(Q, X))
        return self.memory.direction(P, lambda X: riesz(Q, X), h0)

    def restart(self):
        self.memory.clear()

    def remember(self, s, P_new, P, d):
        self.has_history = True
        return not self.memory.update(s, P_new - P, dot(P, s))


#: the direction rule of each method (``method="steepest" | "lbfgs" | "cg"``)
DIRECTION_RULES = {"steepest": SteepestDescent, "lbfgs": LBFGS, "cg": ConjugateGradient}
