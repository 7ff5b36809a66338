"""Augmentation (penalty) functions f1 and f2 with exact derivatives (SPEC §3).

Both penalties are sums of independent *terms*, each evaluated vectorized over all
triangles, all boundary pairs or all nodes:

``f1`` (5.16)/(5.18), :class:`HeightPenalty`, ``alpha = (α1, α2, α3)``::

    f1(Q) = Σ_k Σ_l α1 / h_l(k) + Σ_pairs χ(α2 / D^μ) + (α3/2) ‖Q − Qref‖²_F

``f2`` (5.22)/(5.33), :class:`QualityPenalty`, ``beta = (β1, β2, β3, β4)``::

    f2(Q) = (β1/T) Σ_k 1/ψ_k + β2 / Σ_k A_k
            + β3/(#E∂ #V∂) Σ_pairs χ(1 / D^μ) + β4/(2N) ‖Q − Qref‖²_F

``χ`` is the identity unless a cut-off ``(s_lo, s_hi)`` is given (remarks 5.2.10, 5.3.4),
see :func:`cutoff`.

Per-triangle terms are quotients ``N/A`` of a numerator ``N`` (``S = ΣE_l²`` for f2,
perimeter ``L = ΣE_l`` for f1, since ``Σ_l 1/h_l = L/(2A)``) by the signed area ``A``.
``S`` and ``A`` are quadratic forms in the six local coordinates, so the gradient, the
Hessian-vector product and the curvature ``V·∇²f·V`` all follow in closed form from the
quotient rule; nothing of size ``(T, 6, 6)`` is ever formed. The total area
``Σ_k A_k = ½ Σ_{(a,b)∈E∂} q_a × q_b`` (shoelace formula over the boundary) depends on
the boundary nodes only. The boundary-pair term uses
:func:`meshopt_toolkit.distance.regularized_distance`. The regularized distance is C2
(its ``h_μ`` has a jump in the third derivative at 0; see ``distance``), which is all the
geodesic equation needs.

Every method takes node positions ``Q`` of shape ``(N, 2)``. ``value`` returns ``+inf``
(never NaN) at a non-admissible ``Q`` (a signed area ≤ 0, a non-finite coordinate, or
boundary edges that touch, cross or fold onto each other, i.e. a boundary vertex on or
through a non-incident boundary edge); the derivatives raise
:class:`~meshopt_toolkit.errors.NotAdmissibleError` there, naming the triangle or edges.

Notes
-----
- ``β4`` is given unscaled and divided by ``2N`` as in SPEC §3 (the text of (5.33) prints
  ``β4/2``); ``α3`` is used as ``α3/2``.
- ``μ`` (default :data:`DEFAULT_MU` = ``distance.DEFAULT_MU``) has units of 1/length: the
  smoothing zone of ``D^μ`` is ``1/(2μ)`` wide, so choose ``μ`` of the order of the
  inverse mesh width for fine meshes.
- The per-triangle pass runs over blocks of :data:`BLOCK` triangles (temporaries stay in
  cache; a loop over blocks, vectorized inside) and scatters the per-corner vectors to
  the nodes with one sparse matvec per component.
- :meth:`Penalty.gradient_and_curvature` returns ``∇f`` and the scalar ``V·∇²f·V``
  without forming ``∇²f V`` (the geodesic ODE's right-hand side, SPEC §5).
"""

from __future__ import annotations

import hashlib
import logging
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from . import distance as _distance
from ._linalg import dot as _dot
from ._typing import FloatArray, IntArray
from .errors import InvalidMeshError, NotAdmissibleError
from .mesh import PlanarMesh, TriangleMesh, boundary_self_intersections

logger = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_MU",
    "HeightPenalty",
    "Penalty",
    "QualityPenalty",
    "cutoff",
]

SQRT3 = np.sqrt(3.0)
_OMEGA = np.exp(2j * np.pi / 3 * np.arange(3))  # ω^k, k = 0, 1, 2
_I_SQRT3_2 = 0.5j * SQRT3  # p = z0 − (z1 + z2)/2 + (i√3/2)(z1 − z2), m with −i√3/2

#: default μ of the regularized distance (defined with the distance kernels)
DEFAULT_MU = _distance.DEFAULT_MU

#: boundary configurations remembered as simple by each penalty
SIMPLE_BOUNDARY_CACHE = 64

#: triangles per block of the per-triangle pass (keeps temporaries in cache)
BLOCK = 8192

#: boundary pairs evaluated at once (their derivatives take ~250 bytes per pair)
PAIR_CHUNK = 250_000

#: without a cut-off, the all-pairs list is cached when it has at most this many rows
#: (24 bytes per pair); larger sets are regenerated chunk by chunk on every call
PAIR_CACHE = 2_000_000


# ---------------------------------------------------------------------------------------
# the C3 cut-off χ
# ---------------------------------------------------------------------------------------


