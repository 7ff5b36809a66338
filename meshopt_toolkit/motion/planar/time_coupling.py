"""The path system's time-coupled preconditioner: the inverse of the path's Laplacian in
time, taken in the embedding space and brought back by each frame's least-squares solve.

The Gauss–Newton matrix of the discrete path energy (:mod:`.path`) is exactly

    H = K · 𝔻ᵀ (T ⊗ I) 𝔻,

with ``𝔻 = blockdiag(D_k)`` the frames' embedding Jacobians ``D_k = [m^½; W B_k]``
(restricted to each frame's free coordinates) and ``T`` the path graph's Laplacian over
the frames with unknowns (``T_kk`` the segments at frame ``k``: 2, or 1 for a free last
frame; ``−1`` between neighbouring frames; a fixed frame is a Dirichlet end). Block Jacobi
(:class:`.FrameBlocks`) keeps only ``T``'s diagonal and so sees the time coupling as an
ill-conditioned 1-D Laplacian: about ten CG iterations per digit on a 9-frame morph. Here

    P⁻¹ = 𝔻⁺ (T⁻¹ ⊗ I) 𝔻⁺ᵀ / K,    D_k⁺ = G_k⁻¹ D_kᵀ,  G_k = A_k / (T_kk K),

with ``A_k`` the matrix's own diagonal block (so ``G_k = D_kᵀD_k`` for Gauss–Newton, plus
the damping's and Newton's share otherwise): the frames' kept factorizations, two solves
per frame and application. ``P⁻¹H = I`` where every frame has the same ``D_k``; otherwise
it differs from ``I`` by how much the ranges of consecutive ``D_k`` differ, which is small
on a path of many frames. ``P⁻¹ = Zᵀ (T⁻¹ ⊗ I) Z`` with ``Z = 𝔻F`` injective (``F`` the
SPD frame solves): symmetric positive definite, as CG needs.

Against block Jacobi it needs fewer CG iterations, the more so the more frames a path has.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..._typing import FloatArray, IntArray
from ..engine.frame_threads import frame_submit


@dataclass
class FrameEmbedding:
    """The embedding Jacobians ``D_k`` of the frames with unknowns and the time matrix.

    Parameters
    ----------
    sqrt_mass : (2N,) float array
        ``m^½`` per coordinate.
    strain_blocks : list of (T, 3, 6) float arrays
        ``W B_k`` per frame with unknowns (rows weighted).
    triangle_columns : (T, 6) int array
        The coordinates of each triangle's corners.
    columns : list of int arrays
        Each frame's free coordinates (of ``2N``), in the order of its unknowns.
    segments : list of int
        ``T_kk``: the path's segments at each frame (2, or 1 for the last frame).
    neighbours : list of int
        The indices ``i`` whose frames ``i`` and ``i + 1`` are consecutive in time.
    K : int
        The path's segments (the energy's factor).
    """

    sqrt_mass: FloatArray
    strain_blocks: list[FloatArray]
    triangle_columns: IntArray
    columns: list[IntArray]
    segments: list[int]
    neighbours: list[int]
    K: int

    def __post_init__(self) -> None:
        n = len(self.columns)
        time = np.diag(np.asarray(self.segments, float))
        for i in self.neighbours:
            time[i, i + 1] = time[i + 1, i] = -1.0
        self.time_inverse = np.linalg.inv(time) if n else time  # n ≤ a few hundred frames

    @property
    def coupled(self) -> bool:
        """Whether any two frames with unknowns are neighbours (else block Jacobi is
        this preconditioner, at half the cost)."""
        return bool(self.neighbours)

    def _forward(self, i: int, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``D_i v``: the mass rows (2N,) and the strain rows (T, 3)."""
        full = np.zeros(self.sqrt_mass.size)
        full[self.columns[i]] = v
        strain = np.matmul(self.strain_blocks[i], full[self.triangle_columns][:, :, None])
        return self.sqrt_mass * full, strain[:, :, 0]

    def _backward(self, i: int, mass_rows: FloatArray, strain_rows: FloatArray) -> FloatArray:
        """``D_iᵀ y`` in frame ``i``'s free coordinates."""
        back = np.matmul(strain_rows[:, None, :], self.strain_blocks[i])[:, 0]
        full = self.sqrt_mass * mass_rows + np.bincount(
            self.triangle_columns.ravel(), back.ravel(), minlength=self.sqrt_mass.size)
        return full[self.columns[i]]

    def preconditioner(self, ranges: list[tuple[int, int]],
                       frame_solves: list[Callable[[FloatArray], FloatArray]]
                       ) -> Callable[[FloatArray], FloatArray]:
        """``r ↦ P⁻¹ r`` from the solves ``A_i⁻¹`` of the diagonal blocks (module
        docstring). Each frame's solve and products are one task in the frame pool:
        numpy's kernels release the GIL, and so do the solves of :mod:`.._cholmod` and
        SuperLU (CHOLMOD through ``cvxopt`` does not: its solves then take turns while
        the other frames' products go on)."""
        T_kk = np.asarray(self.segments, float)
        Tinv = self.time_inverse
        frames = range(len(ranges))
        submit = frame_submit(len(self.triangle_columns), len(ranges))

        def forward(i: int, r_i: FloatArray) -> tuple[FloatArray, FloatArray]:
            return self._forward(i, T_kk[i] * self.K * frame_solves[i](r_i))

        def backward(i: int, mass: FloatArray, strain: FloatArray) -> FloatArray:
            return T_kk[i] * frame_solves[i](self._backward(i, mass, strain))

        def apply(r: FloatArray) -> FloatArray:
            rows = [submit(forward, i, r[start:stop]) for i, (start, stop) in zip(frames, ranges)]
            rows = [f.result() for f in rows]
            mass = np.tensordot(Tinv, np.array([m for m, _ in rows]), 1)
            strain = np.tensordot(Tinv, np.array([s for _, s in rows]), 1)
            parts = [submit(backward, i, mass[i], strain[i]) for i in frames]
            out = np.empty_like(r)
            for (start, stop), part in zip(ranges, parts):
                out[start:stop] = part.result()
            return out

        return apply
