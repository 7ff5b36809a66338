"""A local polish of the worst triangles of a moved surface: the last step of the surface
motion (:mod:`.move`).

Around the ``worst`` triangles of lowest relative quality ``q_t/q̄_t`` (aspect ratio 2r/R
over its rest value; their vertices and ``rings`` rings of neighbours, the handles
excluded), it minimizes the soft maximum of the inverse relative qualities of the
triangles these vertices touch,

    F = (1/s) log Σ_t exp(s r_t),    r_t = q̄_t / q_t = q̄_t (ℓ_0+ℓ_1+ℓ_2) ℓ_0 ℓ_1 ℓ_2 / (4 |n_t|²),

(``n_t`` the triangle's normal of length twice its area), plus ``μ`` times the
area-weighted mean ``|φ_t|²`` of their membrane distortion (the neighbourhood stays where
the motion put it), by L-BFGS over tangential displacements: each free vertex moves in the
plane through its start position orthogonal to its area-weighted normal there, so the
surface keeps its shape to first order. A pass starts from the moved points at the sharper
of the given ``s`` and ``focus`` over the gap between the worst and the median ``r_t`` (where
most triangles are nearly as good as the worst, a fixed ``s`` spreads the descent over all
of them). It ends where the budget below refuses its steps: a second, from its result with
``μ`` doubled (the planes those of the moved points), follows the budget's bound further,
kept where the worst rises. The line search refuses every trial with a degenerate triangle (``F = +inf``), a new fold
(:class:`.folds.FoldTest` against the rest surface, evaluated on the triangles
whose corners' fans the free vertices touch) or a rise of the surface's membrane energy
``Σ_t a_t |φ_t|²`` (``a_t`` the rest areas) by more than ``max_energy_rise`` of itself: a
nearly isometric motion is not traded for a sliver of quality. The result is kept only
where the worst relative quality of the triangles not wholly handles rises. A surface whose
worst relative quality is 1 to rounding (a similarity of the rest) is left as it is.
"""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray, IntArray
from ...descent import minimize_lbfgs
from ...kernels.cell_maps import scatter_corners
from ...kernels.surface import area_vectors, aspect_ratios
from ...kernels.surface import areas as triangle_areas
from ..engine.polish import cell_neighbourhood, soft_maximum
from .distortion import SurfaceDistortion
from .folds import FoldTest

#: a worst relative quality this close to 1 is left alone: every triangle is at rest to
#: rounding (a similarity), and trading shape for rounding-level gains would only cost energy
_AT_REST = 1e-9


#: each corner's next and the one after (cyclic)
_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a × b`` over the last axis (broadcast; the products of ``np.cross``, cheaper)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def inverse_qualities(points: FloatArray, triangles: IntArray) -> tuple[FloatArray, FloatArray]:
    """``1/q = (ℓ_0+ℓ_1+ℓ_2) ℓ_0 ℓ_1 ℓ_2 / (4|n|²)`` per triangle (T,) (``q`` the aspect ratio
    2r/R) and its gradient in the corners (T, 3, 3); ``inf`` (gradient 0) where ``|n| = 0``."""
    p = np.asarray(points, float)[triangles]
    e = p[:, _AFTER] - p[:, _NEXT]  # e_i = p_{i+2} − p_{i+1}, opposite i
    ell = np.linalg.norm(e, axis=2)
    n = _cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    nn = np.einsum("ti,ti->t", n, n)
    ok = (nn > 0) & (ell > 0).all(axis=1)
    safe_nn = np.where(ok, nn, 1.0)
    safe_ell = np.where(ok[:, None], ell, 1.0)
    perimeter = safe_ell.sum(axis=1)
    r = np.where(ok, perimeter * safe_ell.prod(axis=1) / (4.0 * safe_nn), np.inf)
    # ∂ log(1/q): Σ_i (1/P + 1/ℓ_i) ∂ℓ_i − ∂ log|n|², with ∂ℓ_i/∂p_{i+2} = −∂ℓ_i/∂p_{i+1}
    # = e_i/ℓ_i and ∂|n|²/∂p_i = 2 n × e_i
    u = ((1.0 / perimeter[:, None] + 1.0 / safe_ell) / safe_ell)[:, :, None] * e
    dlog = u[:, _NEXT] - u[:, _AFTER]  # corner j: u_{j+1} − u_{j+2}
    dlog -= 2.0 * _cross(n[:, None, :], e) / safe_nn[:, None, None]
    grad = np.where(ok, r, 0.0)[:, None, None] * dlog
    return r, grad


