"""Discrete geodesics of the per-triangle graph metric ``g = M + w² JᵀJ``.

A path of ``K`` segments, frames ``Q_0 … Q_K``, has the discrete energy

    E = K · Σ_k ( |Q_{k+1} − Q_k|²_M + w² |φ(Q_{k+1}) − φ(Q_k)|² ),

the energy of the polygon through the embedded points ``X(Q) = (m^½ ⊙ Q, w φ(Q))``: a sparse
nonlinear least-squares problem in the free coordinates, solved by Levenberg–Marquardt
(the Gauss–Newton normal matrix is block tridiagonal over frames, each block a sparse
mesh-shaped matrix) with a feasibility test: a trial with an inverted triangle (``φ = ∞``)
or a self-intersecting boundary is rejected like a trial that raises the energy.

The per-triangle bound holds for every discrete path, exactly (triangle inequality):
``|φ_t(Q_k) − φ_t(Q_0)| ≤ ℓ_k / w`` with ``ℓ_k = Σ_{j<k} |X(Q_{j+1}) − X(Q_j)|``.
"""

from __future__ import annotations

import hashlib
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from .assembly import (UPPER_DIAGONAL, BlockTridiagonal, MeshPattern, PathPattern,
                       block_products, symmetric_products)
from .frame_blocks import FrameBlocks
from .frame_threads import frame_map
from .graph_metric import GraphMetric
from .time_coupling import FrameEmbedding

logger = logging.getLogger(__name__)


@dataclass
class PathResult:
    """A discrete geodesic: ``frames`` (K+1, N, 2), its ``energy``, gradient norm,
    iterations and ``status`` in {"converged", "stalled", "max_iter"}."""

    frames: FloatArray
    energy: float
    gradient_norm: float
    nit: int
    status: str
    history: list = field(default_factory=list)

    @property
    def converged(self) -> bool:
        return self.status == "converged"


_PATTERNS: dict = {}  # the last few assembly patterns, by structure
_LOCK = threading.Lock()  # guards _PATTERNS


