"""The Newton–CG method of the discrete geodesic (the complete metric ``I + ∇f∇fᵀ`` of a
penalty ``f``): the path energy of K segments with the exact Hessian-vector product,
truncated CG preconditioned by the Woodbury-inverted Gauss–Newton matrix, and an Armijo
line search that treats inadmissible frames as ``E = ∞``."""

from __future__ import annotations

import logging

import numpy as np

from .._linalg import dot as _dot
from .._typing import FloatArray
from ..descent import backtrack, sufficient_decrease
from ..errors import NotAdmissibleError
from ._boundary_value import _Counter, _path_frames, _require_finite
from .geodesic_result import DiscreteGeodesic
from .geodesics import penalty_of
from .initial_path import initial_path
from .path_options import NewtonCGOptions

logger = logging.getLogger(__name__)


class _PathEnergy:
    """Path energy ``E`` of K segments with fixed ends, its gradient and Hessian products.

    The interior frames ``X`` have shape (K−1, N, 2).
    """

    def __init__(self, pen: _Counter, Q0: FloatArray, Q1: FloatArray, K: int,
                 f0: float, f1: float) -> None:
        self.pen, self.Q0, self.Q1, self.K = pen, Q0, Q1, K
        self.f0, self.f1 = f0, f1
        n = K - 1
        lap = 2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
        self.Linv = np.linalg.inv(2.0 * K * lap)  # inverse of the scalar part 2K·L
        self.X = None

    def _frames(self, X: FloatArray) -> FloatArray:
        return np.concatenate([self.Q0[None], X, self.Q1[None]])

    def value(self, X: FloatArray) -> float:
        fs = np.empty(self.K + 1)
        fs[0], fs[-1] = self.f0, self.f1
        for k, q in enumerate(X, start=1):
            fs[k] = self.pen.value(q)
            if not np.isfinite(fs[k]):
                return float("inf")
        d = np.diff(self._frames(X), axis=0)
        return float(self.K * (_dot(d, d) + _dot(np.diff(fs), np.diff(fs))))

    def evaluate(self, X: FloatArray) -> tuple[float, FloatArray]:
        """``(E, ∇E)`` at X, storing f_k, ∇f_k for the Hessian products."""
        K = self.K
        fs = np.empty(K + 1)
        fs[0], fs[-1] = self.f0, self.f1
        gs = np.empty_like(X)
        for k, q in enumerate(X):
            fs[k + 1], gs[k] = self.pen.value_and_gradient(q)
        d = np.diff(self._frames(X), axis=0)
        df = np.diff(fs)
        E = float(K * (_dot(d, d) + _dot(df, df)))
        lap_f = df[:-1] - df[1:]  # 2f_k − f_{k−1} − f_{k+1}
        G = 2.0 * K * (d[:-1] - d[1:]) + (2.0 * K * lap_f)[:, None, None] * gs
        self.X, self.fs, self.gs, self.lap_f = X, fs, gs, lap_f
        self.gram = np.einsum("iab,jab->ij", gs, gs)
        self.S = np.linalg.cholesky(self.Linv * (1.0 + self.gram))
        return E, G

    def hvp(self, U: FloatArray, shift: float = 0.0) -> FloatArray:
        """``(∇²E + shift·H_GN) · U`` at the last evaluated X, U of shape (K−1, N, 2)."""
        K = self.K
        Ue = np.concatenate([np.zeros_like(U[:1]), U, np.zeros_like(U[:1])])
        s = np.zeros(K + 1)
        s[1:-1] = np.einsum("iab,iab->i", self.gs, U)
        out = 2.0 * K * (2.0 * U - Ue[:-2] - Ue[2:])
        out += (2.0 * K * (2.0 * s[1:-1] - s[:-2] - s[2:]))[:, None, None] * self.gs
        if shift:
            out *= 1.0 + shift
        for k in range(K - 1):
            c = 2.0 * K * self.lap_f[k]
            if c != 0.0:
                out[k] += c * self.pen.hvp(self.X[k], U[k])
        return out

    def precondition(self, G: FloatArray) -> FloatArray:
        """Exact ``H_GN⁻¹ G``, ``H_GN = 2K(L ⊗ I) + 2K Fᵀ L F`` (Woodbury, O(K² N))."""
        y = np.einsum("ij,jab->iab", self.Linv, G)
        z = np.einsum("iab,iab->i", self.gs, y)
        w = np.linalg.solve(self.S.T, np.linalg.solve(self.S, z))
        return y - np.einsum("ij,jab->iab", self.Linv, w[:, None, None] * self.gs)


def _newton_cg_direction(G, hvp, prec, eta: float, max_cg: int) -> tuple[FloatArray, int, bool]:
    """Preconditioned truncated CG for ``H d = −G``; stops at negative curvature.

    Returns ``(d, CG iterations, negative curvature met)``.
    """
    x = np.zeros_like(G)
    r = -G
    z = prec(r)
    p = z.copy()
    rz = float(_dot(r, z))
    r0 = np.sqrt(max(rz, 0.0))
    for i in range(max_cg):
        Hp = hvp(p)
        pHp = float(_dot(p, Hp))
        if pHp <= 0.0:
            if i == 0:
                return z, 1, True
            # add the direction of negative curvature, oriented downhill, scaled like x
            # (the line search picks the length)
            nx, npn = np.sqrt(_dot(x, x)), np.sqrt(_dot(p, p))
            if npn > 0 and nx > 0:
                d = p if float(_dot(G, p)) <= 0 else -p
                return x + (nx / npn) * d, i + 1, True
            return x, i + 1, True
        a = rz / pHp
        x += a * p
        r -= a * Hp
        z = prec(r)
        rz_new = float(_dot(r, z))
        if np.sqrt(max(rz_new, 0.0)) <= eta * r0:
            return x, i + 1, False
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, max_cg, False


