"""The damped Gauss–Newton system of a surface morph's interior frames
(:mod:`.morph`), solved by preconditioned conjugate gradients; a frame's contact
barrier (:mod:`.morph_contact`) adds its projected Hessian to that frame's block."""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray
from ...solvers import factorize_spd
from ..engine.frame_threads import frame_map

__all__ = ["PathSystem"]


class PathSystem:
    """The damped Gauss–Newton matrix of the interior frames, ``H + λ diag H + B`` with
    ``H = 𝔻ᵀ(T ⊗ I)𝔻``, ``𝔻 = diag(D_1, …, D_{K−1})`` the frames' embedding Jacobians,
    ``T`` the path's Laplacian in time (2 on the diagonal, −1 beside) and ``B`` the
    block-diagonal Hessians of the frames' contact barriers (where one is active), never
    assembled; solved by conjugate gradients preconditioned by its diagonal blocks
    ``(2 + 2λ diag) D_jᵀD_j + B_j``, one Cholesky factor per frame kept across iterations
    (refactorized on its analysis; a block with a barrier term is factorized anew, its
    pattern that of the barrier's pairs)."""

    def __init__(self, frames: int) -> None:
        m = frames - 1
        self.T = 2.0 * np.eye(m) - np.eye(m, k=1) - np.eye(m, k=-1)
        self.factors: list = [None] * m
        self.factorizations = 0
        self.barriers: list = [None] * m
        #: the frames whose kept factor includes a barrier block (not refactorizable)
        self._patterned: set = set()

    def update(self, D: list, damping: float, refactorize: bool,
               barriers: list | None = None) -> None:
        """The frames' Jacobians ``D``, the damping ``λ`` and the frames' barrier Hessians
        (None where none is active); the blocks factorized again where asked or where a
        barrier is active (else the kept factors of an earlier iterate precondition)."""
        self.D, self.damping = D, damping
        self.barriers = [None] * len(D) if barriers is None else list(barriers)
        self.diagonal = np.concatenate([2.0 * np.asarray(Dj.multiply(Dj).sum(axis=0)).ravel()
                                        for Dj in D])
        contact = any(B is not None for B in self.barriers)
        if not refactorize and not contact and self.factors[0] is not None:
            return

        def factorize(j):
            G = 2.0 * (D[j].T @ D[j]).tocsc()
            G.setdiag(G.diagonal() * (1.0 + damping))
            if self.barriers[j] is not None:
                self.factors[j] = factorize_spd((G + self.barriers[j]).tocsc())
                self._patterned.add(j)
            elif hasattr(self.factors[j], "refactorize") and j not in self._patterned:
                self.factors[j].refactorize(G)
            else:
                self.factors[j] = factorize_spd(G)
                self._patterned.discard(j)

        list(frame_map(D[0].shape[0], len(D))(factorize, range(len(D))))
        self.factorizations += len(D)

    def product(self, v: FloatArray, damping: float | None = None) -> FloatArray:
        """``(H + λ·diag H + B) v``, ``λ`` the system's damping unless given."""
        V = v.reshape(len(self.D), -1)
        U = self.T @ np.stack([Dj @ x for Dj, x in zip(self.D, V)])
        Hv = np.concatenate([Dj.T @ u if B is None else Dj.T @ u + B @ x
                             for Dj, u, x, B in zip(self.D, U, V, self.barriers)])
        damping = self.damping if damping is None else damping
        return Hv + damping * self.diagonal * v

    def precondition(self, v: FloatArray) -> FloatArray:
        V = v.reshape(len(self.D), -1)
        return np.concatenate(list(frame_map(self.D[0].shape[0], len(self.D))(
            lambda f, x: f(x), self.factors, V)))

    def solve(self, b: FloatArray, rtol: float = 5e-2, max_iterations: int = 100
              ) -> FloatArray:
        """Preconditioned conjugate gradients from 0 to ``|r| ≤ rtol |b|``."""
        x = np.zeros_like(b)
        self.iterations = 0
        r = b.copy()
        z = self.precondition(r)
        p, rz = z.copy(), float(r @ z)
        target = rtol * float(np.linalg.norm(b))
        for self.iterations in range(1, max_iterations + 1):
            Ap = self.product(p)
            alpha = rz / float(p @ Ap)
            x += alpha * p
            r -= alpha * Ap
            if np.linalg.norm(r) <= target:
                break
            z = self.precondition(r)
            rz, rz_old = float(r @ z), rz
            p = z + (rz / rz_old) * p
        return x
