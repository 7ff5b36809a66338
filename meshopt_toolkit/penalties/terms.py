"""The terms of f1 and f2 and the state of one evaluation.

A term adds its value, gradient, Hessian-vector product and curvature ``V·∇²f·V`` to an
:class:`_Accumulator` (what is wanted is an :class:`_Want`). The per-triangle quotient
term is evaluated block by block by an engine (:mod:`.engines`); the total-area,
boundary-pair and reference terms evaluate themselves (``evaluate(Q, V, acc)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._linalg import dot as _dot
from .._typing import FloatArray, IntArray
from ..kernels import distance as _distance
from . import tuning
from .cutoff import cutoff


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


def _re_dot(a: np.ndarray, b: np.ndarray, scale: float = 1.0) -> FloatArray:
    """``scale · Re(a · conj b)`` elementwise for complex arrays (one temporary)."""
    out = a.real * b.real
    out += a.imag * b.imag
    if scale != 1.0:
        out *= scale
    return out


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
    (see :class:`~.engines.BlockedEngine`).
    """

    def __init__(self, name: str, kind: str, coef: float) -> None:
        self.name = name
        self.quality = kind == "quality"
        self.coef = float(coef)

    def measure(self, ex, ey) -> tuple[FloatArray, FloatArray | None]:
        """``N`` per triangle of the edge vectors ``(ex, ey)`` (3, ...), and ``1/E_l``
        (None for ``S``): what both engines evaluate the term from."""
        sq = ex * ex
        sq += ey * ey
        if self.quality:
            return sq[0] + sq[1] + sq[2], None
        E = np.sqrt(sq)
        return E[0] + E[1] + E[2], 1.0 / E

    @staticmethod
    def first_variation(ex, ey, wx, wy, iE) -> tuple[FloatArray, FloatArray | None]:
        """``n1 = N'[V]`` from the edge vectors and their variations ``(wx, wy)`` (3, ...),
        ``iE`` that of :meth:`measure`; and ``u_l · w_l`` (None for ``S``)."""
        ew = ex * wx
        ew += ey * wy  # e_l · w_l
        if iE is None:
            return 2.0 * (ew[0] + ew[1] + ew[2]), None
        fw = ew * iE  # u_l · w_l
        return fw[0] + fw[1] + fw[2], fw

    @staticmethod
    def second_variation(wx, wy, fw, iE) -> FloatArray:
        """``n2 = N''[V, V]``, ``fw`` and ``iE`` those of :meth:`first_variation` and
        :meth:`measure`."""
        ww = wx * wx
        ww += wy * wy
        if iE is None:
            return 2.0 * (ww[0] + ww[1] + ww[2])
        t = (ww - fw * fw) * iE
        return t[0] + t[1] + t[2]

    def block(self, ex, ey, A, wx, wy, want: _Want, gout, hout) -> tuple[float, float]:
        """One block of triangles: ``(value, curvature)``; vertex vectors of the gradient
        and the hvp are written into ``gout``/``hout`` = ``(x (3, b), y (3, b))``."""
        c = self.coef
        N, iE = self.measure(ex, ey)
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
        n1, fw = self.first_variation(ex, ey, wx, wy, iE)
        a1 = 0.5 * (wx[2] * ey[0] + ex[2] * wy[0] - wy[2] * ex[0] - ey[2] * wx[0])
        a1_a = a1 * inv_a
        if want.curvature:  # second directional derivatives n2 = N''[V, V], a2 = 2 A(V)
            n2 = self.second_variation(wx, wy, fw, iE)
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
        if self.name in acc.values:  # done by the small-mesh engine
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
    (the list is cached when it has at most :data:`~.tuning.PAIR_CACHE` rows); with one, only the pairs whose
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
        if cut is None and n_pairs <= tuning.PAIR_CACHE:
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
            for start in range(0, len(pairs), tuning.PAIR_CHUNK):
                yield pairs[start : start + tuning.PAIR_CHUNK]
        else:
            yield from _distance.iter_boundary_pairs(self.bv, self.be, chunk=tuning.PAIR_CHUNK)

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
