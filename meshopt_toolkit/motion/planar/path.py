"""The discrete path energy of the per-triangle graph metric ``g = M + w² JᵀJ`` as a
least-squares problem (:class:`GraphPath`, the metric's ``path_model``; minimized by
:mod:`meshopt_toolkit.riemannian.levenberg_marquardt`).

A path of ``K`` segments, frames ``Q_0 … Q_K``, has the discrete energy

    E = K · Σ_k ( |Q_{k+1} − Q_k|²_M + w² |φ(Q_{k+1}) − φ(Q_k)|² ),

the energy of the polygon through the embedded points ``X(Q) = (m^½ ⊙ Q, w φ(Q))``: a sparse
nonlinear least-squares problem in the free coordinates (the Gauss–Newton normal matrix is
block tridiagonal over frames, each block a sparse mesh-shaped matrix, solved by CG
preconditioned with :class:`.FrameBlocks`) with a feasibility test: a frame with an
inverted triangle (``φ = ∞``) or a self-intersecting boundary is not admissible.

The per-triangle bound holds for every discrete path, exactly (triangle inequality):
``|φ_t(Q_k) − φ_t(Q_0)| ≤ ℓ_k / w`` with ``ℓ_k = Σ_{j<k} |X(Q_{j+1}) − X(Q_j)|``.
"""
from __future__ import annotations

import hashlib
import logging
import threading

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...kernels.cell_maps import coordinate_columns
from ..engine.frame_threads import frame_map
from .assembly import (
    UPPER_DIAGONAL,
    BlockTridiagonal,
    MeshPattern,
    PathPattern,
    block_products,
    symmetric_products,
)
from .frame_blocks import FrameBlocks
from .time_coupling import FrameEmbedding

logger = logging.getLogger(__name__)


_PATTERNS: dict = {}  # the last few assembly patterns, by structure
_LOCK = threading.Lock()  # guards _PATTERNS