def _smoothstep7(t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """C3 smoothstep ``σ(t) = 35t⁴ − 84t⁵ + 70t⁶ − 20t⁷`` on [0, 1] (clamped outside).

    ``σ(0) = 0``, ``σ(1) = 1`` and ``σ', σ'', σ'''`` vanish at both ends. Returns
    ``(σ, σ', σ'')``.
    """
    t = np.clip(t, 0.0, 1.0)
    t2 = t * t
    t3 = t2 * t
    s = t3 * t * (35.0 + t * (-84.0 + t * (70.0 - 20.0 * t)))
    ds = t3 * (140.0 + t * (-420.0 + t * (420.0 - 140.0 * t)))
    d2s = t2 * (420.0 + t * (-1680.0 + t * (2100.0 - 840.0 * t)))
    return s, ds, d2s


def cutoff(s: FloatArray, s_lo: float, s_hi: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The C3 cut-off ``χ(s) = s σ((s − s_lo)/(s_hi − s_lo))`` and its derivatives.

    ``χ = 0`` for ``s ≤ s_lo`` and ``χ = s`` for ``s ≥ s_hi`` (remarks 5.2.10, 5.3.4);
    ``σ`` is the degree-7 smoothstep whose first three derivatives vanish at 0 and 1, so
    ``χ`` is C3 at both breakpoints (``χ'''`` involves σ', σ'', σ''' only, all zero
    there). For ``s ≥ 0``, ``0 ≤ χ(s) ≤ s`` and ``χ' ≥ 0``.

    Parameters
    ----------
    s : (K,) float array
    s_lo, s_hi : float, ``0 ≤ s_lo < s_hi``

    Returns
    -------
    (χ, χ', χ'') : three (K,) arrays
    """
    w = s_hi - s_lo
    sig, dsig, d2sig = _smoothstep7((s - s_lo) / w)
    chi = s * sig
    dchi = sig + s * dsig / w
    d2chi = 2.0 * dsig / w + s * d2sig / (w * w)
    return chi, dchi, d2chi


def _check_cutoff(cut) -> tuple[float, float] | None:
    if cut is None:
        return None
    try:
        lo, hi = (float(c) for c in cut)
    except (TypeError, ValueError):
        raise ValueError(f"cutoff must be a pair (s_lo, s_hi), got {cut!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo < hi):
        raise ValueError(f"cutoff needs 0 <= s_lo < s_hi, got ({lo}, {hi})")
    return lo, hi


# ---------------------------------------------------------------------------------------
# evaluation state
# ---------------------------------------------------------------------------------------


@dataclass
class _Want:
    """What to compute in one pass (``value=False``: the caller ignores the value, which
    terms may then skip)."""

    gradient: bool = False
    hvp: bool = False
    curvature: bool = False
    value: bool = True


class _Accumulator:
    """Collects the term contributions of one evaluation."""

    def __init__(self, n: int, want: _Want) -> None:
        self.want = want
        self.values: dict[str, float] = {}
        self.grad = np.zeros((n, 2)) if want.gradient else None
        self.hvp = np.zeros((n, 2)) if want.hvp else None
        self.curvature = 0.0


def _edges(qx: FloatArray, qy: FloatArray, tri_t: IntArray) -> tuple[FloatArray, FloatArray]:
    """Edge vectors of triangles ``tri_t (3, b)`` at coordinates ``qx, qy (N,)``.

    Component-major ``(3, b)`` x and y arrays: row ``l`` is edge ``l``,
    ``e_l = q_{i(l+2)} − q_{i(l+1)}`` (opposite vertex ``l``).
    """
    x = np.take(qx, tri_t)
    y = np.take(qy, tri_t)
    ex = np.empty_like(x)
    ey = np.empty_like(y)
    for k, (a, b) in enumerate(((2, 1), (0, 2), (1, 0))):  # 3 local edges, not triangles
        np.subtract(x[a], x[b], out=ex[k])
        np.subtract(y[a], y[b], out=ey[k])
    return ex, ey


def _re_dot(a: np.ndarray, b: np.ndarray, scale: float = 1.0) -> FloatArray:
    """``scale · Re(a · conj b)`` elementwise for complex arrays (one temporary)."""
    out = a.real * b.real
    out += a.imag * b.imag
    if scale != 1.0:
        out *= scale
    return out


def _area(ex: FloatArray, ey: FloatArray) -> FloatArray:
    """Signed areas ``A = ½ det[e2, e0]`` (e2 = q1 − q0, e0 = q2 − q1), (4.2). ``(b,)``."""
    return 0.5 * (ex[2] * ey[0] - ey[2] * ex[0])


_NEXT = [1, 2, 0]
_PREV = [2, 0, 1]


def _to_vertices(phi_x, phi_y, psi_x, psi_y, out_x: FloatArray, out_y: FloatArray) -> None:
    """Write vertex vectors ``Φ_{m+1} − Φ_{m+2} + ½ R Ψ_m`` into ``out_x, out_y (3, b)``.

    ``Φ`` is an edge-space field (a derivative w.r.t. the edge vectors ``e_l``; vertex
    ``m`` is the head of edge ``m+1`` and the tail of edge ``m+2``), ``Ψ`` a field whose
    quarter-turn ``R(a, b) = (−b, a)`` enters as in ``∇_m A = ½ R e_m``. ``psi_x`` and
    ``psi_y`` are overwritten.
    """
    for m in range(3):  # the 3 local vertices
        np.subtract(phi_x[_NEXT[m]], phi_x[_PREV[m]], out=out_x[m])
        np.subtract(phi_y[_NEXT[m]], phi_y[_PREV[m]], out=out_y[m])
    psi_x *= 0.5
    psi_y *= 0.5
    out_x -= psi_y
    out_y += psi_x


# ---------------------------------------------------------------------------------------
# terms
# ---------------------------------------------------------------------------------------


class _TriangleQuotientTerm:
    """``c Σ_k N_k / A_k`` with ``N = S = ΣE_l²`` ("quality") or ``N = L = ΣE_l`` ("height").

    With ``n1 = N'[V]``, ``n2 = N''[V, V]`` and likewise ``a1``, ``a2`` for the area, the
    quotient rule gives the curvature
    ``(N/A)'' = n2/A − 2 n1 a1/A² − N a2/A² + 2 N a1²/A³`` and the Hessian-vector product
    ``H_N V/A − (∇N a1 + ∇A n1)/A² − N H_A V/A² + 2 N a1 ∇A/A³``, where
    ``∇_m A = ½ R e_m``, ``H_A V = ½ R w_m``, ``a2 = 2A(w)`` (``w = e(V)``) and, per edge,
    ``∂S/∂e = 2e``, ``S' = 2Σ e·w``, ``S'' = 2Σ|w|²``, ``H_S: w ↦ 2w``;
    ``∂L/∂e = u = e/E``, ``L' = Σ u·w``, ``L'' = Σ (|w|² − (u·w)²)/E``,
    ``H_L: w ↦ (w − u (u·w))/E``. Evaluated block by block
    (see :meth:`Penalty._triangle_pass`).
    """

    def __init__(self, name: str, kind: str, coef: float) -> None:
        self.name = name
        self.quality = kind == "quality"
        self.coef = float(coef)

    def block(self, ex, ey, A, wx, wy, want: _Want, gout, hout) -> tuple[float, float]:
        """One block of triangles: ``(value, curvature)``; vertex vectors of the gradient
        and the hvp are written into ``gout``/``hout`` = ``(x (3, b), y (3, b))``."""
        c = self.coef
        sq = ex * ex
        sq += ey * ey
        if self.quality:
            N = sq[0] + sq[1] + sq[2]
            iE = None
        else:
            E = np.sqrt(sq)
            N = E[0] + E[1] + E[2]
            iE = 1.0 / E
        inv_a = 1.0 / A
        ratio = N * inv_a  # N / A
        value = c * float(ratio.sum())
        curvature = 0.0
        cinv = c * inv_a
        if gout is not None:
            # ∇(N/A) = ∇N/A − (N/A²) ∇A :  Φ = (c/A) ∂N/∂e,  Ψ = −(c N/A²) e
            f = 2.0 * cinv if iE is None else cinv * iE
            r = -(cinv * ratio)
            _to_vertices(f * ex, f * ey, r * ex, r * ey, *gout)
        if wx is None:
            return value, curvature
        ew = ex * wx
        ew += ey * wy  # e_l · w_l
        if iE is None:
            n1 = 2.0 * (ew[0] + ew[1] + ew[2])
        else:
            fw = ew * iE  # u_l · w_l
            n1 = fw[0] + fw[1] + fw[2]
        a1 = 0.5 * (wx[2] * ey[0] + ex[2] * wy[0] - wy[2] * ex[0] - ey[2] * wx[0])
        a1_a = a1 * inv_a
        if want.curvature:  # second directional derivatives n2 = N''[V, V], a2 = 2 A(V)
            ww = wx * wx
            ww += wy * wy
            if iE is None:
                n2 = 2.0 * (ww[0] + ww[1] + ww[2])
            else:
                t = (ww - fw * fw) * iE
                n2 = t[0] + t[1] + t[2]
            a2 = wx[2] * wy[0] - wy[2] * wx[0]
            curv = inv_a * (n2 - 2.0 * n1 * a1_a - ratio * a2 + 2.0 * ratio * a1_a * a1)
            curvature = c * float(curv.sum())
        if hout is not None:
            # edge part Φ = (c/A)(H_N w − ∂N/∂e a1/A) = g (w − e h)
            if iE is None:
                g, h = 2.0 * cinv, a1_a
            else:
                g, h = cinv * iE, fw * iE + a1_a
            phi_x = wx - ex * h
            phi_x *= g
            phi_y = wy - ey * h
            phi_y *= g
            # rotation part Ψ = (c/A²) [e (2N a1/A − n1) − w N]
            r = cinv * inv_a
            ce = r * (2.0 * N * a1_a - n1)
            cw = -r * N
            psi_x = ce * ex
            psi_x += cw * wx
            psi_y = ce * ey
            psi_y += cw * wy
            _to_vertices(phi_x, phi_y, psi_x, psi_y, *hout)
        return value, curvature


class _TotalAreaTerm:
    """``β2 / 𝒜`` with ``𝒜 = Σ_k A_k = ½ Σ_{(a,b)∈E∂} q_a × q_b`` (5.22).

    Only boundary nodes enter (work and memory are O(#E∂), not O(N)); ``𝒜`` is a
    quadratic form, so ``H_𝒜 V = ∇𝒜(V)``, ``𝒜'' = 2𝒜(V)`` and
    ``(β2/𝒜)'' = β2 (2𝒜'²/𝒜³ − 𝒜''/𝒜²)``.
    """

    name = "area"

    def __init__(self, coef: float, boundary_edges: IntArray, boundary_vertices: IntArray) -> None:
        self.coef = float(coef)
        self.nodes = boundary_vertices  # sorted
        self.a = np.searchsorted(boundary_vertices, boundary_edges[:, 0])
        self.b = np.searchsorted(boundary_vertices, boundary_edges[:, 1])

    def _grad_total(self, qa: FloatArray, qb: FloatArray) -> FloatArray:
        """∇𝒜 on the boundary nodes ``(B, 2)``: ``∂/∂q_a (q_a × q_b) = (y_b, −x_b)``,
        ``∂/∂q_b = (−y_a, x_a)``."""
        n = len(self.nodes)
        gx = np.bincount(self.a, qb[:, 1], n) - np.bincount(self.b, qa[:, 1], n)
        gy = np.bincount(self.b, qa[:, 0], n) - np.bincount(self.a, qb[:, 0], n)
        return 0.5 * np.stack([gx, gy], axis=1)

    def evaluate(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> None:
        if self.name in acc.values:  # done by the small-mesh pass (Penalty._small_pass)
            return
        c = self.coef
        q = Q[self.nodes]
        qa, qb = q[self.a], q[self.b]
        tot = 0.5 * float(np.sum(qa[:, 0] * qb[:, 1] - qa[:, 1] * qb[:, 0]))
        acc.values[self.name] = c / tot
        want = acc.want
        if not (want.gradient or want.hvp or want.curvature):
            return
        grad_tot = self._grad_total(qa, qb)
        if want.gradient:
            acc.grad[self.nodes] += (-c / tot**2) * grad_tot
        if want.hvp or want.curvature:
            v = V[self.nodes]
            d1 = _dot(grad_tot, v)
            hv = self._grad_total(v[self.a], v[self.b])  # H_𝒜 V
            d2 = _dot(hv, v)
            if want.curvature:
                acc.curvature += c * (2.0 * d1 * d1 / tot**3 - d2 / tot**2)
            if want.hvp:
                acc.hvp[self.nodes] += (-c / tot**2) * hv + (2.0 * c * d1 / tot**3) * grad_tot


class _ReferenceTerm:
    """``(c/2) ‖Q − Qref‖²_F``; ``c = α3`` (f1) or ``β4/N`` (f2)."""

    name = "reference"

    def __init__(self, coef: float, reference: FloatArray) -> None:
        self.coef = float(coef)
        self.reference = reference

    def evaluate(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> None:
        c = self.coef
        d = Q - self.reference
        want = acc.want
        acc.values[self.name] = 0.5 * c * _dot(d, d) if want.value else np.nan
        if want.gradient:
            acc.grad += c * d
        if want.hvp:
            acc.hvp += c * V
        if want.curvature:
            acc.curvature += c * _dot(V, V)


class _BoundaryTerm:
    """``c Σ_pairs χ(w / D^μ)`` over boundary pairs ``(i0; [j0, j1])``, ``i0 ∉ {j0, j1}``.

    With ``s = w/D``: ``s' = −w D'/D²``, ``s'' = w (2D'²/D³ − D''/D²)``; with χ:
    ``χ(s)'' = χ''(s) s'² + χ'(s) s''``. Without a cut-off all pairs are visited in chunks
    (the list is cached when it has at most :data:`PAIR_CACHE` rows); with one, only the pairs whose
    summand can exceed ``s_lo`` are found by a radius search around the current ``Q``:
    ``χ(w/D^μ) > 0`` needs ``D^μ < w/s_lo``, and ``D^μ ≥ D − 1/(2μ)`` and ``D ≥`` the
    Euclidean vertex–segment distance, so radius ``w/s_lo + 1/(2μ)`` finds them all.
    """

    name = "boundary"

    def __init__(
        self,
        coef: float,
        weight: float,
        mu: float,
        cut: tuple[float, float] | None,
        boundary_vertices: IntArray,
        boundary_edges: IntArray,
    ) -> None:
        self.coef = float(coef)
        self.weight = float(weight)
        self.mu = float(mu)
        self.cut = cut
        self.bv = boundary_vertices
        self.be = boundary_edges
        self._all_pairs: IntArray | None = None
        n_pairs = len(boundary_vertices) * len(boundary_edges)
        if cut is None and n_pairs <= PAIR_CACHE:
            self._all_pairs = _distance.boundary_pairs(boundary_vertices, boundary_edges)

    def pair_chunks(self, Q: FloatArray):
        """Iterator over the ``(k, 3)`` pair arrays to visit at ``Q``."""
        if self.cut is not None:
            s_lo = self.cut[0]
            if s_lo <= 0.0:
                radius = None
            else:
                radius = self.weight / s_lo + 0.5 / self.mu
            pairs = _distance.boundary_pairs(self.bv, self.be, points=Q, radius=radius)
        else:
            pairs = self._all_pairs
        if pairs is not None:
            for start in range(0, len(pairs), PAIR_CHUNK):
                yield pairs[start : start + PAIR_CHUNK]
        else:
            yield from _distance.iter_boundary_pairs(self.bv, self.be, chunk=PAIR_CHUNK)

    def evaluate(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> None:
        want = acc.want
        derivs = want.gradient or want.hvp or want.curvature
        total = 0.0
        n = len(Q)
        c, w = self.coef, self.weight
        for pairs in self.pair_chunks(Q):
            if len(pairs) and derivs and self.cut is not None:
                # only pairs with χ > 0 carry derivatives: s = w/D^μ > s_lo
                Dv = _distance.regularized_distance_value(Q, pairs, self.mu)
                pairs = pairs[Dv * self.cut[0] < w]
            if len(pairs) == 0:
                continue
            if not derivs:
                D = _distance.regularized_distance_value(Q, pairs, self.mu)
                with np.errstate(divide="ignore"):
                    s = w / D
                if self.cut is not None:
                    s = cutoff(s, *self.cut)[0]
                total += float(s.sum())
                continue
            ev = _distance.regularized_distance(
                Q, pairs, self.mu, direction=V if (want.hvp or want.curvature) else None
            )
            D = ev.value
            inv = 1.0 / D
            s = w * inv
            ds_dD = -s * inv  # ds/dD = −w/D²
            if self.cut is None:
                chi, dchi, d2chi = s, None, None
                g1 = ds_dD  # dχ/dD
            else:
                chi, dchi, d2chi = cutoff(s, *self.cut)
                g1 = dchi * ds_dD
            total += float(chi.sum())
            if want.gradient:
                G = (c * g1)[:, None, None] * ev.gradient  # (k, 3, 2)
                _scatter_pairs(acc.grad, pairs, G, n)
            if want.hvp or want.curvature:
                vloc = V[pairs]  # (k, 3, 2)
                D1 = np.einsum("kij,kij->k", ev.gradient, vloc)
                d2s_dD2 = 2.0 * s * inv * inv  # d²s/dD² = 2w/D³
                # d²χ/dD² = χ''(s) (ds/dD)² + χ'(s) d²s/dD²
                g2 = d2s_dD2 if self.cut is None else d2chi * ds_dD * ds_dD + dchi * d2s_dD2
                if want.curvature:
                    acc.curvature += c * float(np.sum(g2 * D1 * D1 + g1 * ev.curvature))
                if want.hvp:
                    H = (c * g2 * D1)[:, None, None] * ev.gradient + (c * g1)[
                        :, None, None
                    ] * ev.hess_dir
                    _scatter_pairs(acc.hvp, pairs, H, n)
        acc.values[self.name] = c * total


def _scatter_pairs(out: FloatArray, pairs: IntArray, G: FloatArray, n: int) -> None:
    """Add per-pair local vectors ``G (k, 3, 2)`` into ``out (N, 2)`` at ``pairs (k, 3)``."""
    idx = pairs.ravel()
    out[:, 0] += np.bincount(idx, G[..., 0].ravel(), n)
    out[:, 1] += np.bincount(idx, G[..., 1].ravel(), n)


# ---------------------------------------------------------------------------------------
# the penalties
# ---------------------------------------------------------------------------------------


class Penalty:
    """Common machinery of :class:`HeightPenalty` and :class:`QualityPenalty`.

    Subclasses build their terms in ``__init__``; connectivity-derived index arrays are
    computed once and cached in the instance. ``Q`` and ``V`` are ``(N, 2)`` arrays.
    """

    #: declared for the integrators: every evaluation raises ``NotAdmissibleError`` at a
    #: non-positive signed area, and ``mesh`` and the boundary are available
    checks_areas = True

    def __init__(self, mesh: TriangleMesh, mu: float, cutoff, reference) -> None:
        if not isinstance(mesh, TriangleMesh):
            raise TypeError(f"mesh must be a PlanarMesh, got {type(mesh).__name__}")
        mesh = mesh.as_planar()
        self.mesh: PlanarMesh = mesh
        self.mu = float(mu)
        if not (np.isfinite(self.mu) and self.mu > 0):
            raise ValueError(f"mu must be positive, got {mu!r}")
        self.cutoff = _check_cutoff(cutoff)
        n = mesh.n_vertices
        self.n_vertices = n
        self.n_triangles = mesh.n_triangles
        self._tri = mesh.triangles
        self._tri_t = np.ascontiguousarray(mesh.triangles.T.astype(np.intp))
        self._tri_flat = self._tri_t.ravel()
        # contiguous (3, b) blocks: gathers through a contiguous index are ~2x faster
        self._blocks = [
            (s, np.ascontiguousarray(self._tri_t[:, s : s + BLOCK]))
            for s in range(0, len(self._tri), BLOCK)
        ]
        self._boundary_edges = np.ascontiguousarray(mesh.boundary_edges.astype(np.intp))
        self._boundary_vertices = np.ascontiguousarray(mesh.boundary_vertices.astype(np.intp))
        # consecutive boundary edges (a, b), (b, c) for the fold test in is_admissible
        be = self._boundary_edges
        order = np.argsort(be[:, 0], kind="stable")
        pos = np.searchsorted(be[order, 0], be[:, 1])
        pos = np.clip(pos, 0, max(len(be) - 1, 0))
        nxt = order[pos] if len(be) else pos
        ok = be[nxt, 0] == be[:, 1] if len(be) else np.zeros(0, bool)
        self._fold = (be[ok, 0], be[ok, 1], be[nxt[ok], 1])
        # digests of boundary positions already found simple (see _boundary_problem)
        self._simple_boundaries: OrderedDict[bytes, None] = OrderedDict()
        if reference is None:
            ref = np.array(mesh.points, dtype=np.float64)
        else:
            ref = np.array(getattr(reference, "points", reference), dtype=np.float64)
            if ref.shape != (n, 2):
                raise InvalidMeshError(f"reference has shape {ref.shape}, expected {(n, 2)}")
        ref.setflags(write=False)
        self.reference = ref
        self._triangle_term: _TriangleQuotientTerm | None = None
        self._other_terms: list = []
        self._area_term: _TotalAreaTerm | None = None  # (the small pass evaluates it)
        self._scatter_csc = None
        # small meshes (one block): complex-arithmetic pass, see _small_pass
        self._small = len(self._blocks) == 1
        if self._small:
            tt = self._tri_t
            self._edge_head = np.ascontiguousarray(tt[[2, 0, 1]])  # e_l = q_head − q_tail
            self._edge_tail = np.ascontiguousarray(tt[[1, 2, 0]])
            flat2 = 2 * self._tri_flat
            self._corner_xy = np.stack([flat2, flat2 + 1], axis=1).ravel()
            # discrete Fourier coordinates of each triangle (see _small_quality_pass):
            # rows t: p_t = Σ_k ω^k z_{i_k}; rows T + t: m_t = Σ_k ω^{2k} z_{i_k}
            T = self.n_triangles
            rows = np.concatenate([np.tile(np.arange(T), 3), np.tile(np.arange(T, 2 * T), 3)])
            cols = np.concatenate([self._tri_flat, self._tri_flat])
            vals = np.concatenate([np.repeat(_OMEGA, T), np.repeat(_OMEGA**2, T)])
            W = sp.csr_matrix((vals, (rows, cols)), shape=(2 * T, n))
            self._fourier_adjoint = W.conj().T.tocsr()  # (N, 2T): the gradient's scatter

    # -- helpers ------------------------------------------------------------------
    @property
    def _gather_matrix(self):
        """``(N, 3T)`` sparse 0/1 matrix summing per-corner vectors into their nodes.

        Column ``j`` of the flattened ``(3, T)`` corner layout has its single 1 in row
        ``tri_t.ravel()[j]``: in CSC form it costs nothing to build, and its matvec is a
        C scatter-add (about twice as fast as ``np.bincount`` here).
        """
        if self._scatter_csc is None:
            flat = self._tri_flat
            m = flat.size
            idx = np.int32 if max(m, self.n_vertices) < 2**31 - 1 else np.int64
            self._scatter_csc = sp.csc_matrix(
                (np.ones(m), flat.astype(idx), np.arange(m + 1, dtype=idx)),
                shape=(self.n_vertices, m),
            )
        return self._scatter_csc

    def _scatter(self, out: FloatArray, buf: FloatArray) -> None:
        """Add per-corner vectors ``buf (2, 3, T)`` (x, y) into ``out (N, 2)``."""
        M = self._gather_matrix
        out[:, 0] += M @ buf[0].ravel()
        out[:, 1] += M @ buf[1].ravel()

    def _points(self, Q, what: str = "Q") -> FloatArray:
        q = np.ascontiguousarray(Q, dtype=np.float64)
        if q.shape != (self.n_vertices, 2):
            raise ValueError(f"{what} must have shape {(self.n_vertices, 2)}, got {q.shape}")
        return q

    def _area_problem(self, Q: FloatArray) -> str | None:
        """A message naming a non-finite vertex or a non-positive triangle, or None."""
        if not np.isfinite(Q).all():
            v = int(np.flatnonzero(~np.isfinite(Q).all(axis=1))[0])
            return f"vertex {v} has a non-finite coordinate"
        with np.errstate(all="ignore"):
            area = _area(*_edges(Q[:, 0], Q[:, 1], self._tri_t))
        bad = np.flatnonzero(~(area > 0))
        if not bad.size:
            return None
        k = int(bad[0])
        kind = "zero-area" if area[k] == 0 else "inverted"
        more = f" ({bad.size} non-positive triangles)" if bad.size > 1 else ""
        return f"triangle {k} {self._tri[k].tolist()} is {kind} (signed area {area[k]:.3g}){more}"

    def _boundary_problem(self, Q: FloatArray) -> str | None:
        """A message naming boundary edges that fold onto, touch or cross each other.

        The test depends on the boundary positions only; the 128-bit digests of the last
        :data:`SIMPLE_BOUNDARY_CACHE` boundaries found simple are remembered, so iterative
        methods that come back to the same configurations (the morph's path energy
        evaluates value, gradient and Hessian products at each frame; half its penalty
        time was this test) pay for it once per configuration.
        """
        key = hashlib.blake2b(Q[self._boundary_vertices].tobytes(), digest_size=16).digest()
        if key in self._simple_boundaries:
            try:
                self._simple_boundaries.move_to_end(key)
            except KeyError:  # evicted meanwhile by another thread: still simple
                pass
            return None
        problem = self._boundary_test(Q)
        if problem is None:
            self._simple_boundaries[key] = None
            if len(self._simple_boundaries) > SIMPLE_BOUNDARY_CACHE:
                self._simple_boundaries.popitem(last=False)
        return problem

    def _boundary_test(self, Q: FloatArray) -> str | None:
        a, b, c = self._fold
        if len(a):
            u = Q[a] - Q[b]
            v = Q[c] - Q[b]
            cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
            dot = np.einsum("kd,kd->k", u, v)
            folded = np.flatnonzero((cross == 0) & (dot > 0))
            if folded.size:
                i = folded[0]
                return (
                    f"boundary folds onto itself at vertex {b[i]}: edges ({a[i]}, {b[i]}) and "
                    f"({b[i]}, {c[i]}) overlap"
                )
        hits = boundary_self_intersections(Q, self._boundary_edges)
        if len(hits):
            e1 = self._boundary_edges[hits[0, 0]]
            e2 = self._boundary_edges[hits[0, 1]]
            return (
                f"boundary self-intersects: edges ({e1[0]}, {e1[1]}) and "
                f"({e2[0]}, {e2[1]}) touch or cross"
            )
        return None

    def _small_pass(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> bool:
        """The triangle term and the total-area term of a mesh of at most :data:`BLOCK`
        triangles in one pass (value, gradient, curvature; not the hvp).

        Points are viewed as complex numbers ``z = x + iy`` (a free view of the ``(N, 2)``
        array), so one operation handles both components; the rotation ``R`` is ``i·``.
        Per triangle (``e_l`` the edge opposite vertex ``l``, ``w_l`` the same for V):
        ``∇_m N = Φ_{m+1} − Φ_{m+2}`` with ``Φ = ∂N/∂e`` (``2e`` or ``e/E``),
        ``∇_m A = ½ i e_m``, so the corner gradient of ``c N/A + β2/𝒜`` is
        ``(c/A) ∇_m N + ½ i e_m (−c N/A² − β2/𝒜²)``; ``𝒜 = Σ_k A_k``, ``𝒜' = Σ a1``,
        ``𝒜'' = Σ a2`` come with the per-triangle ``a1 = A'[V]``, ``a2 = A''[V, V]``.
        The curvature formulas are those of :class:`_TriangleQuotientTerm` and
        :class:`_TotalAreaTerm`. Corner vectors reach the nodes in one ``np.bincount``
        over the interleaved (x, y) components. Returns False at a non-positive area.
        """
        term = self._triangle_term
        if term is not None and term.quality:
            return self._small_quality_pass(Q, V, acc)
        want = acc.want
        area_term = self._area_term
        z = Q.view(np.complex128).ravel()
        e = z[self._edge_head]
        e -= z[self._edge_tail]
        er, ei = e.real, e.imag
        ce2 = e[2].conj()
        A = 0.5 * (ce2 * e[0]).imag  # ½ e2 × e0, (4.2)
        if not A.min() > 0:
            return False
        inv = 1.0 / A
        with_v = V is not None and want.curvature
        if with_v:
            zv = V.view(np.complex128).ravel()
            w = zv[self._edge_head]
            w -= zv[self._edge_tail]
            wr, wi = w.real, w.imag
            cw2 = w[2].conj()
            a1 = 0.5 * (cw2 * e[0] + ce2 * w[0]).imag  # A'[V]
            a2 = (cw2 * w[0]).imag  # A''[V, V]
        rot = None  # coefficient of ½ i e_m in the corner gradient
        corner = None
        if term is not None:
            c = term.coef
            sq = er * er
            sq += ei * ei
            if term.quality:
                N = sq.sum(axis=0)  # S = Σ|e_l|²
            else:
                E = np.sqrt(sq)
                N = E.sum(axis=0)
                iE = 1.0 / E
            ratio = N * inv
            acc.values[term.name] = c * float(ratio.sum())
            if want.gradient:
                rot = -c * ratio * inv
                if term.quality:
                    # ∇_m S = 2(e_{m+1} − e_{m+2}) = −2 e_m − 4 e_{m+2}  (Σ_l e_l = 0)
                    corner = e[[2, 0, 1]]
                    corner *= -4.0 * c * inv
                    corner -= (2.0 * c * inv) * e
                else:
                    phi = e * iE  # ∂L/∂e
                    corner = phi[[1, 2, 0]]
                    corner -= phi[[2, 0, 1]]
                    corner *= c * inv
            if with_v:
                ew = er * wr
                ew += ei * wi  # e_l · w_l
                ww = wr * wr
                ww += wi * wi
                if term.quality:
                    n1 = 2.0 * ew.sum(axis=0)
                    n2 = 2.0 * ww.sum(axis=0)
                else:
                    fw = ew * iE  # u_l · w_l
                    n1 = fw.sum(axis=0)
                    n2 = ((ww - fw * fw) * iE).sum(axis=0)
                a1_a = a1 * inv
                curv = n2 - ratio * a2
                curv += 2.0 * a1_a * (ratio * a1 - n1)
                acc.curvature += c * float(np.einsum("t,t->", curv, inv))
        if area_term is not None:
            b2 = area_term.coef
            tot = float(A.sum())
            acc.values[area_term.name] = b2 / tot
            if want.gradient:
                rot = (-b2 / tot**2) if rot is None else rot - b2 / tot**2
                if corner is None:
                    corner = np.zeros_like(e)
            if with_v:
                d1, d2 = float(a1.sum()), float(a2.sum())
                acc.curvature += b2 * (2.0 * d1 * d1 / tot**3 - d2 / tot**2)
        if want.gradient and corner is not None:
            if rot is not None:
                corner += (0.5j * rot) * e
            flat = corner.view(np.float64).ravel()
            acc.grad += np.bincount(self._corner_xy, flat, 2 * self.n_vertices).reshape(-1, 2)
        return True

    def _small_quality_pass(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> bool:
        """:meth:`_small_pass` for the quality term (f2), in the triangle's discrete Fourier
        coordinates.

        With ``ω = e^{2πi/3}`` and corners ``z_k``, ``p = z0 + ω z1 + ω² z2`` and
        ``m = z0 + ω² z1 + ω z2`` (``p = 0`` for an equilateral CCW triangle) give
        ``S = ΣE_l² = P + M`` and ``A = (√3/12)(M − P)`` with ``P = |p|²``, ``M = |m|²``, so
        the term is ``c S/A = K (M + P)/D``, ``K = 4√3 c``, ``D = M − P``. With
        ``∂P/∂z̄_k = p ω̄^k`` and ``∂M/∂z̄_k = m ω^k`` the corner gradient (x + iy) of
        ``F(P, M)`` is ``2(F_P p ω̄^k + F_M m ω^k)``: ``F_P = 2KM/D²``, ``F_M = −2KP/D²``,
        plus ``±β2 √3/(12𝒜²)`` from ``β2/𝒜``, ``𝒜 = (√3/12) Σ D``. Along ``V`` (transforms
        ``p_v``, ``m_v``): ``P' = 2 Re(p̄ p_v)``, ``P'' = 2|p_v|²`` (likewise M), and the
        curvature of the quality term is
        ``(2K/D²)(M P'' − P M'') + (4K/D³)(P' − M')(M P' − P M')``
        (from ``F_PP = 4KM/D³``, ``F_MM = 4KP/D³``, ``F_PM = −2K(M + P)/D³``); the area
        term's is ``β2 (2𝒜'²/𝒜³ − 𝒜''/𝒜²)``. Everything but the corner gradient works on
        ``T``-vectors instead of ``(3, T)`` arrays; the gradient ``2 Wᴴ (F_P p, F_M m)``
        is one sparse matvec with the adjoint of the ``(2T, N)`` matrix ``W`` of the
        weights ``ω^k`` (rows of p) and ``ω^{2k}`` (rows of m); ``p, m`` themselves come
        from one gather of the corners, ``z0 − (z1 + z2)/2 ± (i√3/2)(z1 − z2)``.
        """
        want = acc.want
        term = self._triangle_term
        area_term = self._area_term
        WH = self._fourier_adjoint
        T = self.n_triangles
        tri = self._tri_t

        def transform(x):  # (N, 2) → p, m (T,) complex
            zc = x.view(np.complex128).ravel()[tri]  # (3, T) corners
            h = zc[1] + zc[2]
            h *= -0.5
            h += zc[0]  # z0 − (z1 + z2)/2
            b = zc[1] - zc[2]
            b *= _I_SQRT3_2  # (i√3/2)(z1 − z2)
            return h + b, h - b

        p, m = transform(Q)
        P = _re_dot(p, p)
        M = _re_dot(m, m)
        D = M - P
        if not D.min() > 0:
            return False
        iD = 1.0 / D
        K = 4.0 * SQRT3 * term.coef
        acc.values[term.name] = K * float(np.add.reduce((M + P) * iD))
        if area_term is not None:
            b2 = area_term.coef
            tot = SQRT3 / 12.0 * float(D.sum())
            acc.values[area_term.name] = b2 / tot
        iD2 = iD * iD
        if want.gradient:
            FP = (2.0 * K) * M * iD2
            FM = (-2.0 * K) * P * iD2
            if area_term is not None:
                da = b2 * SQRT3 / (12.0 * tot * tot)
                FP += da
                FM -= da
            coef = np.empty(2 * T, dtype=np.complex128)
            np.multiply(FP, p, out=coef[:T])
            np.multiply(FM, m, out=coef[T:])
            g = WH @ coef  # Σ over corners of F_P p ω̄^k + F_M m ω^k, (N,) complex
            g *= 2.0
            acc.grad += g.view(np.float64).reshape(-1, 2)
        if V is not None and want.curvature:
            pv, mv = transform(V)
            P1 = _re_dot(p, pv, 2.0)
            M1 = _re_dot(m, mv, 2.0)
            P2 = _re_dot(pv, pv, 2.0)
            M2 = _re_dot(mv, mv, 2.0)
            first = M * P2
            first -= P * M2
            second = M * P1
            second -= P * M1
            second *= (2.0 * iD) * (P1 - M1)
            first += second
            acc.curvature += 2.0 * K * float(np.add.reduce(first * iD2))
            if area_term is not None:
                d1 = SQRT3 / 12.0 * float(np.add.reduce(M1 - P1))
                d2 = SQRT3 / 12.0 * float(np.add.reduce(M2 - P2))
                acc.curvature += b2 * (2.0 * d1 * d1 / tot**3 - d2 / tot**2)
        return True

    def _triangle_pass(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> bool:
        """Per-triangle work in blocks of :data:`BLOCK` triangles (temporaries stay in
        cache); returns False as soon as a block has a non-positive (or NaN) area.
        Small meshes without an hvp request go to :meth:`_small_pass`."""
        term = self._triangle_term
        want = acc.want
        if self._small and not want.hvp:
            return self._small_pass(Q, V, acc)
        T = self.n_triangles
        qx, qy = np.ascontiguousarray(Q[:, 0]), np.ascontiguousarray(Q[:, 1])
        if with_v := (term is not None and V is not None and (want.hvp or want.curvature)):
            vx, vy = np.ascontiguousarray(V[:, 0]), np.ascontiguousarray(V[:, 1])
        gbuf = np.empty((2, 3, T)) if term is not None and want.gradient else None
        hbuf = np.empty((2, 3, T)) if term is not None and want.hvp else None
        value = curvature = 0.0
        for start, tb in self._blocks:  # blocks of triangles, vectorized inside
            stop = start + tb.shape[1]
            ex, ey = _edges(qx, qy, tb)
            A = _area(ex, ey)
            if not A.min() > 0:
                return False
            if term is None:
                continue
            wx, wy = _edges(vx, vy, tb) if with_v else (None, None)
            gout = None if gbuf is None else (gbuf[0, :, start:stop], gbuf[1, :, start:stop])
            hout = None if hbuf is None else (hbuf[0, :, start:stop], hbuf[1, :, start:stop])
            v, c = term.block(ex, ey, A, wx, wy, want, gout, hout)
            value += v
            curvature += c
        if term is not None:
            acc.values[term.name] = value
            acc.curvature += curvature
            if gbuf is not None:
                self._scatter(acc.grad, gbuf)
            if hbuf is not None:
                self._scatter(acc.hvp, hbuf)
        return True

    def _run(self, Q, V, want: _Want, *, strict: bool, check_boundary: bool = True):
        Q = self._points(Q)
        if V is not None:
            V = self._points(V, "V")
        acc = _Accumulator(self.n_vertices, want)
        problem = None
        if not np.isfinite(Q).all():
            ok = False
        elif self._small and not want.hvp:  # checks the areas before dividing by them
            ok = self._triangle_pass(Q, V, acc)
        else:
            with np.errstate(all="ignore"):
                ok = self._triangle_pass(Q, V, acc)
        if not ok:
            problem = self._area_problem(Q) or "non-positive signed area"
        elif check_boundary:
            problem = self._boundary_problem(Q)
        if problem is not None:
            if strict:
                raise NotAdmissibleError(f"{type(self).__name__}: Q is not admissible: {problem}")
            return None
        for term in self._other_terms:
            term.evaluate(Q, V, acc)
        return acc

    # -- public protocol ----------------------------------------------------------
    @property
    def boundary_edges(self) -> IntArray:
        """Directed boundary edges of the mesh, ``(E∂, 2)`` (interior on the left)."""
        return self._boundary_edges

    @property
    def boundary_vertices(self) -> IntArray:
        """Sorted boundary vertex indices, ``(V∂,)``."""
        return self._boundary_vertices

    def boundary_problem(self, Q) -> str | None:
        """None if the boundary of ``Q`` is simple, else a message naming the boundary
        edges that fold onto, touch or cross each other (an exact test)."""
        return self._boundary_problem(self._points(Q))

    def is_admissible(self, Q) -> bool:
        """True iff every signed area is > 0 and the boundary does not touch itself."""
        Q = self._points(Q)
        return self._area_problem(Q) is None and self._boundary_problem(Q) is None

    def terms(self, Q) -> dict[str, float]:
        """Value of each term at ``Q`` (``+inf`` each when not admissible)."""
        acc = self._run(Q, None, _Want(), strict=False)
        names = self.term_names
        if acc is None:
            return {k: float("inf") for k in names}
        return {k: float(acc.values[k]) for k in names}

    @property
    def term_names(self) -> list[str]:
        """Names of the active terms, in evaluation order."""
        out = [] if self._triangle_term is None else [self._triangle_term.name]
        return out + [t.name for t in self._other_terms]

    def value(self, Q) -> float:
        """``f(Q)``; ``+inf`` at a non-admissible ``Q`` (never NaN)."""
        acc = self._run(Q, None, _Want(), strict=False)
        if acc is None:
            return float("inf")
        val = float(sum(acc.values.values()))
        return val if not np.isnan(val) else float("inf")

    __call__ = value

    def gradient(self, Q) -> FloatArray:
        """``∇f(Q)``, ``(N, 2)``. Raises NotAdmissibleError at a non-admissible Q."""
        return self._run(Q, None, _Want(gradient=True), strict=True).grad

    def value_and_gradient(self, Q) -> tuple[float, FloatArray]:
        """``(f(Q), ∇f(Q))`` sharing the work. Raises NotAdmissibleError."""
        acc = self._run(Q, None, _Want(gradient=True), strict=True)
        return float(sum(acc.values.values())), acc.grad

    def hvp(self, Q, V) -> FloatArray:
        """Hessian-vector product ``∇²f(Q) V``, ``(N, 2)``. Raises NotAdmissibleError."""
        return self._run(Q, V, _Want(hvp=True), strict=True).hvp

    def gradient_and_curvature(
        self, Q, V, *, check_boundary: bool = True
    ) -> tuple[FloatArray, float]:
        """``(∇f(Q), V·∇²f(Q)·V)`` in one pass without forming ``∇²f V``.

        This is the right-hand side of the geodesic equation
        ``Q'' = −∇f (V·∇²f V)/(1 + |∇f|²)`` (SPEC §5). Raises NotAdmissibleError at a
        non-positive signed area and, unless ``check_boundary=False``, at a boundary that
        touches itself. ``check_boundary=False`` is for callers that test the boundary
        themselves where it matters (the geodesic integrators check it exactly at every
        accepted step and output, :class:`~meshopt_toolkit.integrators.GeodesicField`):
        with ``β3 = 0`` (``α2 = 0``) nothing in ``f`` stops a boundary crossing, and the
        formulas are finite on both sides of one.
        """
        acc = self._run(Q, V, _Want(gradient=True, curvature=True, value=False), strict=True,
                        check_boundary=check_boundary)
        return acc.grad, float(acc.curvature)

    def curvature(self, Q, V) -> float:
        """``V·∇²f(Q)·V`` alone. Raises NotAdmissibleError."""
        return float(self._run(Q, V, _Want(curvature=True), strict=True).curvature)

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(n_vertices={self.n_vertices}, "
            f"n_triangles={self.n_triangles}, terms={self.term_names})"
        )


def _coefficients(values, n: int, name: str) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)
    except TypeError:
        raise ValueError(f"{name} must be a sequence of {n} numbers, got {values!r}") from None
    if len(out) != n or not all(np.isfinite(v) and v >= 0 for v in out):
        raise ValueError(f"{name} must be {n} finite numbers >= 0, got {values!r}")
    return out


class HeightPenalty(Penalty):
    """The height penalty f1 (5.16), with an optional cut-off on its pair term (5.18).

    ``f1(Q) = Σ_k Σ_l α1/h_l(k) + Σ_pairs χ(α2/D^μ) + (α3/2)‖Q − Qref‖²_F``
    with heights ``h_l = 2A/E_l`` (5.5), so ``Σ_l 1/h_l = (E0 + E1 + E2)/(2A)``.
    Not invariant under uniform refinement.

    Parameters
    ----------
    mesh : PlanarMesh
        Connectivity (and the default reference positions).
    alpha : (α1, α2, α3), each ≥ 0
    mu : float
        Regularization parameter μ of ``D^μ`` (appendix B).
    cutoff : (s_lo, s_hi) or None
        Wrap each pair summand ``s = α2/D^μ`` as ``χ(s)``, see :func:`cutoff`.
    reference : (N, 2) array or PlanarMesh, optional
        ``Qref``; the mesh's points by default.

    Terms (see :meth:`terms`): ``"height"``, ``"boundary"``, ``"reference"``; a term
    whose coefficient is 0 is skipped.
    """

    def __init__(
        self,
        mesh: TriangleMesh,
        alpha=(1.0, 1.0, 1.0),
        mu: float = DEFAULT_MU,
        cutoff=None,
        reference=None,
    ) -> None:
        super().__init__(mesh, mu, cutoff, reference)
        a1, a2, a3 = self.alpha = _coefficients(alpha, 3, "alpha")
        if a1:
            self._triangle_term = _TriangleQuotientTerm("height", "height", 0.5 * a1)
        if a2:
            self._other_terms.append(
                _BoundaryTerm(
                    1.0, a2, self.mu, self.cutoff, self._boundary_vertices, self._boundary_edges
                )
            )
        if a3:
            self._other_terms.append(_ReferenceTerm(a3, self.reference))


class QualityPenalty(Penalty):
    """The shape-quality penalty f2 (5.22), with an optional cut-off on its pair term (5.33).

    ``f2(Q) = (β1/T) Σ_k 1/ψ_k + β2/Σ_k A_k + β3/(#E∂ #V∂) Σ_pairs χ(1/D^μ)
    + β4/(2N) ‖Q − Qref‖²_F`` with ``1/ψ = (E0² + E1² + E2²)/(4√3 A)`` (5.23).
    The quality and area terms are invariant under rigid motions and exactly invariant
    under uniform refinement; the reference term is not (refinement adds nodes).

    Parameters
    ----------
    mesh : PlanarMesh
    beta : (β1, β2, β3, β4), each ≥ 0; β4 unscaled (the formula divides by 2N)
    mu : float
        Regularization parameter μ of ``D^μ`` (appendix B).
    cutoff : (s_lo, s_hi) or None
        Wrap each pair summand ``s = 1/D^μ`` as ``χ(s)``, see :func:`cutoff`.
    reference : (N, 2) array or PlanarMesh, optional
        ``Qref``; the mesh's points by default.

    Terms (see :meth:`terms`): ``"quality"``, ``"area"``, ``"boundary"``,
    ``"reference"``; a term whose coefficient is 0 is skipped.
    """

    def __init__(
        self,
        mesh: TriangleMesh,
        beta=(1.0, 1.0, 1.0, 1.0),
        mu: float = DEFAULT_MU,
        cutoff=None,
        reference=None,
    ) -> None:
        super().__init__(mesh, mu, cutoff, reference)
        b1, b2, b3, b4 = self.beta = _coefficients(beta, 4, "beta")
        if b1:
            coef = b1 / (4.0 * SQRT3 * self.n_triangles)
            self._triangle_term = _TriangleQuotientTerm("quality", "quality", coef)
        if b2:
            self._area_term = _TotalAreaTerm(b2, self._boundary_edges, self._boundary_vertices)
            self._other_terms.append(self._area_term)
        if b3:
            n_pairs_norm = len(self._boundary_edges) * len(self._boundary_vertices)
            self._other_terms.append(
                _BoundaryTerm(
                    b3 / n_pairs_norm,
                    1.0,
                    self.mu,
                    self.cutoff,
                    self._boundary_vertices,
                    self._boundary_edges,
                )
            )
        if b4:
            self._other_terms.append(_ReferenceTerm(b4 / self.n_vertices, self.reference))
