"""Handle paths for moving triangle surfaces in R³: the similarity part of each group of
handles (Umeyama's fit) followed along its screw motion — about the similarity's own axis
line, so a group turned about a hinge moves along the arc — and the rest of the motion
linearly; the
fold test of a surface against its rest shape.

A group is a connected piece of the handles (through mesh edges between handles). Where
one similarity maps all handles onto their targets (to rounding), the whole surface can
follow it exactly (:func:`global_similarity`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

from .._typing import FloatArray, IntArray


@dataclass(frozen=True)
class Similarity3:
    """``x ↦ s R (x − c) + d``, with two paths from the identity: :meth:`at` (the centroid
    along the chord) and :meth:`screw` (about the similarity's own axis line)."""

    scale: float
    rotation: FloatArray  # (3, 3), det +1
    centre: FloatArray  # (3,)
    image: FloatArray  # (3,)

    def __call__(self, x: FloatArray) -> FloatArray:
        return self.scale * (np.asarray(x) - self.centre) @ self.rotation.T + self.image

    def at(self, t: float) -> "Similarity3":
        """The similarity at fraction ``t`` of its path of least mass-weighted motion from
        the identity: the centroid along the chord, the rotation in angle about its axis,
        the scale geometrically (t = 1: itself)."""
        if t == 1.0:
            return self
        rotvec = Rotation.from_matrix(self.rotation).as_rotvec()
        R = Rotation.from_rotvec(t * rotvec).as_matrix()
        return Similarity3(self.scale**t, R, self.centre,
                           self.centre + t * (self.image - self.centre))

    def screw(self, t: float) -> "Similarity3":
        """The similarity at fraction ``t`` of its screw (spiral) motion
        ``p + s^t R^t (x − p)`` plus the shift along the axis, about the axis line through
        ``p`` it turns about: a turn about a hinge moves along the arc, not the chord
        (t = 1: itself; ``screw(a)`` after ``screw(b)`` is ``screw(a + b)``)."""
        if t == 1.0:
            return self
        rotvec = Rotation.from_matrix(self.rotation).as_rotvec()
        R = Rotation.from_rotvec(t * rotvec).as_matrix()
        q, u, v_u = self._axis(rotvec)
        log_s = float(np.log(self.scale))
        # the shift along the axis under the scale: v_u (s^t − 1)/(s − 1), → t v_u at s = 1
        along = t if abs(log_s) < 1e-12 else np.expm1(t * log_s) / np.expm1(log_s)
        return Similarity3(self.scale**t, R, self.centre,
                           self.centre + q - self.scale**t * (R @ q) + along * v_u * u)

    def _axis(self, rotvec: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        """``(p − c, u, v·u)``: the point of the axis line nearest the centre ``c``
        (relative to it), the unit axis ``u`` (0 without a turn) and the shift ``v = d − c``
        along it; ``(0, v/|v|, |v|)``, the chord, where the similarity is within 1e-6 of a
        translation."""
        v = self.image - self.centre
        angle = float(np.linalg.norm(rotvec))
        if abs(1.0 - self.scale * np.exp(1j * angle)) < 1e-6:
            size = float(np.linalg.norm(v))
            return np.zeros(3), (v / size if size > 0 else np.zeros(3)), size
        u = rotvec / angle if angle > 0 else np.zeros(3)
        v_u = float(v @ u)
        # (I − sR) maps the plane normal to u onto itself, invertibly: |1 − s e^{iθ}| > 0
        uu = np.outer(u, u)
        K = (np.eye(3) - self.scale * self.rotation) @ (np.eye(3) - uu) + uu
        return np.linalg.solve(K, v - v_u * u), u, v_u


def fit_similarity(source: FloatArray, target: FloatArray, scaling: bool = True
                   ) -> Similarity3:
    """Least-squares similarity (rotation with det +1, optional uniform scale) mapping
    ``source`` onto ``target`` (Umeyama 1991)."""
    a, b = np.asarray(source, float), np.asarray(target, float)
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    x, y = a - ca, b - cb
    U, sigma, Vt = np.linalg.svd(y.T @ x)
    d = np.ones(3)
    d[2] = 1.0 if np.linalg.det(U @ Vt) >= 0 else -1.0
    R = (U * d) @ Vt
    var = float(np.sum(x * x))
    s = float(sigma @ d) / var if scaling and var > 0 else 1.0
    if not s > 0:
        s = 1.0
    return Similarity3(s, R, ca, cb)


def handle_groups(triangles: IntArray, handles: IntArray, n_vertices: int) -> IntArray:
    """A label per handle (0, 1, …): its connected piece through mesh edges between
    handles."""
    F = np.asarray(triangles)
    is_handle = np.zeros(n_vertices, bool)
    is_handle[handles] = True
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E = E[is_handle[E].all(axis=1)]
    local = np.full(n_vertices, -1)
    local[handles] = np.arange(len(handles))
    n = len(handles)
    A = sp.coo_matrix((np.ones(len(E)), (local[E[:, 0]], local[E[:, 1]])), shape=(n, n))
    return connected_components(A, directed=False)[1]


class HandlePath:
    """Positions of the handles at fraction ``t`` of their motion from ``start`` to
    ``targets``: per group its similarity path plus ``t`` times what the similarity leaves
    (so exactly ``targets`` at t = 1)."""

    def __init__(self, start: FloatArray, targets: FloatArray, groups: IntArray,
                 scaling: bool = True) -> None:
        self.start = np.asarray(start, float)
        self.targets = np.asarray(targets, float)
        self.groups = np.asarray(groups)
        self.similarities = []
        self.rest = np.empty_like(self.start)
        for g in range(int(self.groups.max()) + 1 if len(self.groups) else 0):
            m = self.groups == g
            # a single vertex or a collinear piece has no rotation of its own
            if _rank(self.start[m]) < 2:
                S = Similarity3(1.0, np.eye(3), self.start[m].mean(0), self.targets[m].mean(0))
            else:
                S = fit_similarity(self.start[m], self.targets[m], scaling)
            self.similarities.append(S)
            self.rest[m] = self.targets[m] - S(self.start[m])

    def __call__(self, t: float) -> FloatArray:
        if t >= 1.0:
            return self.targets.copy()
        out = np.empty_like(self.start)
        for g, S in enumerate(self.similarities):
            m = self.groups == g
            out[m] = S.screw(t)(self.start[m]) + t * self.rest[m]
        return out


def _rank(points: FloatArray) -> int:
    if len(points) < 2:
        return 0
    x = points - points.mean(axis=0)
    s = np.linalg.svd(x, compute_uv=False)
    return int(np.sum(s > 1e-9 * max(s[0], 1e-300)))


def global_similarity(start: FloatArray, targets: FloatArray, diameter: float,
                      rtol: float = 1e-10) -> Similarity3 | None:
    """The similarity mapping every handle onto its target within ``rtol·diameter``, or
    None (none does, or the handles span less than a plane)."""
    if _rank(start) < 2:
        return None
    S = fit_similarity(start, targets)
    if np.abs(S(start) - targets).max() <= rtol * diameter:
        return S
    return None


def best_rotations(S: FloatArray) -> FloatArray:
    """Rotations R (det +1) maximizing tr(R S) for covariances ``S = Σ e eᵀ'`` (T, 3, 3).

    With ``S = U Σ Vᵀ`` (σ_a ≥ σ_b ≥ σ_c) the optimum maps ``u_a ↦ v_a``, ``u_b ↦ v_b`` and,
    being a rotation, ``u_a × u_b ↦ v_a × v_b`` (Kabsch's ``V diag(1, 1, ±1) Uᵀ`` without the
    determinant). ``v_a, v_b`` are the top eigenvectors of the symmetric ``SᵀS`` (one
    batched ``eigh``, faster than the SVD), ``u_a, u_b`` the normalized ``S v_a`` and ``S v_b``
    (Gram–Schmidt), so ``σ_c`` may vanish (coplanar rest edges). Where ``σ_b = 0`` the
    optimum is not unique and ``u_b`` is completed to any unit vector normal to ``u_a``.
    """
    _, W = np.linalg.eigh(np.swapaxes(S, 1, 2) @ S)  # ascending eigenvalues
    va, vb = W[:, :, 2], W[:, :, 1]
    ua = _unit(np.einsum("tij,tj->ti", S, va), np.eye(3)[0])
    ub = np.einsum("tij,tj->ti", S, vb)
    ub -= np.einsum("ti,ti->t", ua, ub)[:, None] * ua
    # where S has rank ≤ 1: any unit vector normal to u_a (the axis of u_a's least component)
    fallback = np.cross(ua, np.eye(3)[np.argmin(np.abs(ua), axis=1)])
    ub = _unit(ub, fallback, scale=np.linalg.norm(S.reshape(len(S), 9), axis=1))
    return (va[:, :, None] * ua[:, None, :] + vb[:, :, None] * ub[:, None, :]
            + np.cross(va, vb)[:, :, None] * np.cross(ua, ub)[:, None, :])


def _unit(x: FloatArray, fallback: FloatArray, scale: FloatArray | None = None) -> FloatArray:
    """Rows of ``x`` normalized; those of norm ≤ 1e-12·scale (or 0) replaced by ``fallback``
    (normalized)."""
    n = np.linalg.norm(x, axis=1)
    tiny = n <= (0.0 if scale is None else 1e-12 * scale)
    if np.any(tiny):
        fb = np.broadcast_to(fallback, x.shape)[tiny]
        x = x.copy()
        x[tiny] = fb
        n = n.copy()
        n[tiny] = np.linalg.norm(fb, axis=1)
    return x / n[:, None]


class FoldTest:
    """Triangle t folds when its normal turns against its rest normal carried by the best
    rotation of its neighbourhood, ``n_t' · (R_t n_t) < 0``; ``R_t`` the Kabsch rotation of
    the rest edge vectors of the one-ring fans of t's corners onto their new ones."""

    def __init__(self, rest: FloatArray, triangles: IntArray) -> None:
        self.rest = np.asarray(rest, float)
        self.triangles = np.asarray(triangles)
        F = self.triangles
        E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        E = np.sort(E, axis=1)
        n = len(self.rest)
        key = np.unique(E[:, 0] * n + E[:, 1])  # each edge once, as one integer key
        self.edges = np.stack(np.divmod(key, n), axis=1)
        self.rest_edges = self.rest[self.edges[:, 1]] - self.rest[self.edges[:, 0]]
        P = self.rest[F]
        self.rest_normals = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])

    def vertex_covariances(self, A: FloatArray, B: FloatArray) -> FloatArray:
        """``Σ a bᵀ`` over the edges at each vertex, ``a`` the edge vector in ``A`` and ``b``
        in ``B`` (N, 9); ``A = None``: the rest shape's."""
        a = self.rest_edges if A is None else A[self.edges[:, 1]] - A[self.edges[:, 0]]
        b = B[self.edges[:, 1]] - B[self.edges[:, 0]]
        outer = (a[:, :, None] * b[:, None, :]).reshape(-1, 9)
        n = len(B)
        return np.stack([np.bincount(self.edges[:, 0], outer[:, c], n)
                         + np.bincount(self.edges[:, 1], outer[:, c], n) for c in range(9)], 1)

    def vertex_rotations(self, A: FloatArray, B: FloatArray) -> FloatArray:
        """The Kabsch rotations (N, 3, 3) of each vertex's edge vectors in ``A`` onto
        those in ``B``."""
        return best_rotations(self.vertex_covariances(A, B).reshape(-1, 3, 3))

    def mask(self, Q: FloatArray) -> np.ndarray:
        """Folded triangles of ``Q`` (T,) bool."""
        Sv = self.vertex_covariances(None, Q)
        R = best_rotations(Sv[self.triangles].sum(axis=1).reshape(-1, 3, 3))
        carried = np.einsum("tij,tj->ti", R, self.rest_normals)
        P = Q[self.triangles]
        normals = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        return np.einsum("ti,ti->t", normals, carried) < 0
