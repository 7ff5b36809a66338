"""Shape optimization on tetrahedra: what :func:`meshopt_toolkit.optimize.optimize` uses in
place of the planar penalty, metric and admissibility when the mesh is a ``TetMesh``.

* admissibility (:class:`TetShapeProblem`): the tet kind's exact test
  (:meth:`~meshopt_toolkit.cells.tetrahedra.Tetrahedra.admissibility_problem`: every tet
  positively oriented by ``orient3d``, the boundary free of self-intersections) and a
  floor on the worst mean ratio, :data:`TET_QUALITY_GUARD` times its initial value;
* the descent direction's metric: the tet motion's ``M + JᵀJ`` of the tet distortion
  (:class:`~meshopt_toolkit.motion.tets.metric.TetGraphMetric`, the tet kind's default
  metric) at the current mesh, one factorization per iterate (:class:`FactoredMetric`);
* the penalty f2 (:class:`DistortionPenalty`): ``½β Σ_c (|K_c|/|Ω|) |φ_c(Q)|²`` of the
  same distortion ``φ`` relative to the initial mesh, a barrier (``|φ_c| → ∞`` as a tet
  degenerates) that keeps the optimum's mesh healthy;
* straight-line steps are capped before the first tet's volume, a cubic in the step,
  vanishes (:func:`tet_step_limit`).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ..cells.tetrahedra import TETRAHEDRA
from ..kernels.tetrahedra import mean_ratios, signed_volumes
from ..kernels.triangles import first_positive_roots
from ..motion.tets.distortion import TetDistortion
from ..solvers import factorize_spd
from .problem import ShapeProblem

__all__ = ["TET_QUALITY_GUARD", "DistortionPenalty", "FactoredMetric", "TetShapeProblem",
           "check_tet_options", "tet_setup", "tet_step_limit"]

#: trial meshes whose worst mean ratio is below this times the initial one are rejected
TET_QUALITY_GUARD = 0.3


def _volume_cubic(Q: FloatArray, tets: IntArray, d: FloatArray) -> FloatArray:
    """Coefficients ``(4, C)`` of ``6 V_c(t) = c0 + c1 t + c2 t² + c3 t³`` on ``Q + t d``."""
    q, w = Q[tets], d[tets]
    e = q[:, 1:] - q[:, :1]
    f = w[:, 1:] - w[:, :1]

    def det(a, b, c):
        return np.einsum("ck,ck->c", a, np.cross(b, c))

    e1, e2, e3 = e[:, 0], e[:, 1], e[:, 2]
    f1, f2, f3 = f[:, 0], f[:, 1], f[:, 2]
    return np.array([det(e1, e2, e3),
                     det(f1, e2, e3) + det(e1, f2, e3) + det(e1, e2, f3),
                     det(e1, f2, f3) + det(f1, e2, f3) + det(f1, f2, e3),
                     det(f1, f2, f3)])


def tet_step_limit(Q: FloatArray, tets: IntArray, d: FloatArray) -> float:
    """First ``t > 0`` at which a tet's signed volume on ``Q + t d`` vanishes (inf if
    none): the real roots of each tet's volume cubic (the eigenvalues of its companion
    matrix, in the step scaled to the tet's own size so the coefficients balance)."""
    Q, d = np.asarray(Q, dtype=float), np.asarray(d, dtype=float)
    tets = np.asarray(tets)
    moving = np.abs(d[tets]).max(axis=(1, 2)) > 0
    if not moving.any():
        return np.inf
    tets = tets[moving]
    c = _volume_cubic(Q, tets, d)
    q, w = Q[tets], d[tets]
    length = np.linalg.norm(q[:, 1:] - q[:, :1], axis=2).max(axis=1)
    speed = np.linalg.norm(w[:, 1:] - w[:, :1], axis=2).max(axis=1)
    speed = np.where(speed > 0, speed, np.abs(w).max(axis=(1, 2)))
    tau = length / speed  # t = tau s: every coefficient of the cubic in s is ~ length³
    p = c * tau ** np.arange(4)[:, None]
    p /= np.abs(p).max(axis=0)
    roots = np.full(len(tets), np.inf)
    cubic = np.abs(p[3]) > 1e-12
    if cubic.any():
        n = int(cubic.sum())
        comp = np.zeros((n, 3, 3))
        comp[:, 0, :] = -(p[2::-1, cubic] / p[3, cubic]).T
        comp[:, 1, 0] = comp[:, 2, 1] = 1.0
        ev = np.linalg.eigvals(comp)
        real = np.abs(ev.imag) <= 1e-9 * np.maximum(np.abs(ev.real), 1.0)
        s = np.where(real & (ev.real > 0), ev.real, np.inf)
        roots[cubic] = s.min(axis=1)
    low = ~cubic  # at most quadratic: the planar formula
    if low.any():
        roots[low] = first_positive_roots(p[2, low], p[1, low], p[0, low])
    return float(np.min(roots * tau))


