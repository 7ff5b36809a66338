"""The distortion metric's least-squares path (motion/planar/path.py): residuals, normal
equations and Newton's matrix, and its discrete geodesics (Levenberg–Marquardt).
"""

from __future__ import annotations

import numpy as np
import pytest
from motion_helpers import _random_admissible, _straight_path

from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.motion.planar.path import GraphPath
from meshopt_toolkit.riemannian.discrete_geodesic import discrete_geodesic


def _geodesic(metric, frames, free, boundary_edges=None, anchor=None, **settings):
    """The Levenberg–Marquardt discrete geodesic from the initial path ``frames``."""
    return discrete_geodesic(metric, frames[0], frames[-1], len(frames) - 1, path=frames,
                             free=free, boundary_edges=boundary_edges, anchor=anchor,
                             options=settings)


def test_path_energy_gradient_taylor(disc, rng):
    P, T = disc.points, disc.triangles
    frames = np.array([P] + [_random_admissible(disc, rng, 0.1 * k) for k in (1, 2, 3)])
    free = np.ones((4, disc.n_vertices), bool)
    free[0] = False
    free[3, :3] = False
    metric = GraphMetric(P, T, 1.7, triangle_weights=1 + rng.uniform(0, 1, len(T)))
    path = GraphPath(metric, frames, free, None, anchor_strain=None)
    x0 = path.unknowns(frames)

    def E(x):
        r, _ = path.evaluate(path.with_unknowns(x), jacobian=False)
        return float(r @ r)

    def grad(x):
        r, J = path.evaluate(path.with_unknowns(x), jacobian=True)
        return 2 * (J.T @ r)

    result = check_gradient(E, grad, x0, eps0=1e-3, rng=rng)
    assert abs(result.order - 2) < 0.2, result


@pytest.mark.parametrize("K, anchored, uneven", [(4, False, False), (4, False, True),
                                                 (4, False, "split"), (1, True, False),
                                                 (1, False, False)])
def test_normal_equations_match_the_sparse_jacobian(disc, rng, K, anchored, uneven):
    """The Gauss–Newton system assembled from per-triangle blocks is ``Jᵀr`` and ``JᵀJ``
    of the sparse Jacobian, with fixed vertices, weights and an anchor, with frames that
    fix different vertices (``uneven``) and with a fixed frame between two free ones."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    if K > 1:
        free[-1] = False
    free[:, np.unique(disc.boundary_edges)[:5]] = False
    if uneven is True:
        free[2, rng.choice(disc.n_vertices, 7, replace=False)] = False
        free[1, :3] = False
    if uneven == "split":
        free[2] = False
    metric = GraphMetric(P, disc.triangles, 1.3,
                         triangle_weights=1 + rng.random(disc.n_triangles))
    anchor = metric.strain.values(P) + 0.1 if anchored else None
    path = GraphPath(metric, frames, free, None, anchor_strain=anchor)
    r, J = path.evaluate(frames, jacobian=True)
    r2, g, H, scaling = path.normal_equations(frames)
    assert np.array_equal(r, r2)
    gJ, HJ = J.T @ r, (J.T @ J).toarray()
    assert np.abs(g - gJ).max() <= 1e-12 * np.abs(gJ).max()
    assert np.abs(H.tocsr().toarray() - HJ).max() <= 1e-12 * np.abs(HJ).max()
    assert np.abs(scaling - np.diag(HJ)).max() <= 1e-12 * np.abs(HJ).max()
    # Newton's matrix (Taylor-tested below): the same gradient and scaling, symmetric
    r3, g3, H3, scaling3 = path.normal_equations(frames, newton=True)
    assert np.array_equal(r3, r) and np.array_equal(g3, g) and np.array_equal(scaling3, scaling)
    assert abs(H3.tocsr() - H3.tocsr().T).max() <= 1e-12 * np.abs(HJ).max()


@pytest.mark.parametrize("K, anchored", [(4, False), (1, True)])
def test_newton_matrix_is_the_hessian_of_the_path_energy(disc, rng, K, anchored):
    """Second-order Taylor test: ``E(x + εv) − E − ε∇E·v − ½ε² vᵀ(2H)v = O(ε³)`` with H
    the Newton matrix (``∇E = 2g``), for a path and for an anchored single frame."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, K + 1)])
    free = np.ones((K + 1, disc.n_vertices), bool)
    free[0] = False
    free[:, np.unique(disc.boundary_edges)[:5]] = False
    metric = GraphMetric(P, disc.triangles, 1.3,
                         triangle_weights=1 + rng.random(disc.n_triangles))
    anchor = metric.strain.values(P) + 0.1 if anchored else None
    path = GraphPath(metric, frames, free, None, anchor_strain=anchor)

    def E(x):
        r, _ = path.evaluate(path.with_unknowns(x), jacobian=False)
        return float(r @ r)

    def grad(x):
        return 2 * path.normal_equations(path.with_unknowns(x))[1]

    def hvp(x, v):
        return 2 * (path.normal_equations(path.with_unknowns(x), newton=True)[2] @ v)

    result = check_hvp(E, grad, hvp, path.unknowns(frames), eps0=1e-3, rng=rng)
    assert abs(result.order - 3) < 0.2, result
    gauss_newton = check_hvp(E, grad, lambda x, v: 2 * (path.normal_equations(
        path.with_unknowns(x))[2] @ v), path.unknowns(frames), eps0=1e-3, rng=rng)
    assert gauss_newton.order < 2.5  # the test can tell the Gauss–Newton matrix apart


