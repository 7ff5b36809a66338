"""The discrete path energy of the tet graph metric ``g = M + w² JᵀJ`` (:mod:`.metric`)
as a least-squares problem (:class:`TetPath`, a
:class:`~meshopt_toolkit.riemannian.levenberg_marquardt.LeastSquaresPath`; minimized by
:func:`~meshopt_toolkit.riemannian.levenberg_marquardt.levenberg_marquardt`).

A path of ``K`` segments, frames ``Q_0 … Q_K`` with both ends fixed, has the energy

    E = K · Σ_k ( |Q_{k+1} − Q_k|²_M + w² |φ(Q_{k+1}) − φ(Q_k)|² ),

the energy of the polygon through ``X(Q) = (m^½ ⊙ Q, w φ(Q))``; the unknowns are every
coordinate of the interior frames. The Gauss–Newton matrix is block tridiagonal over the
frames (:class:`..planar.assembly.BlockTridiagonal`), each block a sparse ``3N × 3N`` matrix with
one 12×12 block per tet (:class:`CellPattern`), solved by conjugate gradients with the
frames' kept factorizations and the time-coupled preconditioner (:class:`.FrameBlocks`,
:mod:`..planar.time_coupling`, which take any per-cell blocks). A frame with a tet not positively
oriented (``φ = ∞``) is not admissible; with ``crosses``, neither is one whose boundary
intersects itself (the morph's avoidance: a trial through itself is refused like an
inverted one).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray
from ..engine.sparse_pattern import CellPattern
from ..planar.assembly import BlockTridiagonal
from ..planar.frame_blocks import FrameBlocks
from ..planar.time_coupling import FrameEmbedding


class TetPath:
    """Residuals, Jacobian and normal equations of the discrete path energy of a tet
    mesh's graph metric, the interior frames' coordinates unknown.

    Parameters
    ----------
    metric : :class:`.metric.TetGraphMetric`
    frames : (K+1, N, 3) float array
        Every vertex in some tet (the mass of the others is zero). The ends are fixed:
        the frames given later have the same ends.
    crosses : callable ``(N, 3) points -> bool``, optional
        Whether a frame's boundary intersects itself; such a frame is not admissible.
    """

    def __init__(self, metric, frames: FloatArray,
                 crosses: Callable[[FloatArray], bool] | None = None) -> None:
        self.metric = metric
        self.crosses = crosses
        self.frames = np.array(frames, dtype=float)
        self.K = self.frames.shape[0] - 1
        self.N = self.frames.shape[1]
        self.n_coords = 3 * self.N
        self.n_unknowns = (self.K - 1) * self.n_coords
        self.sqrt_m = np.repeat(np.sqrt(metric.mass), 3)
        self.columns = metric.strain.columns()  # (C, 12)
        self._pattern: CellPattern | None = None
        # the fixed ends' distortion, evaluated once
        self._ends = (metric.strain.values(self.frames[0]), metric.strain.values(self.frames[-1]))

    # -- the unknowns -----------------------------------------------------------------
    def unknowns(self, frames: FloatArray) -> FloatArray:
        return frames[1:-1].ravel().copy()

    def with_unknowns(self, x: FloatArray) -> FloatArray:
        frames = self.frames.copy()
        frames[1:-1] = x.reshape(self.K - 1, self.N, 3)
        return frames

    @property
    def pattern(self) -> CellPattern:
        if self._pattern is None:
            self._pattern = CellPattern(self.columns, self.n_coords)
        return self._pattern

    # -- residuals ----------------------------------------------------------------------
    def _residuals(self, frames: FloatArray, phis: list[FloatArray]
                   ) -> tuple[list[FloatArray], list[FloatArray], FloatArray]:
        sK, w = np.sqrt(self.K), self.metric.weight
        res_m = [sK * self.sqrt_m * (frames[k + 1] - frames[k]).ravel() for k in range(self.K)]
        res_p = [sK * w * (phis[k + 1] - phis[k]) for k in range(self.K)]  # (C, 7) each
        r = np.concatenate([np.concatenate([a, b.ravel()]) for a, b in zip(res_m, res_p)])
        return res_m, res_p, r

    def evaluate(self, frames: FloatArray, jacobian: bool):
        """The residual vector and, with ``jacobian``, its sparse Jacobian in the unknowns
        (the plain reference :meth:`normal_equations` is tested against)."""
        strain = self.metric.strain
        if not jacobian:
            phis = [self._ends[0], *(strain.values(Q) for Q in frames[1:-1]), self._ends[1]]
            return self._residuals(frames, phis)[2], None
        pairs = [strain.values_and_jacobian(Q) for Q in frames]
        r = self._residuals(frames, [p for p, _ in pairs])[2]
        sK, w, n = np.sqrt(self.K), self.metric.weight, self.n_coords
        n_strain = 7 * len(self.columns)
        Js = [strain.jacobian_matrix(jb) for _, jb in pairs]
        rows = []
        for k in range(self.K):
            row = []
            for j in range(1, self.K):
                sign = 1.0 if j == k + 1 else -1.0 if j == k else 0.0
                if sign == 0.0:
                    row.append(sp.csr_matrix((n + n_strain, n)))
                else:
                    row.append(sign * sK * sp.vstack([sp.diags(self.sqrt_m), w * Js[j]]))
            rows.append(row)
        J = sp.bmat(rows, format="csr") if self.K > 1 else sp.csr_matrix((r.size, 0))
        return r, J

    def normal_equations(self, frames: FloatArray, newton: bool = False
                         ) -> tuple[FloatArray, FloatArray, BlockTridiagonal, FloatArray]:
        """``r``, the gradient ``Jᵀr`` (half ``∇E``), the step matrix (``JᵀJ``, or with
        ``newton`` the Hessian of ``½E``: each frame's residual curvature
        :meth:`.TetDistortion.second_order` added to its diagonal block) and the diagonal
        of ``JᵀJ``, in the unknowns. Segment ``k`` adds ``K·D_kᵀD_k`` and ``K·D_{k+1}ᵀD_{k+1}``
        to the diagonal and ``−K·D_kᵀD_{k+1}`` off it, ``D_k = [m^½; w B_k]``."""
        K, n, w = self.K, self.n_coords, self.metric.weight
        sK = np.sqrt(K)
        strain = self.metric.strain
        phis, blocks = [self._ends[0]], [None]
        for Q in frames[1:-1]:
            phi, jb = strain.values_and_jacobian(Q)
            phis.append(phi)
            blocks.append(w * jb)  # w B_k, (C, 7, 12)
        phis.append(self._ends[1])
        res_m, res_p, r = self._residuals(frames, phis)
        cols = self.columns.ravel()
        mass = self.sqrt_m**2
        g = np.empty(self.n_unknowns)
        scaling = np.empty(self.n_unknowns)
        diagonal, ranges = [], []
        for k in range(1, K):
            i = k - 1
            ranges.append((i * n, (i + 1) * n))
            part = res_p[k - 1] - res_p[k]  # (C, 7)
            back = np.einsum("ci,cij->cj", part, blocks[k])
            g[i * n:(i + 1) * n] = (sK * self.sqrt_m * (res_m[k - 1] - res_m[k])
                                    + sK * np.bincount(cols, back.ravel(), minlength=n))
            products = 2.0 * K * np.matmul(np.swapaxes(blocks[k], 1, 2), blocks[k])
            scaling[i * n:(i + 1) * n] = 2.0 * K * mass + np.bincount(
                cols, np.diagonal(products, axis1=1, axis2=2).ravel(), minlength=n)
            if newton:  # Σ_i r_i ∇²r_i of the strain rows at frame k
                products = products + strain.second_order(frames[k], sK * w * part)
            diagonal.append(self.pattern.matrix(self.pattern.values(products, 2.0 * K * mass)))
        upper, lower = {}, {}
        for i in range(K - 2):
            products = -K * np.matmul(np.swapaxes(blocks[i + 1], 1, 2), blocks[i + 2])
            values = self.pattern.values(products, -K * mass)
            upper[i] = self.pattern.matrix(values)
            lower[i] = self.pattern.matrix(values, transpose=True)
        embedding = FrameEmbedding(self.sqrt_m, blocks[1:K], self.columns,
                                   [np.arange(n)] * (K - 1), [2] * (K - 1),
                                   list(range(K - 2)), K)
        return r, g, BlockTridiagonal(ranges, diagonal, upper, lower,
                                      embedding=embedding), scaling

    # -- admissibility and the step solver ----------------------------------------------
    def admissible(self, frames: FloatArray) -> bool:
        """Every tet of every interior frame positively oriented (and, with ``crosses``,
        no interior frame's boundary through itself: checked last, it costs more)."""
        inner = frames[1:-1]
        return all(np.isfinite(Q).all() and (self.metric.strain.determinants(Q) > 0).all()
                   for Q in inner) and (self.crosses is None
                                        or not any(self.crosses(Q) for Q in inner))

    def step_solver(self, kept: FrameBlocks | None = None) -> FrameBlocks:
        """The interior frames' factorizations (block Jacobi or time-coupled
        preconditioner of the step systems)."""
        indices = [np.arange(i * self.n_coords, (i + 1) * self.n_coords)
                   for i in range(self.K - 1)]
        blocks = FrameBlocks(indices) if kept is None else kept
        if [i.size for i in blocks.indices] != [i.size for i in indices]:
            raise ValueError("factors were made for other free coordinates")
        return blocks
