"""Measures of a deformed triangle surface against its rest shape, shared by
``bench_surface.py`` and its tests.

* quality: the aspect ratio 2r/R of each triangle (inradius over half the circumradius;
  1 for an equilateral triangle, 0 for a degenerate one), divided by its rest value; the
  worst relative quality is taken over the triangles that are not wholly handles.
* folds: triangle t folds when its new normal turns against its rest normal carried by
  the best rotation of its neighbourhood, ``n_t' · (R_t n_t) < 0``. R_t is the Kabsch
  rotation (uniform weights) that best maps the rest edge vectors of the one-ring fans of
  t's three corners onto their new edge vectors.
* ARAP energy (Sorkine & Alexa 2007, "spokes"): ``Σ_i Σ_{j∈N(i)} w_ij |e_ij' − R_i e_ij|²``
  over directed edges, ``e_ij = p_j − p_i``, w_ij = ½(cot α_ij + cot β_ij) at rest clamped
  at 0 (obtuse triangles make raw cotangent weights negative, and the energy indefinite:
  negative on real scanned/decimated meshes), R_i the per-vertex rotation fitted (Kabsch,
  weights w_ij) to the fan of vertex i. ``clamp=False`` gives the raw cotangent energy
  that libigl's ARAP ("spokes") minimizes.

Everything is vectorized over triangles, edges and vertices; rotations come from one
batched ``np.linalg.svd``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def aspect_ratios(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Aspect ratio 2r/R of every triangle of a surface in 3D (or the plane).

    Parameters
    ----------
    V : (n, 3) or (n, 2) float array
    F : (m, 3) int array

    Returns
    -------
    (m,) float array in [0, 1]: 16 A² / ((a + b + c) a b c), 1 for equilateral triangles.
    """
    P = np.asarray(V, float)[F]
    if P.shape[-1] == 2:
        P = np.concatenate([P, np.zeros(P.shape[:-1] + (1,))], -1)
    a = np.linalg.norm(P[:, 1] - P[:, 2], axis=1)
    b = np.linalg.norm(P[:, 2] - P[:, 0], axis=1)
    c = np.linalg.norm(P[:, 0] - P[:, 1], axis=1)
    area2 = np.sum(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]) ** 2, axis=1) / 4.0
    denom = (a + b + c) * a * b * c
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(denom > 0, 16.0 * area2 / denom, 0.0)
    return np.clip(q, 0.0, 1.0)