class _ArmijoTrial:
    """A trial step of the energy ``value`` along ``D`` from ``X`` (Armijo's test), and
    the steps to try: halved after a refused finite energy, quartered after an infinite
    one (outside the admissible set), down to 1e-14."""

    def __init__(self, value, X: FloatArray, D: FloatArray, E: float, slope: float) -> None:
        self.value, self.X, self.D, self.E, self.slope = value, X, D, E, slope
        self.finite = True
        self.steps = self._steps()

    def _steps(self):
        t = 1.0
        while t >= 1e-14:
            yield t
            t *= 0.5 if self.finite else 0.25

    def __call__(self, t: float) -> float | None:
        En = self.value(self.X + t * self.D)
        self.finite = bool(np.isfinite(En))
        return En if sufficient_decrease(En, self.E, t, self.slope) else None


def newton_cg(metric, Q0: FloatArray, Q1: FloatArray, K: int, path: FloatArray | None,
              options: NewtonCGOptions, callback=None) -> DiscreteGeodesic:
    """The K-segment discrete geodesic of a complete (or the Euclidean) metric from ``Q0``
    to ``Q1`` by Newton–CG; see :func:`.discrete_geodesic.discrete_geodesic`."""
    tol, energy_rtol, window = options.tolerance, options.energy_rtol, options.window
    max_iterations, max_cg = options.max_iterations, options.max_cg
    raw = penalty_of(metric)
    if raw is None:
        t = np.linspace(0.0, 1.0, K + 1)[:, None, None]
        pts = (1.0 - t) * Q0 + t * Q1
        d = np.diff(pts, axis=0)
        return DiscreteGeodesic(pts, np.full(K + 1, np.nan), float(K * _dot(d, d)),
                                float(np.linalg.norm(Q1 - Q0)))
    pen = _Counter(raw)
    f0 = _require_finite(pen, Q0, "the source")
    f1 = _require_finite(pen, Q1, "the target")
    if np.array_equal(Q0, Q1):  # the geodesic from a frame to itself stays there
        return DiscreteGeodesic(np.repeat(Q0[None], K + 1, axis=0), np.full(K + 1, f0), 0.0,
                                0.0, n_evaluations=pen.n)
    if path is None:
        path = initial_path(raw, Q0, Q1, K)
    path = _path_frames(path, Q0, Q1, K)
    if K == 1:
        fs = np.array([f0, f1])
        return DiscreteGeodesic(path, fs, float(_dot(Q1 - Q0, Q1 - Q0) + (f1 - f0) ** 2),
                                float(np.sqrt(_dot(Q1 - Q0, Q1 - Q0) + (f1 - f0) ** 2)),
                                n_evaluations=pen.n)
    pe = _PathEnergy(pen, Q0, Q1, K, f0, f1)
    X = path[1:-1].copy()
    if not np.isfinite(pe.value(X)):
        raise NotAdmissibleError("the initial path has an inadmissible frame")
    E, G = pe.evaluate(X)
    gnorm = float(np.sqrt(max(_dot(G, pe.precondition(G)), 0.0)))
    nit = 0
    n_cg = 0
    negative = False
    converged = gnorm <= tol * np.sqrt(E)
    status = "converged" if converged else "max_iter"
    energies = [E]
    while not converged and nit < max_iterations:
        nit += 1
        eta = min(0.5, np.sqrt(gnorm / max(np.sqrt(E), 1e-300)))
        D, n_cg, negative = _newton_cg_direction(G, pe.hvp, pe.precondition, eta, max_cg)
        slope = float(_dot(G, D))
        if slope >= 0:  # cannot happen with an SPD preconditioner; be safe
            D = -pe.precondition(G)
            slope = float(_dot(G, D))
        trial = _ArmijoTrial(pe.value, X, D, E, slope)
        found = backtrack(trial, trial.steps)
        if found is None:
            logger.info("discrete geodesic: line search failed at iteration %d", nit)
            status = "line_search"
            break
        t = found[0]
        X = X + t * D
        E, G = pe.evaluate(X)
        energies.append(E)
        gnorm = float(np.sqrt(max(_dot(G, pe.precondition(G)), 0.0)))
        converged = gnorm <= tol * np.sqrt(E)
        logger.debug("discrete geodesic %d: E = %.12g, |g| = %.3g, step %.3g, %d CG%s",
                     nit, E, gnorm, t, n_cg, " (negative curvature)" if negative else "")
        if callback is not None and callback(nit, E, gnorm) and not converged:
            status = "stopped"  # the callback returned True
            break
        if converged:
            status = "converged"
        elif (energy_rtol > 0 and nit >= window
              and energies[-1 - window] - E <= energy_rtol * window * E):
            status = "stationary"
            break
    pts = pe._frames(X)
    fs = pe.fs
    length = float(np.sum(np.sqrt(np.sum(np.diff(pts, axis=0) ** 2, axis=(1, 2))
                                  + np.diff(fs) ** 2)))
    return DiscreteGeodesic(pts, fs.copy(), E, length, nit, gnorm, bool(converged), pen.n,
                            status)