class DistortionPenalty:
    """``f2(Q) = ½β Σ_c a_c |φ_c(Q)|²``: the tet distortion ``φ`` relative to ``reference``
    (:class:`~meshopt_toolkit.motion.tets.distortion.TetDistortion`) with the volume
    fractions ``a_c = |K_c| / |Ω|`` of the reference; ``+inf`` where a tet is inverted.

    Parameters
    ----------
    reference : (N, 3) float array
    tets : (C, 4) int array
    beta : float
        ``β ≥ 0``.
    """

    def __init__(self, reference: FloatArray, tets: IntArray, beta: float) -> None:
        self.distortion = TetDistortion(np.asarray(reference, dtype=float), np.asarray(tets))
        v = np.abs(signed_volumes(reference, tets))
        self.weights = float(beta) * v / v.sum()
        self.tets = np.asarray(tets)

    def value(self, Q: FloatArray) -> float:
        phi = self.distortion.values(np.asarray(Q, dtype=float))
        with np.errstate(invalid="ignore"):
            return 0.5 * float(self.weights @ np.sum(phi * phi, axis=1))

    def gradient(self, Q: FloatArray) -> FloatArray:
        """``∇f2`` ``(N, 3)``: ``β Σ_c a_c (∂φ_c/∂Q)ᵀ φ_c``."""
        Q = np.asarray(Q, dtype=float)
        phi, blocks = self.distortion.values_and_jacobian(Q)
        per_cell = np.einsum("cm,cmj->cj", self.weights[:, None] * phi, blocks)
        cols = (3 * self.tets[:, :, None] + np.arange(3)).reshape(len(self.tets), -1)
        return np.bincount(cols.ravel(), per_cell.ravel(), minlength=Q.size).reshape(Q.shape)


class FactoredMetric:
    """A metric with ``matrix(Q)`` (e.g. the tet kind's default metric) whose Riesz maps at
    one ``(Q, free)`` share one sparse factorization: the gradient, the L-BFGS direction
    and the constraints' normals of an iterate cost one factorization together."""

    is_flat = False

    def __init__(self, metric) -> None:
        self.metric = metric
        self._key = None
        self._solve = None
        self.n_factorizations = 0

    def inner(self, Q: FloatArray, U: FloatArray, V: FloatArray) -> float:
        return self.metric.inner(Q, U, V)

    def norm(self, Q: FloatArray, V: FloatArray) -> float:
        return self.metric.norm(Q, V)

    def riesz(self, Q: FloatArray, P: FloatArray, free: np.ndarray | None = None) -> FloatArray:
        """``g_Q⁻¹ P`` on the free vertices' dofs (zero on the fixed ones)."""
        Q = np.asarray(Q, dtype=float)
        P = np.asarray(P, dtype=float)
        d = Q.shape[1]
        keep = np.ones(len(Q), bool) if free is None else np.asarray(free, dtype=bool)
        key = (Q.tobytes(), keep.tobytes())
        if key != self._key:
            dof = np.repeat(keep, d)
            A = self.metric.matrix(Q)
            self._solve = factorize_spd(A[dof][:, dof].tocsc())
            self._key = key
            self.n_factorizations += 1
        out = np.zeros_like(P)
        out[keep] = self._solve(P[keep].ravel()).reshape(-1, d)
        return out

    def exp(self, Q: FloatArray, V: FloatArray, t: float = 1.0) -> FloatArray:
        return self.metric.exp(Q, V, t)


