"""The preconditioner of the path systems: the frames' kept (nested-dissection ordered)
factorizations, applied as block Jacobi or, where frames are neighbours, as the
time-coupled preconditioner (:mod:`.time_coupling`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ... import _cholmod
from ..._typing import FloatArray
from ...solvers import CholeskyFactor, cholmod_available, factorize_spd, nested_dissection, pcg
from ..engine.frame_threads import frame_pool
from .assembly import BlockTridiagonal
from .time_coupling import FrameEmbedding

REFACTOR_AFTER_CG = 12  # CG iterations after which the kept factorizations are renewed
#: the same with the time-coupled preconditioner, which needs fresher factors: its frame
#: solves stand for the pseudo-inverses of the current frames' Jacobians, twice per
#: application
REFACTOR_AFTER_CG_COUPLED = 4
#: and a solve on kept factors that needs more than this many iterations goes on from
#: there on fresh ones (stale factors can make a single solve several times longer; the
#: limit stays above the iterations a Newton system takes on fresh factors)
STALE_CG_LIMIT = 12


#: frames of at least this many unknowns are factorized and solved in parallel threads
#: (SuperLU and CHOLMOD through :mod:`.._cholmod` release the GIL; below this the
#: threads' overhead outweighs the work)
PARALLEL_FROM = 20_000


def _time_coupling(A) -> FrameEmbedding | None:
    """The frames' embedding of a path matrix whose frames are neighbours (the
    time-coupled preconditioner applies), else None."""
    embedding = getattr(A, "embedding", None)
    return embedding if embedding is not None and embedding.coupled else None


class FrameBlocks:
    """The diagonal blocks (one per frame, mesh-sized) of a recent path matrix, factorized,
    as the preconditioner of CG on the path system: block Jacobi ``P = D̃``, or the
    time-coupled preconditioner (:mod:`.time_coupling`: two solves per frame, a few CG
    iterations instead of ten per digit) for a path matrix whose frames are neighbours.

    The factorizations are kept across Levenberg–Marquardt iterations (and across the
    problems of a continuation) until a CG solve needs more than ``REFACTOR_AFTER_CG``
    (time-coupled: ``REFACTOR_AFTER_CG_COUPLED``) iterations (a count, not a time: the
    decisions and so the results must not depend on the machine's load); CHOLMOD's are
    then refactorized on their kept analyses. The frames' blocks are independent: with
    several frames of at least ``PARALLEL_FROM`` unknowns they are factorized and solved
    in threads, one per core (``threaded``; the results do not depend on it). Block
    Jacobi rather than symmetric block Gauss–Seidel, which does two solves per block.

    ``indices`` are each frame's columns, its vertices' ``x, y`` in turn; with ``points``,
    the positions of each frame's vertices (the reference mesh), the blocks are factorized
    in :func:`.solvers.nested_dissection` order (computed once) instead of minimum degree
    (less fill).

    Where CHOLMOD is installed (:func:`.solvers.cholmod_available`) the blocks are its
    double-precision Cholesky factors (faster to factorize and to solve than SuperLU's
    float32 LU), called through :mod:`.._cholmod`, which releases the GIL, so the frames
    run in threads. Without CHOLMOD, SuperLU in float32, in threads.
    """

    def __init__(self, indices: list[np.ndarray], points: list[FloatArray] | None = None):
        if points is not None and [2 * len(p) for p in points] != [i.size for i in indices]:
            raise ValueError("points must give one vertex per two columns of each frame")
        self.indices = indices
        self.points = points
        self.orderings: list | None = None
        # SuperLU's factors in float32 while CG converges (.solvers.factorize_spd);
        # CHOLMOD's are double precision
        self.single = not cholmod_available()
        self.factors: list = []
        self.stale = True
        large = len(indices) > 1 and min(i.size for i in indices) >= PARALLEL_FROM
        pool = frame_pool() if large else None
        #: whether the frames' factorizations and solves run in the frame pool's threads
        #: (SuperLU, or CHOLMOD through :mod:`.._cholmod`: both release the GIL)
        self.threaded = pool is not None and (self.single or _cholmod.library() is not None)
        self._map = pool.map if self.threaded else map

    def factorize(self, A: sp.csr_matrix | BlockTridiagonal) -> None:
        if isinstance(A, BlockTridiagonal):
            blocks = A.diagonal_blocks()
            if [B.shape[0] for B in blocks] != [i.size for i in self.indices]:
                raise ValueError("the matrix's frames are not these factors' frames")
        elif len(self.indices) == 1 and self.indices[0].size == A.shape[0]:
            blocks = [A]  # the frame's columns are all columns, in order
        else:
            blocks = [A[idx][:, idx] for idx in self.indices]
        if self.points is not None and self.orderings is None:
            self.orderings = [nested_dissection(p, B, 2) for p, B in zip(self.points, blocks)]
        orderings = self.orderings or [None] * len(blocks)
        if len(self.factors) == len(blocks) and all(
                isinstance(f, CholeskyFactor) for f in self.factors) and not self.single:
            list(self._map(CholeskyFactor.refactorize, self.factors, blocks))  # kept analyses
        else:
            self.factors = [*self._map(factorize_spd, blocks, orderings,
                                       [self.single] * len(blocks))]
        self.stale = False

    def solve(self, A: sp.csr_matrix | BlockTridiagonal, b: FloatArray, rtol: float
              ) -> FloatArray:
        """PCG on ``A x = b`` to the relative residual ``rtol``, factorizing first when
        there is no factorization or it went stale; judges staleness afterwards. A solve
        that fails on float32 factors is redone, in double precision from then on; one
        with the time-coupled preconditioner on kept factors that does not converge within
        ``STALE_CG_LIMIT`` iterations goes on from its iterate on fresh factors.

        Raises FloatingPointError where ``A`` is not positive definite (a Newton matrix
        may not be): conjugate gradients meet non-positive curvature ``pᵀAp ≤ 0`` (which
        only an indefinite ``A`` has), or its factorization is singular; the next solve
        (of a more damped matrix) then factorizes afresh."""
        fresh = self.stale or not self.factors
        if fresh:
            try:
                self.factorize(A)
            except RuntimeError as exc:  # SuperLU: exactly singular
                self.stale = True
                raise FloatingPointError(str(exc)) from exc
        coupled = _time_coupling(A) is not None
        capped = coupled and not fresh
        try:
            x, iterations, residual = pcg(A, b, self.preconditioner(A), rtol, max_iterations=(
                STALE_CG_LIMIT if capped else max(200, b.size // 2_000)))
        except FloatingPointError:
            self.stale = True
            raise
        if residual > rtol and capped:
            # kept factors too old for the time-coupled preconditioner: the rest of the
            # solve on fresh ones (from x, so that no iteration is lost)
            self.stale = True
            return x + self.solve(A, b - A @ x, rtol / residual)
        if residual > rtol and self.single:
            self.single, self.stale = False, True
            return self.solve(A, b, rtol)
        self.stale = iterations > (REFACTOR_AFTER_CG_COUPLED if coupled else REFACTOR_AFTER_CG)
        return x

    def preconditioner(self, A: sp.csr_matrix | BlockTridiagonal | None = None
                       ) -> Callable[[FloatArray], FloatArray]:
        """``r ↦ P⁻¹ r``: the time-coupled preconditioner (:mod:`.time_coupling`) where
        ``A`` is a path matrix with neighbouring frames, block Jacobi otherwise."""
        embedding = _time_coupling(A)
        if embedding is not None:
            return embedding.preconditioner(A.ranges, self.factors)
        idx, solves, run = self.indices, self.factors, self._map

        def apply(v: FloatArray) -> FloatArray:
            out = np.empty_like(v)
            parts = run(lambda k: solves[k](v[idx[k]]), range(len(idx)))
            for i, part in zip(idx, parts):
                out[i] = part
            return out

        return apply
