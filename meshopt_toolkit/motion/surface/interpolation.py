"""As-rigid-as-possible interpolation of two poses of a triangle surface in R³ (Alexa,
Cohen-Or & Levin 2000), the start of :func:`.morph.morph_surface`.

Each triangle's map from the source to the target (completed by its normal scaled by
``1/√|n|``, as in deformation transfer) is split ``A = R_g R S``: ``R_g`` the best global
rotation of the pair (Umeyama), ``R S`` the polar decomposition of what is left. At time
``t`` the triangle wants ``A(t) = R_g^t R^t M(t)``, ``M(t) = (1 − t) I + t S`` (rotations
in angle, each ``R``'s branch chosen continuous across the triangles' edges,
:func:`continuous_rotation_vectors`: a twist past half a turn is followed as one); the
vertices are the least-squares fit of these maps (a cotangent-Laplacian system, factorized
once), each connected piece translated so that its area-weighted centroid moves linearly.

Each triangle's rotation is interpolated alone, so neighbours whose residual rotations lie
near a half turn (where the axis of ``R`` turns fast with the map, e.g. a bar twisted by
half a turn mostly near one end) want half-way maps that disagree on their shared edge, and
the fit shears them. Optional local/global steps (Sorkine & Alexa 2007, per triangle) then
lower each frame's as-rigid-as-possible energy against the interpolated stretch,
``Σ a |∇X − R_t M(t) ∇X_0|²``: each triangle's rotation ``R_t`` becomes the best one for the
current frame (Procrustes, in closed form), the vertices the fit of those maps (the same
factor). Alexa's rotations are the first iterate; no step raises the energy. All frames
take the same number of steps, so that neighbouring frames stay alike.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial.transform import Rotation

from ..._typing import FloatArray, IntArray
from ...kernels.surface import areas
from ...mesh.core import TriangleMesh
from ...solvers import factorize_spd
from ..engine.similarity import fit_similarity_3d as fit_similarity
from .bending import diamonds_and_triangles, dihedral_angles, wrap
from .distortion import SurfaceDistortion


def _frames(P: FloatArray) -> FloatArray:
    """Per triangle ``[e1, e2, n/√|n|]`` (T, 3, 3), ``e`` the edges from corner 0."""
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    n = np.cross(e1, e2)
    n /= np.sqrt(np.linalg.norm(n, axis=1))[:, None]
    return np.stack([e1, e2, n], axis=2)


def _polar(A: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``A = R S`` per 3×3 block: R a rotation (det +1), S symmetric."""
    U, s, Vt = np.linalg.svd(A)
    d = np.sign(np.linalg.det(U @ Vt))
    d[d == 0] = 1.0
    U = U.copy()
    U[:, :, 2] *= d[:, None]
    s = s.copy()
    s[:, 2] *= d
    R = U @ Vt
    S = np.swapaxes(Vt, 1, 2) @ (s[:, :, None] * Vt)
    return R, S


class _Fit:
    """The least-squares fit of per-triangle maps from the rest planes: the cotangent
    Laplacian (one vertex of each connected piece pinned) factorized once, each piece's
    area-weighted centroid placed."""

    def __init__(self, V0: FloatArray, F: IntArray) -> None:
        self.F, self.n = F, len(V0)
        self.distortion = SurfaceDistortion(V0, F)
        self.grads = self.distortion.gradients  # (T, 3, 2) barycentric gradients
        self.area = areas(V0, F)
        # L_jk = Σ_t a_t γ_j·γ_k
        G = self.area[:, None, None] * np.einsum("tja,tka->tjk", self.grads, self.grads)
        rows = np.repeat(F, 3, axis=1).ravel()
        cols = np.tile(F, (1, 3)).ravel()
        L = sp.coo_matrix((G.ravel(), (rows, cols)), shape=(self.n, self.n)).tocsr()
        # each piece's translation is free in L: one vertex of each pinned
        n_pieces, self.piece = connected_components(L, directed=False)
        self.free = np.ones(self.n, bool)
        self.free[np.unique(self.piece, return_index=True)[1]] = False
        self.solve = factorize_spd(L[self.free][:, self.free].tocsc())
        mass = np.bincount(F.ravel(), np.repeat(self.area / 3.0, 3), minlength=self.n)
        # per piece: its vertices' share of its area (the rows of ``centroids``)
        share = mass / np.bincount(self.piece, mass, n_pieces)[self.piece]
        self.mass = sp.csr_matrix((share, (self.piece, np.arange(self.n))),
                                  shape=(n_pieces, self.n))
        # the right-hand side Σ_t a_t D_t γ_j as one operator on the maps' columns (n, 2T)
        T = len(F)
        self.divergence = sp.csr_matrix(
            ((self.area[:, None, None] * self.grads).ravel(),
             (np.repeat(F, 2, axis=1).ravel(), np.tile(np.arange(2 * T).reshape(T, 1, 2),
                                                     (1, 3, 1)).ravel())),
            shape=(self.n, 2 * T))

    def centroids(self, X: FloatArray) -> FloatArray:
        """Each connected piece's area-weighted centroid (pieces, 3)."""
        return self.mass @ X

    def __call__(self, D: FloatArray, centroids: FloatArray) -> FloatArray:
        """The vertices whose gradients best fit ``D`` (T, 3, 2), the pieces' centroids
        ``centroids`` (pieces, 3)."""
        rhs = self.divergence @ np.swapaxes(D, 1, 2).reshape(-1, 3)
        X = np.zeros((self.n, 3))
        X[self.free] = self.solve(rhs[self.free])
        return X + (centroids - self.centroids(X))[self.piece]