class TetShapeProblem(ShapeProblem):
    """:class:`~.problem.ShapeProblem` on tetrahedra: exact admissibility of the tet kind,
    the worst mean ratio kept above ``quality_floor``, mean ratios as the quality, the
    volume cubic as the straight-line step limit. ``triangles`` are the tets ``(C, 4)``,
    ``boundary_edges`` the boundary faces (unused: the tet kind finds them)."""

    floor_quality = staticmethod(mean_ratios)

    def admissible(self, Q: FloatArray) -> bool:
        """Finite, every tet positively oriented (exact), the boundary free of
        self-intersections, the worst mean ratio at least the quality floor."""
        if TETRAHEDRA.admissibility_problem(Q, self.triangles) is not None:
            return False
        return self._above_floor(Q)

    def quality(self, Q: FloatArray) -> tuple[float, float]:
        """``(mean, worst)`` mean ratio of the tets."""
        q = mean_ratios(Q, self.triangles)
        return float(q.mean()), float(q.min())

    def step_limit(self, Q: FloatArray, d: FloatArray) -> float:
        return tet_step_limit(Q, self.triangles, d)

    def travel_limit(self, Q: FloatArray, d: FloatArray) -> float:
        return 0.5 * tet_step_limit(Q, self.triangles, d)


def check_tet_options(variant: str, preconditioner: str) -> str:
    """The metric kind of ``variant`` on tetrahedra; a planar-only variant (the complete
    metric) or L-BFGS preconditioner is refused (``OptionError``)."""
    from ..errors import OptionError
    from .setup import VARIANT_PARTS

    kind = VARIANT_PARTS[variant][0]
    if kind == "complete":
        raise OptionError(f"--variant {variant}: the complete metric is planar; on tetrahedra "
                          "use elasticity-euclidean (the tet motion's metric) or "
                          "euclidean-euclidean")
    if preconditioner not in ("auto", "none"):
        raise OptionError(f"--lbfgs-preconditioner {preconditioner} is planar; on tetrahedra "
                          "use auto or none")
    return kind


def tet_setup(mesh, variant: str, penalty, preconditioner: str):
    """``(f2, metric, problem class, quality floor)`` of a run on the ``TetMesh`` ``mesh``.

    ``variant``'s metric: ``"elasticity"`` is the tet motion's metric (:class:`FactoredMetric`
    of the tet kind's default metric), ``"euclidean"`` the Euclidean one; the complete metric
    is planar and refused, as is an L-BFGS preconditioner. f2 is :class:`DistortionPenalty`
    with ``β`` = β1 of ``penalty`` (None or 0: no penalty)."""
    from ..riemannian.metrics import EuclideanMetric

    kind = check_tet_options(variant, preconditioner)
    Q, tets = np.asarray(mesh.points, dtype=float), np.asarray(mesh.tets)
    metric = (EuclideanMetric() if kind == "euclidean"
              else FactoredMetric(TETRAHEDRA.default_metric(Q, tets)))
    beta = 0.0 if penalty is None else float(penalty[0])
    f2 = DistortionPenalty(Q, tets, beta) if beta > 0 else None
    floor = TET_QUALITY_GUARD * float(mean_ratios(Q, tets).min())
    return f2, metric, TetShapeProblem, floor
