"""The surface metric's path model (motion.surface.path) through discrete_geodesic: the
minimum is MINPACK's on the same residuals, the result's energy, length and initial energy
are those of its frames; the model refuses a free subset or an anchor; and
levenberg_marquardt runs a path model's own iteration rules (their damped-step
arguments, stop rules and the iteration limit)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import least_squares
from test_surface_morph import bent, tube

from meshopt_toolkit.errors import NotAdmissibleError, OptionError
from meshopt_toolkit.least_squares import DampedStep
from meshopt_toolkit.motion.surface.bending import dihedral_angles, wrap
from meshopt_toolkit.motion.surface.interpolation import arap_interpolation
from meshopt_toolkit.motion.surface.metric import SurfaceGraphMetric
from meshopt_toolkit.motion.surface.path import SurfacePathOptions
from meshopt_toolkit.riemannian.discrete_geodesic import discrete_geodesic
from meshopt_toolkit.riemannian.geodesic_result import DiscreteGeodesic
from meshopt_toolkit.riemannian.levenberg_marquardt import levenberg_marquardt
from meshopt_toolkit.riemannian.path_options import LevenbergMarquardtOptions


def test_discrete_geodesic_of_the_surface_metric_is_minpacks():
    V0, F = tube(6, 4, length=2.0)
    V1 = bent(V0, np.pi / 3, length=2.0)
    metric, K = SurfaceGraphMetric(V0, F), 3
    start = np.array(arap_interpolation(V0, V1, F, np.linspace(0.0, 1.0, K + 1)))
    geo = discrete_geodesic(metric, V0, V1, K, path=start,
                            options=SurfacePathOptions(max_iterations=60, rtol=1e-13))
    assert geo.status in ("converged", "stalled") and geo.nit > 2
    np.testing.assert_array_equal(geo.points[0], V0)
    np.testing.assert_array_equal(geo.points[-1], V1)

    def residual(x):  # the embedding (m^½ Q, w φ, √c θ) of the metric, segment by segment
        Q = [V0] + list(x.reshape(K - 1, -1, 3)) + [V1]
        X = [np.concatenate([metric.sqrt_m * P.ravel(), metric.weight
                             * metric.membrane.values(P).ravel()]) for P in Q]
        th = [dihedral_angles(P, metric.shell.diamonds) for P in Q]
        return np.concatenate([np.concatenate([X[k + 1] - X[k], metric.sqrt_c
                                               * wrap(th[k + 1] - th[k])]) for k in range(K)])

    def jacobian(x):
        D = [metric.jacobian(P) for P in [V0] + list(x.reshape(K - 1, -1, 3)) + [V1]]
        return sp.bmat([[D[j] if j == k + 1 else -D[j] if j == k else None
                         for j in range(1, K)] for k in range(K)]).toarray()

    x0 = start[1:-1].ravel()
    assert geo.initial_energy == pytest.approx(0.5 * residual(x0) @ residual(x0), rel=1e-12)
    r = residual(geo.points[1:-1].ravel())
    assert geo.energy == pytest.approx(0.5 * r @ r, rel=1e-12)
    assert geo.length == pytest.approx(sum(np.linalg.norm(v) for v in np.split(r, K)),
                                       rel=1e-12)
    assert geo.factorizations > 0
    peer = least_squares(residual, x0, jac=jacobian, method="lm", xtol=1e-15, ftol=1e-15,
                         gtol=1e-15)
    assert geo.energy == pytest.approx(peer.cost, rel=1e-9)
    np.testing.assert_allclose(geo.points[1:-1].ravel(), peer.x, atol=1e-6)


def test_the_path_model_refuses_a_free_subset_and_an_anchor():
    V0, F = tube(6, 4, length=2.0)
    frames = np.array([V0, V0, bent(V0, 1.0, length=2.0)])
    free = np.zeros(frames.shape[:2], bool)
    free[1] = True
    metric = SurfaceGraphMetric(V0, F)
    assert metric.path_model(frames, free).n_unknowns == V0.size
    part = free.copy()
    part[1, 0] = False
    with pytest.raises(OptionError, match="every vertex"):
        metric.path_model(frames, part)
    with pytest.raises(OptionError, match="no anchor"):
        metric.path_model(frames, free, anchor=np.zeros((len(F), 3)))
    flat = frames.copy()
    flat[1, :, 2] = 0.0  # the tube pressed flat: every triangle along z degenerate
    with pytest.raises(NotAdmissibleError, match="initial path"):
        discrete_geodesic(metric, frames[0], frames[-1], 2, path=flat,
                          options=SurfacePathOptions())


class _Rules:
    """Minimizes ½(x − 3)² by damped Newton steps ``−(x − 3)/(1 + λ)``, λ halved per step;
    stops where |x − 3| < tol. Records what the loop asked."""

    def __init__(self, tol):
        self.x, self.tol, self.damping, self.calls = 0.0, tol, 1.0, []

    def start(self):
        self.calls.append("start")

    def before_step(self, callback):
        self.calls.append("before")

    def solve(self, damping, attempt):
        return np.array([-(self.x - 3.0) / (1.0 + damping)])

    def try_step(self, step, t):
        x = self.x + t * step[0]
        return x if (x - 3.0) ** 2 < (self.x - 3.0) ** 2 else None

    def step_arguments(self):
        return dict(attempts=1, update=lambda lam, t, x: lam / 2.0)

    def after_step(self, found, callback):
        assert isinstance(found, DampedStep) and found.accepted
        self.calls.append("after")
        self.x = found.payload
        return "converged" if abs(self.x - 3.0) < self.tol else None

    def result(self, status):
        self.calls.append(status)
        return DiscreteGeodesic(np.zeros((2, 1, 3)), np.full(2, np.nan), 0.0, 0.0)


class _Model:
    def __init__(self, rules):
        self.rules = rules

    def iteration_rules(self, frames, options):
        return self.rules


@pytest.mark.parametrize("max_iterations", [2, 50])
def test_levenberg_marquardt_runs_the_models_iteration_rules(max_iterations):
    rules = _Rules(1e-6)
    levenberg_marquardt(_Model(rules), np.zeros((2, 1, 3)),
                        LevenbergMarquardtOptions(max_iterations=max_iterations))
    x, lam, expected = 0.0, 1.0, 0  # the recurrence, independently
    while abs(x - 3.0) >= 1e-6 and expected < max_iterations:
        x, lam, expected = x - (x - 3.0) / (1.0 + lam), lam / 2.0, expected + 1
    assert rules.x == x and rules.damping == lam
    status = "converged" if abs(x - 3.0) < 1e-6 else None
    assert (status is None) == (max_iterations == 2)
    assert rules.calls == ["start"] + ["before", "after"] * expected + [status]


def test_the_metric_keeps_its_path_problem_and_its_measures_by_frame_values():
    V0, F = tube(6, 4, length=2.0)
    V1 = bent(V0, np.pi / 3, length=2.0)
    metric = SurfaceGraphMetric(V0, F)
    problem = metric.path_problem(V1)
    assert metric.path_problem(V1.copy()) is problem
    assert metric.path_model(np.array([V0, V1]), np.zeros((2, len(V0)), bool)
                             ).problem is problem
    calls, mask = [], problem.folds.mask
    problem.folds.mask = lambda Q: calls.append(Q) or mask(Q)
    Q = 0.5 * (V0 + V1)
    first = problem.fold_mask(Q)
    assert problem.fold_mask(Q.copy()) is first and len(calls) == 1
    moved = Q.copy()
    moved[0, 0] += 1e-12
    problem.fold_mask(moved)
    assert len(calls) == 2
    assert metric.path_problem(V0) is not problem
