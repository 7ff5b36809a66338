"""The :class:`Penalty` engine: sums its terms over blocks of triangles, with the boundary
cache, the admissibility checks and the derivative products the integrators need."""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError, NotAdmissibleError
from ..mesh import PlanarMesh, TriangleMesh, boundary_self_intersections
from .cutoff import _check_cutoff, cutoff
from .kernels import SQRT3, _I_SQRT3_2, _OMEGA, _Accumulator, _Want, _area, _edges, _re_dot
from .terms import _TotalAreaTerm, _TriangleQuotientTerm


#: boundary configurations remembered as simple by each penalty
SIMPLE_BOUNDARY_CACHE = 64
#: triangles per block of the per-triangle pass (keeps temporaries in cache)
BLOCK = 8192


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