class SoftMaxObjective:
    """``F + μ Σ_t a_t |φ_t|² / Σ_t a_t`` over ``triangles`` (rest qualities ``rest``,
    membrane distortion ``membrane`` with rest areas ``areas``, ``μ = shape``) as a function
    of the tangential coordinates ``u`` (k, 2) of the ``free`` vertices: ``x = start +
    basis u`` at them, ``start`` elsewhere. Calling it gives ``(value, ∂/∂u)``, ``(inf,
    None)`` where a triangle is degenerate."""

    def __init__(self, start: FloatArray, triangles: IntArray, rest: FloatArray,
                 free: IntArray, basis: FloatArray, sharpness: float,
                 membrane: SurfaceDistortion, areas: FloatArray, shape: float) -> None:
        self.start, self.triangles, self.rest = start, triangles, rest
        self.free, self.basis, self.sharpness = free, basis, float(sharpness)
        self.membrane, self.shape = membrane, float(shape)
        # the term is ½ Σ_t (2μ a_t / Σa) |φ_t|²
        self.area_weights = 2.0 * self.shape * areas / areas.sum()
        self._last: tuple = (None, None)  # (u, φ) of the last call: the line search's trial

    def membrane_values(self, u: FloatArray) -> FloatArray:
        """``φ`` (T, 3) of the triangles at ``u``: the last call's where it was at ``u``."""
        last_u, phi = self._last
        if last_u is not None and np.array_equal(last_u, u):
            return phi
        return self.membrane.values(self.points(u))

    def points(self, u: FloatArray) -> FloatArray:
        """The positions at tangential coordinates ``u`` (k, 2)."""
        x = self.start.copy()
        x[self.free] += np.einsum("kij,kj->ki", self.basis, np.reshape(u, (-1, 2)))
        return x

    def __call__(self, u: FloatArray):
        x = self.points(u)
        r, g = inverse_qualities(x, self.triangles)
        if not np.isfinite(r).all():
            return np.inf, None
        value, g = soft_maximum(self.rest * r, self.rest[:, None, None] * g, self.sharpness)
        if self.shape > 0:
            phi, J = self.membrane.values_and_jacobian(x)
            self._last = (np.array(u, copy=True), phi)
            value += 0.5 * float(self.area_weights @ np.einsum("ti,ti->t", phi, phi))
            g = g + np.einsum("t,ti,tij->tj", self.area_weights, phi, J).reshape(-1, 3, 3)
        G = scatter_corners(self.triangles, g, len(self.start))
        dU = np.einsum("kij,ki->kj", self.basis, G[self.free])
        return float(value), dU.reshape(np.shape(u))


def _tangent_bases(points: FloatArray, triangles: IntArray, vertices: IntArray) -> FloatArray:
    """Orthonormal (k, 3, 2) bases of the planes orthogonal to the area-weighted vertex
    normals at ``vertices`` (zero where the normal vanishes: the vertex stays)."""
    n = area_vectors(points, triangles)
    N = scatter_corners(triangles, np.repeat(n[:, None, :], 3, axis=1), len(points))[vertices]
    size = np.linalg.norm(N, axis=1)
    N = N / np.where(size > 0, size, 1.0)[:, None]
    # the full SVD of each normal's row: its last two right singular vectors span the plane
    B = np.swapaxes(np.linalg.svd(N[:, None, :])[2][:, 1:, :], 1, 2)
    return np.where((size > 0)[:, None, None], B, 0.0)


