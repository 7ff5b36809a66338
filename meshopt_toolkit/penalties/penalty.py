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
:func:`meshopt_toolkit.kernels.distance.regularized_distance`. The regularized distance is C2
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
- The per-triangle pass is done by an evaluation engine (:mod:`.engines`): blocks of
  :data:`~.tuning.BLOCK` triangles, or one complex-arithmetic pass for a small mesh.
  The terms are in :mod:`.terms`, the cut-off in :mod:`.cutoff`, the admissibility
  tests in :mod:`meshopt_toolkit.kernels.admissibility`.
- :meth:`Penalty.gradient_and_curvature` returns ``∇f`` and the scalar ``V·∇²f·V``
  without forming ``∇²f V`` (the geodesic ODE's right-hand side, SPEC §5).
"""

from __future__ import annotations

import logging
from functools import cached_property

import numpy as np

from .._options import require_shape
from .._typing import FloatArray, IntArray
from ..errors import InvalidMeshError, NotAdmissibleError
from ..kernels import distance as _distance
from ..kernels.admissibility import BoundaryCheck, area_problem
from ..mesh import PlanarMesh, TriangleMesh
from . import tuning
from .cutoff import _check_cutoff, cutoff
from .engines import BlockedEngine, ComplexEngine, Engine, FourierEngine
from .terms import (
    _Accumulator,
    _BoundaryTerm,
    _ReferenceTerm,
    _TotalAreaTerm,
    _TriangleQuotientTerm,
    _Want,
)

logger = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_MU",
    "HeightPenalty",
    "Penalty",
    "QualityPenalty",
    "cutoff",
]

SQRT3 = np.sqrt(3.0)

#: default μ of the regularized distance (defined with the distance kernels)
DEFAULT_MU = _distance.DEFAULT_MU


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
        self._block = int(tuning.BLOCK)
        self._boundary_edges = np.ascontiguousarray(mesh.boundary_edges.astype(np.intp))
        self._boundary_vertices = np.ascontiguousarray(mesh.boundary_vertices.astype(np.intp))
        self._boundary_check = BoundaryCheck(
            self._boundary_edges, self._boundary_vertices, tuning.SIMPLE_BOUNDARY_CACHE
        )
        if reference is None:
            ref = np.array(mesh.points, dtype=np.float64)
        else:
            ref = require_shape("reference", np.array(getattr(reference, "points", reference),
                                                      dtype=np.float64), (n, 2),
                                error=InvalidMeshError)
        ref.setflags(write=False)
        self.reference = ref
        self._triangle_term: _TriangleQuotientTerm | None = None
        self._other_terms: list = []
        self._area_term: _TotalAreaTerm | None = None  # (the small-mesh engines evaluate it)
        # small meshes (one block): a complex-arithmetic engine, see engines.py
        self._small = self.n_triangles <= self._block

    # -- evaluation engines ---------------------------------------------------------
    # (built on first use: subclasses set the terms after Penalty.__init__)
    @cached_property
    def _blocked_engine(self) -> BlockedEngine:
        return BlockedEngine(self._tri_t, self.n_vertices, self._triangle_term, self._block)

    @cached_property
    def _small_engine(self) -> Engine:
        term = self._triangle_term
        if term is not None and term.quality:
            return FourierEngine(self._tri_t, self.n_vertices, term, self._area_term)
        return ComplexEngine(self._tri_t, self.n_vertices, term, self._area_term)

    def _engine(self, want: _Want) -> Engine:
        """The engine for ``want``: small meshes without an hvp request take the
        small-mesh engine, everything else the blocked one."""
        if self._small and not want.hvp:
            return self._small_engine
        return self._blocked_engine

    @property
    def _blocks(self):
        return self._blocked_engine._blocks

    def _triangle_pass(self, Q: FloatArray, V: FloatArray | None, acc: _Accumulator) -> bool:
        return self._engine(acc.want).run(Q, V, acc)

    # -- admissibility (kernels.admissibility) -----------------------------------------
    def _area_problem(self, Q: FloatArray) -> str | None:
        """A message naming a non-finite vertex or a non-positive triangle, or None."""
        return area_problem(Q, self._tri_t)

    def _boundary_problem(self, Q: FloatArray) -> str | None:
        """A message naming boundary edges that fold onto, touch or cross each other
        (configurations found simple are remembered, see ``BoundaryCheck``)."""
        return self._boundary_check.problem(Q, self._boundary_test)

    def _boundary_test(self, Q: FloatArray) -> str | None:
        return self._boundary_check.test(Q)

    # -- helpers ------------------------------------------------------------------
    def _points(self, Q, what: str = "Q") -> FloatArray:
        q = np.ascontiguousarray(Q, dtype=np.float64)
        if q.shape != (self.n_vertices, 2):
            raise ValueError(f"{what} must have shape {(self.n_vertices, 2)}, got {q.shape}")
        return q

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
        accepted step and output, :class:`~meshopt_toolkit.riemannian.field.GeodesicField`):
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
