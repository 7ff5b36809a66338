"""Shared by the tests of the motion package (tests/motion/): hypothesis settings, similar
and random admissible meshes, a straight path, random rotations of R³, the weighted sum of
a distortion with its derivatives (Taylor tests) and the rate it bounds."""

from __future__ import annotations

import numpy as np
from hypothesis import settings

from meshopt_toolkit.motion.planar.metric import GraphMetric


FAST = settings(max_examples=15, deadline=None)



def _similar(points, angle, scale, shift):
    c, s = np.cos(angle), np.sin(angle)
    return scale * points @ np.array([[c, -s], [s, c]]).T + np.asarray(shift)



def _random_admissible(mesh, rng, amplitude):
    """An affine image of ``mesh`` plus a small perturbation, admissible by construction:
    ``A = I + a·B`` with ``‖B‖₂ ≤ ‖B‖_F ≤ 1`` and ``a < 1`` keeps ``det A > 0``; the noise is
    halved until no triangle inverts (the affine image alone is admissible)."""
    assert amplitude < 1
    A = np.eye(2) + amplitude * rng.uniform(-0.5, 0.5, (2, 2))
    Q = mesh.points @ A.T + rng.uniform(-1, 1, 2)
    noise = 0.05 * amplitude / np.sqrt(mesh.n_vertices) * rng.standard_normal(Q.shape)
    while not (mesh.with_points(Q + noise).signed_areas() > 0).all():
        noise /= 2
    return Q + noise



def _straight_path(disc, rng, K=4):
    """Frames on the straight line to a random admissible target, ends fixed."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = free[-1] = False
    return frames, free, GraphMetric(P, disc.triangles)


def record_damped_steps(monkeypatch, module) -> list:
    """``(damping, DampedStep)`` of every call of ``module.damped_step`` from now on (the
    least-squares step a minimizer takes, :mod:`meshopt_toolkit.least_squares`)."""
    steps, damped_step = [], module.damped_step

    def spy(solve, try_step, damping, **kwargs):
        out = damped_step(solve, try_step, damping, **kwargs)
        steps.append((damping, out))
        return out

    monkeypatch.setattr(module, "damped_step", spy)
    return steps


def random_rotation(rng) -> np.ndarray:
    """A uniformly random rotation of R³ (det +1)."""
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q * np.linalg.det(q)


def distortion_functional(dist, weights, columns, second=None):
    """``f(X) = Σ ρ·φ(X)`` of the distortion ``dist`` with weights ``ρ = weights`` (C, m), its
    gradient through the assembled Jacobian and its Hessian-vector product through the
    per-cell ``dist.second_order`` (``second`` maps its output to (C, K, K) blocks),
    scattered to the coordinates ``columns`` (C, K)."""
    second = (lambda H: H) if second is None else second

    def f(X):
        return float(np.sum(weights * dist.values(X)))

    def grad(X):
        _, blocks = dist.values_and_jacobian(X)
        return (dist.jacobian_matrix(blocks).T @ weights.ravel()).reshape(X.shape)

    def hvp(X, V):
        local = np.matmul(second(dist.second_order(X, weights)),
                          V.ravel()[columns][:, :, None])[:, :, 0]
        return np.bincount(columns.ravel(), local.ravel(), minlength=V.size).reshape(V.shape)

    return f, grad, hvp


def rates(dist, Q, V):
    """Per cell: ``|J V|`` of the distortion ``dist`` at ``Q`` and the affine-invariant rate
    ``½‖C^{-½} Ċ C^{-½}‖_F`` (``C = AᵀA``) that it bounds from above."""
    _, blocks = dist.values_and_jacobian(Q)
    rate = np.linalg.norm(np.einsum("tij,tj->ti", blocks, V.ravel()[dist.columns()]), axis=1)
    A, dA = dist.affine_maps(Q), dist.affine_maps(V)
    C = np.swapaxes(A, 1, 2) @ A
    dC = np.swapaxes(dA, 1, 2) @ A + np.swapaxes(A, 1, 2) @ dA
    lam, U = np.linalg.eigh(C)
    root = U @ (lam[:, :, None] ** -0.5 * np.swapaxes(U, 1, 2))
    return rate, 0.5 * np.linalg.norm(root @ dC @ root, axis=(1, 2))