def relative_quality(V0: np.ndarray, V1: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Aspect ratio of every triangle in ``V1`` divided by its rest value in ``V0``."""
    q0 = aspect_ratios(V0, F)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(q0 > 0, aspect_ratios(V1, F) / q0, 0.0)


def free_triangles(F: np.ndarray, handles: np.ndarray, n_vertices: int) -> np.ndarray:
    """Boolean mask of the triangles with at least one corner that is not a handle."""
    is_handle = np.zeros(n_vertices, bool)
    is_handle[np.asarray(handles, int)] = True
    return ~is_handle[F].all(axis=1)


def worst_relative_quality(V0, V1, F, handles) -> float:
    """Minimum relative aspect ratio over the triangles not wholly made of handles."""
    free = free_triangles(F, handles, len(V0))
    rq = relative_quality(V0, V1, F)[free]
    return float(rq.min()) if rq.size else 1.0


def _edges(F: np.ndarray) -> np.ndarray:
    """Unique undirected edges (k, 2) of a triangle list."""
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return np.unique(np.sort(E, axis=1), axis=0)


def cotangent_weights(V: np.ndarray, F: np.ndarray):
    """Undirected edges and their weights ½(cot α + cot β) (one term on boundary edges).

    Returns
    -------
    E : (k, 2) int array, W : (k,) float array
    """
    P = np.asarray(V, float)[F]
    n = len(V)
    rows, cols, vals = [], [], []
    for k in range(3):  # the angle at corner k faces the edge (k+1, k+2)
        i, j = (k + 1) % 3, (k + 2) % 3
        u, v = P[:, i] - P[:, k], P[:, j] - P[:, k]
        cot = np.sum(u * v, axis=1) / np.linalg.norm(np.cross(u, v), axis=1)
        rows.append(np.minimum(F[:, i], F[:, j]))
        cols.append(np.maximum(F[:, i], F[:, j]))
        vals.append(0.5 * cot)
    C = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsr()
    C.sum_duplicates()
    E = _edges(F)
    return E, np.asarray(C[E[:, 0], E[:, 1]]).ravel()


def best_rotations(S: np.ndarray) -> np.ndarray:
    """Rotations R (det +1) maximizing tr(R S) for a batch of 3×3 covariances
    ``S = Σ w e eᵀ'`` (rest edges times new edges transposed): R = V diag(1, 1, ±1) Uᵀ."""
    U, _, Vt = np.linalg.svd(S)
    D = np.ones(S.shape[:-1])
    D[:, -1] = np.sign(np.linalg.det(np.swapaxes(Vt, 1, 2) @ np.swapaxes(U, 1, 2)))
    D[D[:, -1] == 0, -1] = 1.0
    return np.swapaxes(Vt, 1, 2) @ (D[:, :, None] * np.swapaxes(U, 1, 2))


def _vertex_covariances(V0, V1, E, W) -> np.ndarray:
    """Per vertex Σ_{j∈N(i)} w_ij e_ij e_ij'ᵀ over the undirected edges E with weights W
    (both directions give the same outer product, so each edge adds to both ends)."""
    e0 = V0[E[:, 1]] - V0[E[:, 0]]
    e1 = V1[E[:, 1]] - V1[E[:, 0]]
    outer = (W[:, None, None] * e0[:, :, None] * e1[:, None, :]).reshape(len(E), 9)
    S = np.zeros((len(V0), 9))
    np.add.at(S, E[:, 0], outer)
    np.add.at(S, E[:, 1], outer)
    return S.reshape(-1, 3, 3)


def normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unnormalized triangle normals (twice the area vector)."""
    P = np.asarray(V, float)[F]
    return np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])


def fold_mask(V0: np.ndarray, V1: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Triangles whose new normal points against their rest normal carried by the
    Kabsch rotation of the one-ring fans of their three corners (see module docstring)."""
    V0, V1 = np.asarray(V0, float), np.asarray(V1, float)
    E = _edges(F)
    Sv = _vertex_covariances(V0, V1, E, np.ones(len(E)))
    R = best_rotations(Sv[F].sum(axis=1))
    carried = np.einsum("tij,tj->ti", R, normals(V0, F))
    return np.sum(normals(V1, F) * carried, axis=1) < 0


def fold_count(V0, V1, F, handles=None) -> int:
    """Number of folded triangles (among those not wholly handles when ``handles`` given)."""
    m = fold_mask(V0, V1, F)
    if handles is not None:
        m &= free_triangles(F, handles, len(V0))
    return int(m.sum())


def _arap_terms(V0: np.ndarray, V1: np.ndarray, F: np.ndarray, clamp: bool):
    """The edges E (k, 2), their weights W, the per-vertex rotations R and the squared
    residuals of the directed edges i→j and j→i of each undirected edge (k,) each."""
    V0, V1 = np.asarray(V0, float), np.asarray(V1, float)
    E, W = cotangent_weights(V0, F)
    if clamp:
        W = np.maximum(W, 0.0)
    R = best_rotations(_vertex_covariances(V0, V1, E, W))
    e0 = V0[E[:, 1]] - V0[E[:, 0]]
    e1 = V1[E[:, 1]] - V1[E[:, 0]]
    # directed edge i→j uses R_i, j→i uses R_j (the sign of e flips on both sides)
    ri = e1 - np.einsum("kij,kj->ki", R[E[:, 0]], e0)
    rj = e1 - np.einsum("kij,kj->ki", R[E[:, 1]], e0)
    return E, W, R, np.sum(ri * ri, axis=1), np.sum(rj * rj, axis=1)


def arap_energy(V0: np.ndarray, V1: np.ndarray, F: np.ndarray, *, clamp: bool = True,
                return_rotations: bool = False):
    """As-rigid-as-possible energy of ``V1`` against the rest shape ``V0`` (module
    docstring): per-vertex best rotations with the cotangent weights of the rest mesh,
    clamped at 0 unless ``clamp=False``."""
    _, W, R, si, sj = _arap_terms(V0, V1, F, clamp)
    energy = float(np.sum(W * (si + sj)))
    return (energy, R) if return_rotations else energy


def arap_vertex_energy(V0: np.ndarray, V1: np.ndarray, F: np.ndarray, *,
                       clamp: bool = True) -> np.ndarray:
    """Each vertex's share of :func:`arap_energy` (n,): ``Σ_{j∈N(i)} w_ij |e'_ij − R_i
    e_ij|²``, the terms of the directed edges leaving vertex i (the shares sum to the
    energy)."""
    E, W, _, si, sj = _arap_terms(V0, V1, F, clamp)
    out = np.zeros(len(V0))
    np.add.at(out, E[:, 0], W * si)
    np.add.at(out, E[:, 1], W * sj)
    return out


def self_intersecting_faces(V: np.ndarray, F: np.ndarray) -> int:
    """How many triangles pymeshlab's test selects as intersecting another
    (``compute_selection_by_self_intersections_per_face``); -1 where pymeshlab is absent."""
    try:
        import pymeshlab
    except ImportError:
        return -1
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(V, float),
                               face_matrix=np.asarray(F, np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    return int(ms.current_mesh().selected_face_number())


def rigid_pose_faces(V: np.ndarray, F: np.ndarray, poses: int = 4, seed: int = 0) -> int:
    """The most faces :func:`self_intersecting_faces` selects on ``(V, F)`` turned rigidly
    by ``poses`` random rotations (seeded): 0 where pymeshlab's test can be trusted on this
    mesh. Its test of two triangles that share one vertex intersects, in floating point,
    the midsegment of one with the other; on a smooth surface (nearly coplanar
    neighbours) a rigid turn alone makes it select faces of a clean surface."""
    from scipy.spatial.transform import Rotation

    turns = Rotation.random(poses, random_state=seed).as_matrix()
    return max(self_intersecting_faces(np.asarray(V, float) @ R.T, F) for R in turns)