class GraphPath:
    """Residuals and Jacobian of the discrete path energy in the free coordinates."""

    def __init__(self, metric, frames: FloatArray, free: np.ndarray,
                 boundary_edges: IntArray | None, anchor_strain: FloatArray | None = None) -> None:
        self.metric = metric
        self.anchor_strain = None if anchor_strain is None else np.ravel(anchor_strain)
        self.K = frames.shape[0] - 1
        self.frames = frames.copy()
        self.free = free  # (K+1, N) bool, frame 0 all False
        self.free_coords = np.repeat(free[:, :, None], 2, axis=2)  # (K+1, N, 2)
        self.boundary_edges = boundary_edges
        N = frames.shape[1]
        self.sqrt_m = np.repeat(np.sqrt(metric.mass), 2)
        # column index of each free coordinate
        self.col = -np.ones(self.free_coords.shape, dtype=np.int64)
        self.col[self.free_coords] = np.arange(int(self.free_coords.sum()))
        self.n_unknowns = int(self.free_coords.sum())
        self.N = N
        self._pattern: PathPattern | None = None

    def unknowns(self, frames: FloatArray) -> FloatArray:
        return frames[self.free_coords]

    def with_unknowns(self, x: FloatArray) -> FloatArray:
        frames = self.frames.copy()
        frames[self.free_coords] = x
        return frames

    def evaluate(self, frames: FloatArray, jacobian: bool):
        """Residual vector (and its sparse Jacobian in the unknowns). The solver uses
        :meth:`normal_equations`; the sparse Jacobian is the plain reference it is tested
        against (and that the path energy's Taylor test differentiates)."""
        K, w = self.K, self.metric.row_weights
        sK = np.sqrt(K)
        phis, blocks = [], []
        if jacobian:
            for Q in frames:
                phi, jb = self.metric.strain.values_and_jacobian(Q)
                blocks.append(jb)
                phis.append(phi.ravel())
        else:  # φ(Q_0) is not evaluated where the anchor replaces it
            first = 0 if self.anchor_strain is None else 1
            phis = [None] * first + [phi.ravel() for phi in frame_map(
                len(self.metric.triangles), K)(self.metric.strain.values, frames[first:])]
        if self.anchor_strain is not None:
            phis[0] = self.anchor_strain
        res = []
        for k in range(K):
            res.append(sK * self.sqrt_m * (frames[k + 1] - frames[k]).ravel())
            res.append(sK * w * (phis[k + 1] - phis[k]))
        r = np.concatenate(res)
        if not jacobian:
            return r, None
        nM, nP = 2 * self.N, phis[0].size
        Jframes = [self.metric.strain.jacobian_matrix(b) for b in blocks]
        rows, cols, vals = [], [], []
        dm = sK * self.sqrt_m
        for k in range(K):
            base = k * (nM + nP)
            for frame, sign in ((k + 1, 1.0), (k, -1.0)):
                colmap = self.col[frame].ravel()
                if not (colmap >= 0).any():
                    continue
                # mass part: diagonal
                sel = np.flatnonzero(colmap >= 0)
                rows.append(base + sel)
                cols.append(colmap[sel])
                vals.append(sign * dm[sel])
                # strain part
                Jf = Jframes[frame].tocoo()
                keep = colmap[Jf.col] >= 0
                rows.append(base + nM + Jf.row[keep])
                cols.append(colmap[Jf.col[keep]])
                vals.append(sign * sK * w[Jf.row[keep]] * Jf.data[keep])
        J = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(r.size, self.n_unknowns))
        return r, J

    def normal_equations(self, frames: FloatArray, newton: bool = False
                         ) -> tuple[FloatArray, FloatArray, BlockTridiagonal, FloatArray]:
        """Residual ``r``, gradient ``Jᵀr``, the matrix of the step and the diagonal of
        ``JᵀJ`` (Levenberg–Marquardt's scaling), in the unknowns.

        ``JᵀJ`` (Gauss–Newton) is assembled from the per-triangle 6×6 products
        ``B_kᵀ W² B_l`` of the frames' Jacobian blocks (no sparse ``J``, no sparse
        product): with ``D_k`` the embedding's Jacobian at frame ``k``, segment ``k``
        contributes ``K·D_kᵀD_k``, ``K·D_{k+1}ᵀD_{k+1}`` and ``−K·D_kᵀD_{k+1}`` (and its
        transpose); agrees with :meth:`evaluate` (tested). With ``newton`` the matrix is
        the Hessian of ``½E``, ``JᵀJ + Σ_i r_i ∇²r_i``: the residual curvature of each
        free frame, :meth:`.TriangleDistortion.second_order` weighted by the strain part of
        its gradient (Taylor-tested). It may be indefinite."""
        K, N = self.K, self.N
        sK = np.sqrt(K)
        strain = self.metric.strain
        w_rows = self.metric.row_weights.reshape(-1, 3)  # (T, 3)
        # frame 0 is fixed: only its strain enters (and not even that with an anchor)
        phis = [strain.values(frames[0]) if self.anchor_strain is None
                else self.anchor_strain.reshape(-1, 3)]
        tri_cols = coordinate_columns(strain.triangles, 2)  # (T, 6)
        pattern = self._assembly_pattern(tri_cols)
        moving = set(pattern.frames)

        def strain_terms(k: int) -> tuple[FloatArray, FloatArray | None]:
            """``φ`` of frame ``k`` and, where it has unknowns, its Jacobian blocks."""
            if k in moving:
                return strain.values_and_jacobian(frames[k])
            return strain.values(frames[k]), None

        run = frame_map(len(strain.triangles), K)
        blocks: list = [None] * (K + 1)
        for k, (phi, jb) in enumerate(run(strain_terms, range(1, K + 1)), start=1):
            phis.append(phi)
            if jb is not None:
                blocks[k] = w_rows[:, :, None] * jb  # W B_k, (T, 3, 6)
        res_m = [sK * self.sqrt_m * (frames[k + 1] - frames[k]).ravel() for k in range(K)]
        res_p = [sK * w_rows * (phis[k + 1] - phis[k]) for k in range(K)]  # (T, 3) each
        r = np.concatenate([np.concatenate([a, b.ravel()]) for a, b in zip(res_m, res_p)])
        by_corner = tri_cols.T.ravel()  # the coordinates in the order of an upper row
        mass2 = np.repeat(self.metric.mass, 2)

        def frame_terms(k: int) -> tuple[FloatArray, FloatArray, FloatArray]:
            """Frame ``k``'s gradient and ``JᵀJ`` diagonal (all its coordinates) and the
            slot values of its diagonal block."""
            gm = (res_m[k - 1] - (res_m[k] if k < K else 0.0)) * sK * self.sqrt_m
            strain_part = res_p[k - 1] - (res_p[k] if k < K else 0.0)  # (T, 3)
            gp = sK * np.matmul(strain_part[:, None, :], blocks[k])[:, 0]
            full = gm + np.bincount(tri_cols.ravel(), gp.ravel(), minlength=2 * N)
            # segments k − 1 and k (one for the last)
            segments = (2.0 if k < K else 1.0) * K
            upper = symmetric_products(np.ascontiguousarray(blocks[k].transpose(2, 1, 0)))
            upper *= segments
            own = segments * mass2 + np.bincount(by_corner, upper[UPPER_DIAGONAL].ravel(),
                                                 minlength=2 * N)
            if newton:
                strain.second_order(frames[k], sK * w_rows * strain_part, out=upper)
            return full, own, pattern.mesh.symmetric_values(upper, segments * mass2)

        g = np.zeros(self.n_unknowns)
        scaling = np.zeros(self.n_unknowns)
        diagonal: list = [None] * K  # frame k's at k − 1
        for k, (full, own, values) in zip(pattern.frames, run(frame_terms, pattern.frames)):
            cols = self.col[k].ravel()
            keep = cols >= 0
            g[cols[keep]] += full[keep]
            scaling[cols[keep]] = own[keep]
            diagonal[k - 1] = values
        coupling: list = [None] * (K - 1)  # frames k, k + 1 at k − 1
        neighbours = [pattern.frames[i] for i in pattern.adjacent]
        for k, values in zip(neighbours, run(lambda k: pattern.mesh.values(
                -K * block_products(blocks[k], blocks[k + 1]), -K * mass2), neighbours)):
            coupling[k - 1] = values
        embedding = FrameEmbedding(self.sqrt_m, [blocks[k] for k in pattern.frames], tri_cols,
                                   pattern.columns, pattern.segments, pattern.adjacent, K)
        return r, g, pattern.matrix(diagonal, coupling, embedding), scaling

    def _assembly_pattern(self, tri_cols: IntArray) -> PathPattern:
        """The matrix structure (:mod:`.assembly`): it depends only on the triangles and on
        which coordinates are free, so it is kept for the path and for the next paths of
        the same structure (a continuation's steps, the rounds of a quality step)."""
        if self._pattern is None:
            structure = (self.K, hashlib.blake2b(tri_cols.tobytes() + self.free.tobytes()
                                                 ).digest())
            with _LOCK:  # paths may be solved in threads (move's frames)
                pattern = _PATTERNS.get(structure)
                if pattern is None:
                    if len(_PATTERNS) >= 4:
                        _PATTERNS.pop(next(iter(_PATTERNS)))
                    mesh = MeshPattern(self.metric.triangles, self.N)
                    pattern = PathPattern(mesh, self.col.reshape(self.K + 1, -1))
                    _PATTERNS[structure] = pattern
            self._pattern = pattern
        return self._pattern

    def frame_indices(self) -> list[np.ndarray]:
        """Column indices of each frame's free coordinates (frames with none left out)."""
        cols = [c.ravel() for c in self.col[1:]]
        return [c[c >= 0] for c in cols if (c >= 0).any()]

    def frame_points(self) -> list[FloatArray]:
        """Reference positions of each frame's free vertices, as :meth:`frame_indices`."""
        return [self.metric.reference[f] for f in self.free[1:] if f.any()]

    def step_solver(self, kept: FrameBlocks | None = None) -> FrameBlocks:
        """The frames' factorizations that precondition the step systems: ``kept`` (made
        for the same free coordinates: a continuation's steps, move's quality rounds) or
        new ones."""
        blocks = FrameBlocks(self.frame_indices(), self.frame_points()) if kept is None else kept
        if len(blocks.indices) != len(self.frame_indices()) or any(
                a.size != b.size for a, b in zip(blocks.indices, self.frame_indices())):
            raise ValueError("factors were made for other free coordinates")
        return blocks

    def admissible(self, frames: FloatArray) -> bool:
        """Every triangle of every frame positive, no boundary self-intersection."""
        from ...mesh import boundary_self_intersections

        def admissible_frame(Q: FloatArray) -> bool:
            if not (self.metric.strain.determinants(Q) > 0).all():
                return False
            return self.boundary_edges is None or not len(
                boundary_self_intersections(Q, self.boundary_edges))

        return all(frame_map(len(self.metric.triangles), self.K)(admissible_frame, frames[1:]))
