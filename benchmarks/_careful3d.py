"""A careful optimizer of tet-mesh motion, the quality reference of the 3D benchmark.

Continuation along the handles' path: each step moves the handles a little, predicts the
free nodes by the harmonic extension of that increment (or, where that inverts a tet, by
the last step's velocity, or keeps them; it halves the step where all three invert), then minimizes the exponential AMIPS energy
``(1/s) log Σ_e exp(s q_e)`` with ``q_e = tr(AᵀA) / (3 det(A)^{2/3}) = 1/η_e`` (``A`` the
map from the regular tet, ``η`` the mean ratio) by L-BFGS, whose backtracking line search
refuses every trial with an inverted tet. Slow (minutes at 25k tets) but never inverts.
"""

from __future__ import annotations

import time

import numpy as np
from _anchors3d import dirichlet_solve, laplacian

_I, _J = np.triu_indices(4, 1)


def inverse_mean_ratios(x, tets):
    """``q = Σℓ² / (12 (3V)^{2/3}) = 1/η`` per tet, and its gradient (C, 4, 3);
    ``q = inf`` where ``V ≤ 0``."""
    p = x[tets]
    D = np.swapaxes(p[:, 1:] - p[:, :1], 1, 2)
    det = np.linalg.det(D)
    ok = det > 0
    q = np.full(len(tets), np.inf)
    grad = np.zeros((len(tets), 4, 3))
    if not ok.all():
        return q, grad
    e = p[:, _I] - p[:, _J]
    sq = np.einsum("cek,cek->c", e, e)
    den = 12.0 * (det / 2.0) ** (2.0 / 3.0)  # 12 (3V)^{2/3} with V = det/6
    q = sq / den
    # d Σℓ² / dx_a = 2 (4 x_a − Σ_b x_b)
    dsq = 2.0 * (4.0 * p - p.sum(axis=1, keepdims=True))
    # d det / dD = det D^{-T}: columns are the gradients w.r.t. x_1, x_2, x_3
    cof = det[:, None, None] * np.swapaxes(np.linalg.inv(D), 1, 2)
    ddet = np.empty_like(p)
    ddet[:, 1:] = np.swapaxes(cof, 1, 2)
    ddet[:, 0] = -ddet[:, 1:].sum(axis=1)
    grad = dsq / den[:, None, None] - (2.0 / 3.0) * (q / det)[:, None, None] * ddet
    return q, grad


class _Energy:
    """``F(x_free) = (1/s) log Σ exp(s q_e)`` with the handles fixed; ``inf`` if inverted."""

    def __init__(self, tets, n, free, s):
        self.tets, self.n, self.free, self.s = tets, n, free, s
        self.flat = tets.ravel()

    def __call__(self, x):
        q, g = inverse_mean_ratios(x, self.tets)
        if not np.isfinite(q).all():
            return np.inf, None
        m = q.max()
        w = np.exp(self.s * (q - m))
        total = w.sum()
        F = m + np.log(total) / self.s
        gq = (w / total)[:, None, None] * g
        G = np.column_stack([np.bincount(self.flat, gq[:, :, k].ravel(), self.n)
                             for k in range(3)])
        return F, G[self.free]


def lbfgs(energy, x, free, iterations: int, memory: int = 10, tol: float = 1e-9):
    """Minimize ``energy`` over ``x[free]`` from a valid ``x``; every trial point with an
    inverted tet (energy ``inf``) is refused by halving the step. Returns the new ``x``."""
    x = x.copy()
    F, G = energy(x)
    S, Y = [], []
    for _ in range(iterations):
        d = -G.ravel().copy()
        alphas = []
        for s_, y_ in reversed(list(zip(S, Y))):
            a = s_ @ d / (y_ @ s_)
            alphas.append(a)
            d -= a * y_
        if S:
            d *= (S[-1] @ Y[-1]) / (Y[-1] @ Y[-1])
        else:
            d *= 1e-3 / max(np.abs(d).max(), 1e-300)
        for (s_, y_), a in zip(zip(S, Y), reversed(alphas)):
            b = y_ @ d / (y_ @ s_)
            d += (a - b) * s_
        slope = G.ravel() @ d
        if slope >= 0:  # not a descent direction: restart from steepest descent
            S, Y = [], []
            continue
        step, trial = 1.0, x.copy()
        while step > 1e-12:
            trial[free] = x[free] + step * d.reshape(-1, 3)
            F1, G1 = energy(trial)
            if np.isfinite(F1) and F1 <= F + 1e-4 * step * slope:
                break
            step *= 0.5
        else:
            break
        s_, y_ = (trial[free] - x[free]).ravel(), (G1 - G).ravel()
        x, done = trial, F - F1 <= tol * max(abs(F), 1.0)
        F, G = F1, G1
        if s_ @ y_ > 1e-16:
            S.append(s_)
            Y.append(y_)
            if len(S) > memory:
                S.pop(0)
                Y.pop(0)
        if done:
            break
    return x


def careful_motion(points, tets, handles, path, steps: int = 20, sharpness: float = 1.0,
                   iterations: int = 60, final_iterations: int = 600,
                   max_seconds: float = np.inf) -> np.ndarray:
    """Continuation along ``path`` (see the module docstring): ``steps`` nominal steps,
    ``iterations`` L-BFGS iterations per step and ``final_iterations`` at the end; the
    energy's ``sharpness`` ``s`` weighs the worst tets (``s → ∞``: the worst one alone).

    Raises
    ------
    RuntimeError
        Where the continuation cannot advance without inverting a tet, or has not reached
        the end of the path after ``max_seconds``.
    """
    start = time.perf_counter()
    n = len(points)
    free = np.ones(n, bool)
    free[handles] = False
    energy = _Energy(np.asarray(tets), n, free, sharpness)
    L = laplacian(points, tets)
    x, t, dt = np.array(points, float), 0.0, 1.0 / steps
    velocity = np.zeros_like(x)  # the free nodes' motion per unit t in the last step
    while t < 1.0:
        if time.perf_counter() - start > max_seconds:
            raise RuntimeError(f"not done in {max_seconds:.0f} s (at t = {t:.3f})")
        t1 = min(1.0, t + dt)
        moved = dirichlet_solve(L, handles, path(t1) - x[handles])
        kept = np.where(free[:, None], 0.0, moved)
        predictors = (x + moved, x + kept + (t1 - t) * velocity, x + kept)
        valid = [p for p in predictors if np.isfinite(energy(p)[0])]
        if not valid:
            dt *= 0.5
            if dt < 1e-4:
                raise RuntimeError(f"continuation stalled at t = {t:.4f}")
            continue
        x1 = lbfgs(energy, valid[0], free, final_iterations if t1 >= 1.0 else iterations)
        velocity = np.where(free[:, None], (x1 - x) / (t1 - t), 0.0)
        x, t, dt = x1, t1, min(2.0 * dt, 1.0 / steps)
    return x