def test_discrete_geodesic_damps_more_where_the_newton_matrix_is_indefinite(
        disc, rng, monkeypatch):
    """A step whose solve meets non-positive curvature is rejected and the damping grows:
    the path still converges, to the same frames as without the failure."""
    from meshopt_toolkit.motion.planar.frame_blocks import FrameBlocks

    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    free = np.ones((2, disc.n_vertices), bool)
    free[0] = False
    free[1, np.unique(disc.boundary_edges)] = False
    metric = GraphMetric(P, disc.triangles)
    frames = np.stack([P, P])
    anchor = metric.strain.values(target)
    reference = _geodesic(metric, frames, free, anchor=anchor, newton=True)
    calls = []
    solve = FrameBlocks.solve

    def fail_once(self, A, b, rtol):
        calls.append(len(calls))
        if len(calls) == 1:
            self.stale = True
            raise FloatingPointError("conjugate gradients broke down (pᵀAp ≤ 0)")
        return solve(self, A, b, rtol)

    monkeypatch.setattr(FrameBlocks, "solve", fail_once)
    result = _geodesic(metric, frames, free, anchor=anchor, newton=True)
    assert len(calls) > 1 and result.converged and reference.converged
    assert np.abs(result.points - reference.points).max() <= 1e-5 * np.abs(P).max()


def test_discrete_geodesic_converges_and_lowers_energy(disc, rng):
    frames, free, metric = _straight_path(disc, rng)
    P, target = frames[0], frames[-1]
    r0, _ = GraphPath(metric, frames, free, None).evaluate(frames, jacobian=False)
    res = _geodesic(metric, frames, free, boundary_edges=disc.boundary_edges)
    assert res.converged and res.energy <= float(r0 @ r0)
    assert res.gradient_norm <= 1e-7 * max(1, np.sqrt(res.energy))
    assert np.array_equal(res.points[0], P) and np.array_equal(res.points[-1], target)


def test_discrete_geodesic_at_machine_precision_is_converged(disc):
    """With ``gtol = 0`` (unreachable) the path stops where no step can lower the energy
    beyond its rounding nor its gradient (steps E cannot judge are judged by |∇E|), and
    says converged, not stalled: the gradient is then at its floating-point floor (8e-13
    with this seed; judging those steps by E alone stopped at 2.6e-9)."""
    rng = np.random.default_rng(1)
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, 4)])
    free = np.ones((4, disc.n_vertices), bool)
    free[[0, -1]] = False
    res = _geodesic(GraphMetric(P, disc.triangles), frames, free, gtol=0.0,
                            max_iterations=200)
    assert res.status == "converged" and res.nit < 200
    assert res.gradient_norm <= 1e-10 * max(1.0, np.sqrt(res.energy))


def test_discrete_geodesic_without_an_admissible_trial_is_stalled(disc, rng, monkeypatch):
    """Where every trial step leaves M+ nothing is known about the energy: the path says
    stalled, never converged."""
    P = disc.points
    target = _random_admissible(disc, rng, 0.3)
    frames = np.array([(1 - s) * P + s * target for s in np.linspace(0, 1, 4)])
    free = np.ones((4, disc.n_vertices), bool)
    free[[0, -1]] = False
    checks = []

    def only_the_start(self, frames):  # the initial path passes, no trial does
        checks.append(1)
        return len(checks) == 1

    monkeypatch.setattr(GraphPath, "admissible", only_the_start)
    res = _geodesic(GraphMetric(P, disc.triangles), frames, free)
    assert res.status == "stalled" and len(checks) == 31


def test_discrete_geodesic_relative_stop(disc, rng):
    """``rtol`` stops a relaxation once the gradient fell by that factor: converged, the
    gradient at most ``rtol`` times the first one, in fewer iterations than the full solve."""
    frames, free, metric = _straight_path(disc, rng)
    full = _geodesic(metric, frames, free)
    quick = _geodesic(metric, frames, free, rtol=1e-3)
    assert quick.converged and quick.nit < full.nit
    assert quick.gradient_norm <= 1e-3 * full.history[0][1]
