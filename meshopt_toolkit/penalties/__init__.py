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

import numpy as np

from .. import distance as _distance
from ..mesh import TriangleMesh
from . import kernels, penalty, terms  # noqa: F401 (submodules: their constants are tuning knobs)
from .cutoff import cutoff
from .kernels import SQRT3
from .penalty import BLOCK, SIMPLE_BOUNDARY_CACHE, Penalty  # noqa: F401 (re-exported)
from .terms import (PAIR_CACHE, PAIR_CHUNK, _BoundaryTerm,  # noqa: F401 (re-exported)
                    _ReferenceTerm, _TotalAreaTerm, _TriangleQuotientTerm)

__all__ = [
    "DEFAULT_MU",
    "HeightPenalty",
    "Penalty",
    "QualityPenalty",
    "cutoff",
]

#: default μ of the regularized distance (defined with the distance kernels)
DEFAULT_MU = _distance.DEFAULT_MU


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