def _descend(V: FloatArray, F: IntArray, P: FloatArray, is_handle, rest_q: FloatArray,
             rel: FloatArray, areas: FloatArray, energy: FloatArray, limit: float,
             worst: int, rings: int, iterations: int, sharpness: float, focus: float,
             shape: float, clear=None, planes: FloatArray | None = None
             ) -> FloatArray | None:
    """One L-BFGS pass of :func:`polish_worst_triangles` from ``P`` (relative qualities
    ``rel``, ``inf`` where not counted; membrane energies ``energy`` per triangle, their sum
    at most ``limit``) at the sharper of ``sharpness`` and ``focus`` over the gap, each
    vertex in its tangent plane at ``planes`` (None: ``P``): the moved points, or None where
    nothing can move."""
    seeds = np.argsort(rel)[:min(worst, int(np.isfinite(rel).sum()))]
    movable = cell_neighbourhood(F, seeds, rings, len(P)) & ~is_handle
    free = np.flatnonzero(movable)
    if len(free) == 0:
        return None
    active = movable[F].any(axis=1)  # the triangles whose shape the polish changes
    if focus > 0:
        with np.errstate(divide="ignore"):  # a degenerate triangle: 1/q = inf, no gap
            inverse = 1.0 / rel[active]
        gap = inverse.max() - np.median(inverse)
        if np.isfinite(gap) and gap > 0 and focus > sharpness * gap:
            sharpness = focus / gap
    objective = SoftMaxObjective(P, F[active], rest_q[active], free,
                                 _tangent_bases(P if planes is None else planes, F, free),
                                 sharpness,
                                 SurfaceDistortion(V, F[active]), areas[active], shape)
    # a triangle's fold test reads the fans of its corners: those that can change are the
    # triangles with a corner on or next to a free vertex; their corners' fans make the
    # submesh on which the test is the whole mesh's
    touched = movable.copy()
    touched[F[active]] = True
    watched = touched[F].any(axis=1)
    corners = np.zeros(len(P), bool)
    corners[F[watched]] = True
    sub = np.flatnonzero(corners[F].any(axis=1))
    # the submesh's vertices numbered in order (the test's sums over them, not all of P)
    local = np.zeros(len(P), bool)
    local[F[sub]] = True
    local = np.flatnonzero(local)
    number = np.zeros(len(P), np.int64)
    number[local] = np.arange(len(local))
    folds = FoldTest(V[local], number[F[sub]])
    check = watched[sub]
    folded = folds.mask(P[local]) & check
    # the whole surface's membrane energy Σ a_t|φ_t|² stays within ``limit``: only the
    # active triangles' part changes
    budget = limit - float(energy[~active].sum())

    def admissible(u: FloatArray) -> bool:  # the membrane energy within budget, no new fold
        phi = objective.membrane_values(u)
        if float(areas[active] @ np.sum(phi**2, axis=1)) > budget:
            return False
        x = objective.points(u)
        if np.any(folds.mask(x[local]) & check & ~folded):
            return False
        return clear is None or clear(P, x)

    # the pass stops where no step above a thousandth of the quasi-Newton one is admissible
    # and lowers F: the soft maximum has stalled (on the budget, a fold or its minimum)
    edges = np.linalg.norm(P[F[active]] - np.roll(P[F[active]], 1, axis=1), axis=2)
    u = minimize_lbfgs(objective, np.zeros(2 * len(free)), int(iterations),
                       first_step=1e-2 * float(edges.mean()), admissible=admissible,
                       min_step=1e-3)
    out = objective.points(u)
    out[is_handle] = P[is_handle]
    return out


