"""A local polish of the worst tets of a moved mesh: the last step of the tet motion
(:mod:`.move`).

Around the ``worst`` tets of lowest mean ratio ``η`` (their vertices and ``rings`` rings
of neighbours, the fixed vertices excluded), it minimizes the soft maximum of the inverse
mean ratios ``q = 1/η = Σℓ² / (12 (3V)^{2/3})`` of the tets these vertices touch,

    F = (1/s) log Σ_e exp(s q_e),

by L-BFGS whose backtracking line search refuses every trial with an inverted tet (``F``
is ``+inf`` there): every accepted iterate has every tet positively oriented, and the
result is kept only where its worst mean ratio is higher (it is not tried where the worst tet
has only fixed corners). With ``clear`` (a motion's contact, :mod:`.contact`) a trial
is also refused where the straight path to it passes through contact (CCD).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._typing import FloatArray, IntArray
from ...descent import minimize_lbfgs
from ...kernels.cell_maps import scatter_corners
from ...kernels.tetrahedra import mean_ratios
from ..engine.polish import cell_neighbourhood, soft_maximum

_I, _J = np.triu_indices(4, 1)


def inverse_mean_ratios(points: FloatArray, tets: IntArray) -> tuple[FloatArray, FloatArray]:
    """``q = Σℓ² / (12 (3V)^{2/3}) = 1/η`` per tet (C,) and its gradient in the corners
    (C, 4, 3); ``q = inf`` (gradient 0) where ``V ≤ 0``."""
    p = np.asarray(points, float)[tets]
    D = np.swapaxes(p[:, 1:] - p[:, :1], 1, 2)
    cof = np.stack([np.cross(D[:, :, 1], D[:, :, 2]), np.cross(D[:, :, 2], D[:, :, 0]),
                    np.cross(D[:, :, 0], D[:, :, 1])], axis=1)  # rows: ∂det/∂(x_1, x_2, x_3)
    det = np.einsum("ci,ci->c", cof[:, 0], D[:, :, 0])
    ok = det > 0
    safe = np.where(ok, det, 1.0)
    e = p[:, _I] - p[:, _J]
    sq = np.einsum("cek,cek->c", e, e)
    den = 12.0 * (safe / 2.0) ** (2.0 / 3.0)  # 12 (3V)^{2/3} with V = det/6
    q = np.where(ok, sq / den, np.inf)
    dsq = 2.0 * (4.0 * p - p.sum(axis=1, keepdims=True))  # ∂Σℓ²/∂x_a = 2(4x_a − Σ_b x_b)
    ddet = np.empty_like(p)
    ddet[:, 1:] = cof
    ddet[:, 0] = -cof.sum(axis=1)
    grad = dsq / den[:, None, None] - (2.0 / 3.0) * (np.where(ok, q, 0.0) / safe
                                                     )[:, None, None] * ddet
    grad[~ok] = 0.0
    return q, grad


@dataclass
class _SoftMax:
    """``F`` over ``tets`` with the vertices outside ``free`` fixed: value and gradient over
    the free vertices (``inf`` and ``None`` where a tet is inverted)."""

    tets: IntArray
    n_vertices: int
    free: IntArray
    sharpness: float

    def __call__(self, x: FloatArray):
        q, g = inverse_mean_ratios(x, self.tets)
        if not np.isfinite(q).all():
            return np.inf, None
        value, gq = soft_maximum(q, g, self.sharpness)
        return value, scatter_corners(self.tets, gq, self.n_vertices)[self.free].ravel()


def fixed_ceiling(points: FloatArray, tets: IntArray, fixed: IntArray) -> float:
    """The lowest mean ratio of the tets whose four corners are all ``fixed`` (``inf``
    where there are none): no motion of the other vertices raises the worst mean ratio
    above it."""
    is_fixed = np.zeros(len(points), bool)
    is_fixed[np.asarray(fixed, dtype=np.int64)] = True
    pinned = is_fixed[tets].all(axis=1)
    return float(mean_ratios(points, tets[pinned]).min()) if pinned.any() else np.inf


def polish_worst_tets(points: FloatArray, tets: IntArray, fixed: IntArray, *,
                      worst: int = 300, rings: int = 3, iterations: int = 300,
                      sharpness: float = 1.0, clear=None) -> tuple[FloatArray, dict]:
    """Raise the worst mean ratio of a positively oriented tet mesh by moving the vertices
    near its worst tets (the ``fixed`` vertices kept bitwise).

    Parameters
    ----------
    points, tets : (N, 3) float and (C, 4) int arrays
        Every tet positively oriented.
    fixed : (k,) int array
        Vertices that do not move.
    worst : int
        How many of the lowest-``η`` tets seed the neighbourhood.
    rings : int
        Rings of neighbouring vertices added around them.
    iterations : int
        L-BFGS iterations.
    sharpness : float
        ``s`` of the soft maximum (``s → ∞``: the worst tet alone).
    clear : callable ``(Q0, Q1) -> bool``, optional
        Whether the straight step between two configurations is free of contact
        (:meth:`..engine.contact.ContactTerm.clear`); every accepted trial is, from the last
        iterate.

    Returns
    -------
    points : (N, 3) float array
        The polished points, or ``points`` itself where the polish did not raise min η.
    info : dict
        ``polish_vertices`` (how many moved freely), ``polish_min_mean_ratio`` (before,
        after).
    """
    P = np.asarray(points, float)
    T = np.asarray(tets)
    eta = mean_ratios(P, T)
    before = float(eta.min())
    movable = cell_neighbourhood(T, np.argsort(eta)[:worst], rings, len(P))
    movable[np.asarray(fixed, dtype=np.int64)] = False
    free = np.flatnonzero(movable)
    info = {"polish_vertices": int(len(free)), "polish_min_mean_ratio": [before, before]}
    if len(free) == 0 or iterations <= 0 or before >= fixed_ceiling(P, T, fixed):
        return P, info  # (the worst tet has only fixed corners: nothing to gain)
    active = movable[T].any(axis=1)
    energy = _SoftMax(T[active], len(P), free, float(sharpness))

    def at(u: FloatArray) -> FloatArray:
        x = P.copy()
        x[free] = u.reshape(-1, 3)
        return x

    def objective(u: FloatArray):
        return energy(at(u))

    last = [P[free].ravel()]  # the last accepted iterate: the start of the next trials

    def admissible(u: FloatArray) -> bool:
        if not clear(at(last[0]), at(u)):
            return False
        last[0] = u
        return True

    out = P.copy()
    out[free] = minimize_lbfgs(objective, P[free].ravel(), iterations, first_step=1e-3,
                               min_step=1e-12, curvature=1e-16,
                               admissible=None if clear is None else admissible
                               ).reshape(-1, 3)
    after = float(mean_ratios(out, T).min())
    if not after > before:
        return P, info
    info["polish_min_mean_ratio"] = [before, after]
    return out, info
