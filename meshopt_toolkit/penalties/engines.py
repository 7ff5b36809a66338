"""The evaluation engines of the per-triangle terms: three ways to compute the same thing.

An engine's ``run(Q, V, acc)`` adds the triangle quotient term (and, for the small-mesh
engines, the total-area term) to the accumulator and returns False as soon as a signed
area is not positive; nothing else. All three implement :class:`Engine`, and
``tests/penalties/test_penalty_engines.py`` checks that they agree on random meshes.

- :class:`BlockedEngine`: any mesh, everything including the Hessian-vector product;
  blocks of :data:`~.tuning.BLOCK` triangles in component-major ``(3, b)`` arrays.
- :class:`ComplexEngine`: a mesh of one block, value, gradient and curvature (no hvp), in
  complex arithmetic (the height term f1, or no triangle term).
- :class:`FourierEngine`: the same for the quality term f2, in each triangle's discrete
  Fourier coordinates.

:meth:`~.penalty.Penalty._engine` picks one: small meshes without an hvp request go to
a small-mesh engine.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..kernels.triangles import areas_from_edges as _area
from ..kernels.triangles import edges_xy as _edges
from .terms import _Accumulator, _re_dot, _TotalAreaTerm, _TriangleQuotientTerm

__all__ = ["BlockedEngine", "ComplexEngine", "Engine", "FourierEngine"]

SQRT3 = np.sqrt(3.0)
_OMEGA = np.exp(2j * np.pi / 3 * np.arange(3))  # ω^k, k = 0, 1, 2
_I_SQRT3_2 = 0.5j * SQRT3  # p = z0 − (z1 + z2)/2 + (i√3/2)(z1 − z2), m with −i√3/2


class Engine(Protocol):
    """What :class:`~.penalty.Penalty` asks of an evaluation engine."""

    #: whether ``run`` can fill ``acc.hvp`` (Hessian-vector products)
    supports_hvp: bool

    def run(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> bool: ...


class BlockedEngine:
    """Per-triangle work in blocks of triangles (temporaries stay in cache), scattered to
    the nodes with one sparse matvec per component. Evaluates the triangle term only."""

    supports_hvp = True

    def __init__(
        self,
        tri_t: IntArray,
        n_vertices: int,
        triangle_term: _TriangleQuotientTerm | None,
        block: int,
    ) -> None:
        self._triangle_term = triangle_term
        self.n_vertices = n_vertices
        self.n_triangles = tri_t.shape[1]
        self._tri_flat = tri_t.ravel()
        # contiguous (3, b) blocks: gathers through a contiguous index are ~2x faster
        self._blocks = [
            (s, np.ascontiguousarray(tri_t[:, s : s + block]))
            for s in range(0, self.n_triangles, block)
        ]
        self._scatter_csc = None

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

    def run(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> bool:
        """Per-triangle work in blocks of :data:`BLOCK` triangles (temporaries stay in
        cache); returns False as soon as a block has a non-positive (or NaN) area."""
        term = self._triangle_term
        want = acc.want
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


class _OneBlockEngine:
    """The triangle term and the total-area term of a mesh of one block, in one pass
    (value, gradient, curvature; not the hvp)."""

    supports_hvp = False

    def __init__(
        self,
        tri_t: IntArray,
        n_vertices: int,
        triangle_term: _TriangleQuotientTerm | None,
        area_term: _TotalAreaTerm | None,
    ) -> None:
        self._triangle_term = triangle_term
        self._area_term = area_term
        self.n_vertices = n_vertices
        self._index(tri_t)

    def _index(self, tri_t: IntArray) -> None:
        """Keep the index arrays of the triangles ``tri_t`` (3, T) that :meth:`run` uses."""
        raise NotImplementedError


class ComplexEngine(_OneBlockEngine):
    """The triangle term and the total-area term of a mesh of one block, in complex
    arithmetic (value, gradient, curvature; not the hvp)."""

    def _index(self, tri_t: IntArray) -> None:
        self._edge_head = np.ascontiguousarray(tri_t[[2, 0, 1]])  # e_l = q_head − q_tail
        self._edge_tail = np.ascontiguousarray(tri_t[[1, 2, 0]])
        flat2 = 2 * tri_t.ravel()
        self._corner_xy = np.stack([flat2, flat2 + 1], axis=1).ravel()

    def run(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> bool:
        """The triangle term and the total-area term of a mesh of at most :data:`BLOCK`
        triangles in one pass (value, gradient, curvature; not the hvp).

        Points are viewed as complex numbers ``z = x + iy`` (a free view of the ``(N, 2)``
        array), so one operation handles both components; the rotation ``R`` is ``i·``.
        Per triangle (``e_l`` the edge opposite vertex ``l``, ``w_l`` the same for V):
        ``∇_m N = Φ_{m+1} − Φ_{m+2}`` with ``Φ = ∂N/∂e`` (``2e`` or ``e/E``),
        ``∇_m A = ½ i e_m``, so the corner gradient of ``c N/A + β2/𝒜`` is
        ``(c/A) ∇_m N + ½ i e_m (−c N/A² − β2/𝒜²)``; ``𝒜 = Σ_k A_k``, ``𝒜' = Σ a1``,
        ``𝒜'' = Σ a2`` come with the per-triangle ``a1 = A'[V]``, ``a2 = A''[V, V]``.
        The curvature formulas are those of :class:`~.terms._TriangleQuotientTerm`
        and :class:`~.terms._TotalAreaTerm`. Corner vectors reach the nodes in one ``np.bincount``
        over the interleaved (x, y) components. Returns False at a non-positive area.
        """
        term = self._triangle_term
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
            N, iE = term.measure(er, ei)
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
                n1, fw = term.first_variation(er, ei, wr, wi, iE)
                n2 = term.second_variation(wr, wi, fw, iE)
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


class FourierEngine(_OneBlockEngine):
    """The quality term (f2) and the total-area term of a mesh of one block, in the
    triangles' discrete Fourier coordinates (value, gradient, curvature; not the hvp; the
    triangle term must be given)."""

    def _index(self, tri_t: IntArray) -> None:
        self._tri_t = tri_t
        T = self.n_triangles = tri_t.shape[1]
        flat = tri_t.ravel()
        # discrete Fourier coordinates of each triangle:
        # rows t: p_t = Σ_k ω^k z_{i_k}; rows T + t: m_t = Σ_k ω^{2k} z_{i_k}
        rows = np.concatenate([np.tile(np.arange(T), 3), np.tile(np.arange(T, 2 * T), 3)])
        cols = np.concatenate([flat, flat])
        vals = np.concatenate([np.repeat(_OMEGA, T), np.repeat(_OMEGA**2, T)])
        W = sp.csr_matrix((vals, (rows, cols)), shape=(2 * T, self.n_vertices))
        self._fourier_adjoint = W.conj().T.tocsr()  # (N, 2T): the gradient's scatter

    def run(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> bool:
        """:class:`ComplexEngine` for the quality term (f2), in the triangle's discrete Fourier
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