def _plane_frames(A: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per 3×2 block ``A = [u v] r`` (Gram–Schmidt): the orthonormal ``u, v`` (T, 3) and
    the upper triangular ``r`` as its entries ``r00, r01, r11`` (T, 3), ``r00, r11 > 0``."""
    a0, a1 = A[:, :, 0], A[:, :, 1]
    r00 = np.sqrt(np.einsum("ti,ti->t", a0, a0))
    u = a0 / r00[:, None]
    r01 = np.einsum("ti,ti->t", u, a1)
    w = a1 - r01[:, None] * u
    r11 = np.sqrt(np.einsum("ti,ti->t", w, w))
    return u, w / r11[:, None], np.stack([r00, r01, r11], axis=1)


def _best_rotated(J: FloatArray, m: FloatArray) -> FloatArray:
    """``R M`` per triangle, ``R`` the rotation (det +1) minimizing ``|J − R M|`` for 3×2
    blocks of rank 2 (T, 3, 2), ``M`` given by its triangular factor ``m`` of
    :func:`_plane_frames` (T, 3). ``R`` maps ``M``'s oriented plane onto ``J``'s (the
    optimum: in those planes' bases both blocks have a positive determinant) and turns it
    by the 2D Procrustes angle, in closed form."""
    u, v, j = _plane_frames(J)
    j00, j01, j11 = j.T
    m00, m01, m11 = m.T
    # the 2×2 cross-covariance j mᵀ in the planes' bases, and its rotation (c, s)
    c, s = j00 * m00 + j01 * m01 + j11 * m11, j11 * m01 - j01 * m11
    h = np.hypot(c, s)
    c, s = c / h, s / h
    # [u v] R(c, s) m, m upper triangular
    return np.stack([(c * m00)[:, None] * u + (s * m00)[:, None] * v,
                     (c * m01 - s * m11)[:, None] * u + (s * m01 + c * m11)[:, None] * v],
                    axis=2)


def continuous_rotation_vectors(rotvecs: FloatArray, points: FloatArray,
                                triangles: IntArray, *, long_way=None,
                                turned: FloatArray | None = None) -> FloatArray:
    """The rotation vectors of the same rotations (T, 3), each triangle's branch
    ``(θ + 2πk) a`` chosen nearest its neighbour's: over a breadth-first tree of the
    triangles' edge adjacency, rooted at the least turned triangle of each connected piece,
    each takes the branch nearest its parent's, level by level. Neighbours near a half turn
    then turn the same way round, and turns beyond a half turn are followed as such
    (``θ`` beyond π) instead of the other way round.

    ``long_way`` (a (T, T) sparse matrix, nonzero on pairs of neighbours) marks the
    neighbours whose relative turn goes the long way round: a child reached from its parent
    over a marked pair takes the branch one turn beyond the nearest, away from it.
    ``turned`` (T,) orders the roots instead of the rotation angles."""
    angle = np.linalg.norm(rotvecs, axis=1)
    adjacency = TriangleMesh(points, triangles).triangle_adjacency
    _, labels = connected_components(adjacency, directed=False)
    order = np.lexsort((angle if turned is None else turned, labels))
    roots = order[np.r_[0, np.flatnonzero(np.diff(labels[order])) + 1]]
    depth, parent, _ = dijkstra(adjacency, directed=False, indices=roots, unweighted=True,
                                min_only=True, return_predecessors=True)
    depth = depth.astype(np.int64)
    out = np.array(rotvecs, float)
    by_depth = np.argsort(depth, kind="stable")
    levels = np.split(by_depth, np.searchsorted(depth[by_depth], np.arange(1, depth.max() + 1)))
    for level in levels[1:]:
        P = out[parent[level]]
        a = np.where(angle[level, None] > 0, rotvecs[level], P)  # no turn: the parent's axis
        size = np.linalg.norm(a, axis=1)
        a = a / np.where(size > 0, size, 1.0)[:, None]
        # the branch θ + 2πk along a nearest P: k = round((P·a − θ) / 2π)
        k = np.round((np.einsum("ti,ti->t", P, a) - angle[level]) / (2.0 * np.pi))
        if long_way is not None:  # the relative turn δ the other way round: δ − 2π sign δ
            delta = angle[level] + 2.0 * np.pi * k - np.einsum("ti,ti->t", P, a)
            marked = np.asarray(long_way[parent[level], level]).ravel() != 0
            k = k - np.where(marked, np.where(delta >= 0.0, 1.0, -1.0), 0.0)
        out[level] = (angle[level] + 2.0 * np.pi * k)[:, None] * a
    return out


def fold_crossings(source: FloatArray, target: FloatArray, triangles: IntArray
                   ) -> sp.csr_matrix:
    """The pairs of neighbouring triangles (a symmetric (T, T) matrix, nonzero on them)
    whose dihedral angle, turned the short way from ``source`` to ``target``, passes the
    fold (±π: one triangle laid on the other); turned the long way it passes flat."""
    F = np.asarray(triangles, np.int64)
    D, holders = diamonds_and_triangles(F)
    theta0 = dihedral_angles(source, D)
    crossing = np.abs(theta0 + wrap(dihedral_angles(target, D) - theta0)) > np.pi
    t1, t2 = holders[crossing].T
    return sp.csr_matrix((np.ones(2 * len(t1)), (np.r_[t1, t2], np.r_[t2, t1])),
                         shape=(len(F), len(F)))


def arap_interpolation(source: FloatArray, target: FloatArray, triangles: IntArray,
                       times, *, iterations: int = 0,
                       until: Callable[[list], bool] | None = None,
                       long_way: bool = False) -> list:
    """The frames of the as-rigid-as-possible interpolation at ``times`` (module
    docstring); ``source`` at ``t = 0`` and ``target`` at ``t = 1`` exactly.

    Parameters
    ----------
    source, target : (N, 3) float arrays, every vertex in some triangle
    triangles : (T, 3) int array, no degenerate triangle in ``source``
    times : sequence of floats in [0, 1]
    iterations : local/global steps at most (module docstring), taken by every frame
        strictly inside together (none that would leave a degenerate triangle, where the
        closed-form rotation is undefined); 0 returns Alexa et al.'s fit
    until : called with the frames (all of them, new arrays after each step) before each
        step; True ends the steps, so the frames are the fewest steps' it accepts (or all
        ``iterations``')
    long_way : turn each pair of neighbours whose dihedral angle's short way passes the
        fold (:func:`fold_crossings`) the long way round, through flat: the least turned
        triangle stays on its branch, those beyond such a pair take the other
        (:func:`continuous_rotation_vectors`)
    """
    V0, V1 = np.asarray(source, float), np.asarray(target, float)
    F = np.asarray(triangles, np.int64)
    Rg = fit_similarity(V0, V1, scaling=False).rotation
    global_vec = Rotation.from_matrix(Rg).as_rotvec()
    A = _frames(V1[F]) @ np.linalg.inv(_frames(V0[F]))
    R, S = _polar(np.swapaxes(Rg, 0, 1)[None] @ A)
    if long_way:  # rooted at the least turned in all, so that no piece whirls round
        local_vec = continuous_rotation_vectors(
            Rotation.from_matrix(R).as_rotvec(), V0, F, long_way=fold_crossings(V0, V1, F),
            turned=Rotation.from_matrix(Rg[None] @ R).magnitude())
    else:
        local_vec = continuous_rotation_vectors(Rotation.from_matrix(R).as_rotvec(), V0, F)
    fit = _Fit(V0, F)
    A0 = fit.distortion.affine_maps(V0)  # (T, 3, 2)
    c0, c1 = fit.centroids(V0), fit.centroids(V1)
    out, inside = [], []  # the frames; per frame strictly inside (index, M(t), centroid)
    for t in times:
        t = float(t)
        if t in (0.0, 1.0):
            out.append((V0 if t == 0.0 else V1).copy())
            continue
        M = ((1.0 - t) * np.eye(3) + t * S) @ A0  # (T, 3, 2): the interpolated stretch
        Rt = (Rotation.from_rotvec(t * global_vec).as_matrix()[None]
              @ Rotation.from_rotvec(t * local_vec).as_matrix())
        centroid = (1.0 - t) * c0 + t * c1
        inside.append((len(out), _plane_frames(M)[2], centroid))
        out.append(fit(Rt @ M, centroid))
    for _ in range(iterations):
        if until is not None and until(out):
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            stepped = [fit(_best_rotated(fit.distortion.affine_maps(out[k]), m), centroid)
                       for k, m, centroid in inside]
        if not all(np.isfinite(X).all() for X in stepped):
            break  # a frame's triangle degenerated: keep the last frames
        for (k, _, _), X in zip(inside, stepped):
            out[k] = X
    return out