class _Path:
    """Residuals and Jacobian of the discrete path energy in the free coordinates."""

    def __init__(self, metric: GraphMetric, frames: FloatArray, free: np.ndarray,
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
        tri_cols = (2 * strain.triangles[:, :, None] + np.arange(2)).reshape(-1, 6)  # (T, 6)
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

    def admissible(self, frames: FloatArray) -> bool:
        """Every triangle of every frame positive, no boundary self-intersection."""
        from ..mesh import boundary_self_intersections

        def admissible_frame(Q: FloatArray) -> bool:
            if not (self.metric.strain.determinants(Q) > 0).all():
                return False
            return self.boundary_edges is None or not len(
                boundary_self_intersections(Q, self.boundary_edges))

        return all(frame_map(len(self.metric.triangles), self.K)(admissible_frame, frames[1:]))


#: relative size below which a change of the energy is rounding (its evaluation sums
#: thousands of rounded terms)
ENERGY_RESOLUTION = 100 * np.finfo(float).eps
#: the damping's factor after a step whose decrease the model predicted well (ρ > 0.75).
#: The paths have soft directions (a frame sliding along itself) that a damped step
#: barely moves along; with the usual 1/3 the morph spent its last iterations waiting
#: for λ to fall (4.2k twist: 14 iterations, 6 of them at |∇E| ≈ 1e-3 with ρ ≈ 1);
#: with 1/10, 10 iterations to the same min AR in every frame, and move's relaxations
#: and quality rounds 10–15 % fewer.
LAMBDA_DECREASE = 0.1
#: damping below which a step is the model's own (Gauss–Newton or Newton) step. Such a
#: step that promises less than ``ENERGY_RESOLUTION · E`` cannot be judged by E (its
#: change is rounding, ~1e-16·E, either sign): it is taken if it lowers |∇E| (one
#: assembly at the trial, reused as the next iteration's), and where it does not, the
#: path is converged to machine precision. Measured on the 225° twist of the 27k disc
#: (|∇E| ≈ 1e-4 there, gtol·√E = 2.2e-5): the ratio test rejected such steps on E's
#: rounding and raised λ fourfold each time, 20 CG solves in one iteration; a target
#: changed by 2e-16 so took 14 iterations (26 s) instead of 11 (13 s).
UNDAMPED = 1e-6


def discrete_geodesic(
    metric: GraphMetric,
    frames: FloatArray,
    free: np.ndarray,
    *,
    boundary_edges: IntArray | None = None,
    anchor_strain: FloatArray | None = None,
    gtol: float = 1e-7,
    rtol: float = 0.0,
    max_iter: int = 200,
    callback: Callable[[int, float, float], None] | None = None,
    factors: FrameBlocks | None = None,
    cg_rtol: float = 1e-2,
    newton: bool = False,
    lambda_decrease: float = LAMBDA_DECREASE,
) -> PathResult:
    """Minimize the discrete path energy over the free coordinates by Levenberg–Marquardt.

    Parameters
    ----------
    metric : GraphMetric
    frames : (K+1, N, 2) float array
        An admissible initial path (every triangle positive, boundaries simple).
    free : (K+1, N) bool array
        Which vertices of which frame move (frame 0 never does).
    boundary_edges : (E, 2) int array, optional
        Checked for self-intersection in every accepted frame.
    anchor_strain : (T, 3) float array, optional
        Used instead of ``φ(Q_0)`` in the first segment: with one segment, the frame that
        stays close to ``Q_0`` while its strain approaches ``anchor_strain``.
    gtol : float
        Stop when ``|∇E| ≤ gtol · max(1, √E)``; also reported "converged" when no step
        can lower ``E`` by more than its floating-point resolution (``ENERGY_RESOLUTION``
        relative): the minimum to machine precision, which a tight ``gtol`` on a large
        energy may not reach (measured: a morph whose ``E ≈ 1e4`` stopped at
        ``|∇E| = 6e-5`` with model decreases of 3e-12).
    rtol : float
        Or when ``|∇E| ≤ rtol · |∇E₀|`` (the first gradient): enough for a relaxation
        whose start is already close (the Gauss–Newton steps then converge fast).
    max_iter : int
    callback : callable ``(iteration, E, |∇E|)``, optional
    factors : FrameBlocks, optional
        The preconditioner's frame factorizations, shared with the caller: a sequence of
        close problems with the same free coordinates (the frames of a continuation)
        factorizes only when conjugate gradients slow down, not once per problem.
    cg_rtol : float
        Relative residual of the conjugate-gradient solve of each step. An inexact step
        is fine (the ratio test judges it): measured on the 225° twist of the 4.2k disc,
        1e-6, 1e-3 and 1e-2 take the same 14 iterations to the same frames (1e-3: 13 %
        less time than 1e-6; 1e-2: 1862 triangular solves instead of 2058); move's
        relaxations and quality rounds and the morph use 0.1 (see where they say so).
    newton : bool
        Steps from the Hessian of the energy (True) or from its Gauss–Newton part ``JᵀJ``
        (False). Where the residual is not small (a frame pulled towards strains it cannot
        reach: move's relaxations and quality step), Gauss–Newton converges only linearly
        (measured on the 90° annulus turn, 42.6k triangles: a relaxation took 5 iterations
        to a 100× smaller gradient, Newton 3; a quality round's gradient fell 30× in 15
        Gauss–Newton iterations, 1e5× in 7 Newton ones). On the morph's paths from a cold
        start it saves none (225° twist, 4.2k / 27k triangles: 14 / 17 iterations either
        way; 180° annulus pair 17 → 23); from the refined frames of a coarser level it
        does (107k: 7 iterations instead of 11, :data:`.morph.REFINED_CG_RTOL`). The
        Hessian may be indefinite: a step on which conjugate gradients meet non-positive
        curvature is rejected like one that raises the energy (the damping
        ``λ·diag(JᵀJ)`` grows until the matrix is positive definite).
    lambda_decrease : float
        The damping's factor after a step whose decrease the model predicted well
        (``ρ > 0.75``; :data:`LAMBDA_DECREASE`). Newton steps from a start close to the
        minimizer converge quadratically only once the damping is gone: there a
        smaller factor gets there sooner (:data:`.morph.REFINED_LAMBDA_DECREASE`).

    Returns
    -------
    PathResult
    """
    frames = np.array(frames, dtype=float)
    free = np.array(free, dtype=bool)
    free[0] = False
    path = _Path(metric, frames, free, boundary_edges, anchor_strain)
    if not path.admissible(frames):
        raise ValueError("the initial path is not admissible")
    if path.n_unknowns == 0:
        r, _ = path.evaluate(frames, jacobian=False)
        return PathResult(frames, float(r @ r), 0.0, 0, "converged")
    r, g, H, d = path.normal_equations(frames, newton)
    E = float(r @ r)
    lam = 1e-3
    blocks = (FrameBlocks(path.frame_indices(), path.frame_points()) if factors is None
              else factors)
    if len(blocks.indices) != len(path.frame_indices()) or any(
            a.size != b.size for a, b in zip(blocks.indices, path.frame_indices())):
        raise ValueError("factors were made for other free coordinates")
    status = "max_iter"
    history = []
    it = 0
    for it in range(1, max_iter + 1):
        gnorm = 2.0 * float(np.linalg.norm(g))
        history.append((E, gnorm))
        if callback is not None:
            callback(it - 1, E, gnorm)
        if it == 1:
            g0 = gnorm
        if gnorm <= max(gtol * max(1.0, np.sqrt(E)), rtol * g0):
            status = "converged"
            it -= 1
            break
        x = path.unknowns(frames)
        accepted = False
        # whether an admissible trial's model decrease exceeded E's rounding (None: no
        # admissible trial was evaluated)
        resolvable: bool | None = None
        at_floor = False
        judged = None  # the normal equations at a step judged by its gradient
        for _ in range(30):
            A = H.damped(lam * (d + 1e-12 * d.max()))
            try:
                step = blocks.solve(A, -g, cg_rtol)
            except FloatingPointError:  # A is not positive definite (Newton): damp more
                lam *= 4.0
                continue
            trial = path.with_unknowns(x + step)
            if path.admissible(trial):
                r_t, _ = path.evaluate(trial, jacobian=False)
                E_t = float(r_t @ r_t)
                predicted = -(2 * g @ step + step @ (H @ step))  # the quadratic model's
                resolvable = bool(resolvable or predicted > ENERGY_RESOLUTION * E)
                if lam <= UNDAMPED and predicted <= ENERGY_RESOLUTION * E:
                    # E cannot judge the model's own step (its change is rounding): the
                    # gradient, computed to full precision, does
                    judged = path.normal_equations(trial, newton)
                    if 2.0 * float(np.linalg.norm(judged[1])) < gnorm:
                        frames = trial
                        accepted = True
                    else:
                        at_floor = True
                    break
                if np.isfinite(E_t) and E_t < E:
                    rho = (E - E_t) / max(predicted, 1e-300)
                    frames = trial
                    lam = lam * (lambda_decrease if rho > 0.75 else 1.0 if rho > 0.25 else 2.0)
                    lam = max(lam, 1e-12)
                    accepted = True
                    break
            lam *= 4.0
        if at_floor:
            # neither E nor its gradient can be lowered: the minimum to machine precision
            status = "converged"
            it -= 1
            break
        if not accepted:
            # no step lowers E, and the admissible ones promised no more than E's
            # floating-point resolution: the minimum to machine precision (a tight gtol
            # cannot be met there)
            status = "converged" if resolvable is False else "stalled"
            break
        path.frames = frames
        r, g, H, d = path.normal_equations(frames, newton) if judged is None else judged
        E = float(r @ r)
    gnorm = 2.0 * float(np.linalg.norm(g))
    if status == "max_iter" and gnorm <= gtol * max(1.0, np.sqrt(E)):
        status = "converged"
    return PathResult(frames, E, gnorm, it, status, history)