def polish_worst_triangles(rest: FloatArray, triangles: IntArray, points: FloatArray,
                           handles: IntArray, *, worst: int = 400, rings: int = 5,
                           iterations: int = 100, sharpness: float = 200.0,
                           focus: float = 20.0,
                           shape: float = 10.0, max_energy_rise: float = 0.02,
                           clear=None) -> tuple[FloatArray, dict]:
    """Raise the worst relative quality of a moved surface by tangential moves of the
    vertices near its worst triangles (the ``handles`` kept bitwise; module docstring).

    Parameters
    ----------
    rest : (N, 3) float array
        Rest positions (no degenerate triangle).
    triangles : (T, 3) int array
    points : (N, 3) float array
        The moved positions: no degenerate triangle among those not wholly handles.
    handles : (H,) int array
        Vertices that do not move.
    worst : int
        How many of the lowest relative quality triangles seed the neighbourhood.
    rings : int
        Rings of neighbouring vertices added around them.
    iterations : int
        L-BFGS iterations.
    sharpness, focus : float
        ``s`` of the soft maximum (``s → ∞``: the worst triangle alone), or where that is
        sharper, ``focus`` over the gap between the worst and the median inverse relative
        quality of the triangles moved (where most are nearly as good as the worst, a fixed
        ``s`` spreads the descent over all of them); 0: ``s``.
    shape : float
        ``μ``, the weight of the area-weighted mean squared membrane distortion
        (:class:`.distortion.SurfaceDistortion`) of the triangles moved, against
        the soft maximum (0: the soft maximum alone); the second pass's is ``2μ``.
    max_energy_rise : float
        The largest relative rise of the whole surface's area-weighted membrane energy
        that a trial may cost (a constraint of the line search).
    clear : callable ``(P0, P1) -> bool``, optional
        Whether the straight path from a pass's start to a trial is free of contact
        (:mod:`..engine.contact`: a constraint of the line search; None: none).

    Returns
    -------
    points : (N, 3) float array
        The polished points, or ``points`` itself where the polish did not raise the worst
        relative quality or where it is 1 to rounding.
    info : dict
        ``polish_vertices`` (how many moved; 0 where ``points`` is returned),
        ``polish_worst_quality`` (before, after).
    """
    V = np.asarray(rest, float)
    F = np.asarray(triangles, np.int64)
    P = np.asarray(points, float)
    is_handle = np.zeros(len(P), bool)
    is_handle[np.asarray(handles, np.int64)] = True
    counted = ~is_handle[F].all(axis=1)  # the triangles whose quality is measured
    rest_q = aspect_ratios(V, F)
    rel = np.where(counted, aspect_ratios(P, F) / rest_q, np.inf)
    before = float(rel.min()) if counted.any() else 1.0
    info = {"polish_vertices": 0, "polish_worst_quality": [before, before]}
    if iterations <= 0 or not counted.any() or abs(before - 1.0) <= _AT_REST:
        return P, info  # nothing to do, or the worst triangle at rest to rounding
    areas = triangle_areas(V, F)
    membrane = SurfaceDistortion(V, F)
    energy = areas * np.sum(membrane.values(P) ** 2, axis=1)
    limit = (1.0 + max_energy_rise) * float(energy.sum())
    out, after = P, before

    def better(start, start_rel, start_energy, mu):  # the pass's, where higher
        moved = _descend(V, F, start, is_handle, rest_q, start_rel, areas, start_energy,
                         limit, worst, rings, iterations, sharpness, focus, mu, clear, P)
        if moved is None:
            return out, after
        quality = float((aspect_ratios(moved, F)[counted] / rest_q[counted]).min())
        return (moved, quality) if quality > after else (out, after)

    out, after = better(P, rel, energy, shape)
    # a pass ends where the energy budget refuses its steps: a second from its result, μ
    # doubled, follows the budget's bound further (the limit and planes stay those of P)
    if after > before:
        start = out
        out, after = better(start, np.where(counted, aspect_ratios(start, F) / rest_q, np.inf),
                            areas * np.sum(membrane.values(start) ** 2, axis=1), 2.0 * shape)
    if not after > before:
        return P, info
    info["polish_vertices"] = int(np.any(out != P, axis=1).sum())
    info["polish_worst_quality"] = [before, after]
    return out, info
