"""``benchmarks/_arap_contact.py`` (ARAP with IPC contact, the clean peer of
``bench_surface_clean_peer.py``): its ARAP energy against ``_surface_measures``'
independent one, Taylor tests of the energy's gradient and Hessian-vector product, and a
small two-sheet push that plain ARAP drives through itself and the peer keeps clean."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
pytest.importorskip("ipctk")
pytest.importorskip("igl")
pytest.importorskip("trimesh")
import _arap_contact as ac  # noqa: E402
import _surface_measures as sm  # noqa: E402
import bench_surface as bench  # noqa: E402

from meshopt_toolkit.kernels.intersections3d import self_intersections  # noqa: E402


def two_sheets(gap: float = 0.2, spacing: float = 0.1):
    """A 1×1 sheet at z = 0 and a 0.8×0.3 strip over its middle at z = ``gap`` (one
    mesh; the sheet's 121 vertices first)."""
    A, FA = bench.strip_surface(1.0, 1.0, spacing)
    B, FB = bench.strip_surface(0.8, 0.3, spacing)
    B = B + np.array([0.1, 0.35, gap])
    return np.concatenate([A, B]), np.concatenate([FA, FB + len(A)])


def push_case() -> bench.Case:
    """The strip's middle band (|x − 0.5| ≤ 0.1) pushed from z = 0.2 down to z = −0.15,
    its ends (|x − 0.5| ≥ 0.3) and the sheet's rim fixed: the strip must go through the
    sheet unless something pushes the sheet out of its way."""
    V, F = two_sheets()
    sheet = np.arange(len(V)) < 121
    rim = sheet & ((V[:, 0] < 1e-9) | (V[:, 0] > 1 - 1e-9) | (V[:, 1] < 1e-9)
                   | (V[:, 1] > 1 - 1e-9))
    middle = np.flatnonzero(~sheet & (np.abs(V[:, 0] - 0.5) <= 0.1 + 1e-9))
    fixed = np.flatnonzero(rim | (~sheet & (np.abs(V[:, 0] - 0.5) >= 0.3 - 1e-9)))
    drop = np.array([0.0, 0.0, -0.35])
    return bench.Case("push", V, F, np.concatenate([middle, fixed]),
                      lambda t: np.concatenate([V[middle] + t * drop, V[fixed]]),
                      np.r_[np.ones(len(middle)), np.zeros(len(fixed))])


def taylor_slope(f, g, x, v, eps=np.logspace(-2.5, -4.5, 5)) -> float:
    """Observed order of |f(x + εv) − f(x) − ε g·v| over ε (2 for a right derivative)."""
    r = [abs(f(x + e * v) - f(x) - e * g) for e in eps]
    return float(np.polyfit(np.log(eps), np.log(r), 1)[0])


@pytest.fixture
def deformed(rng):
    """The two sheets 0.005 apart (inside dhat = 0.01), gently perturbed."""
    V0, F = two_sheets(gap=0.005)
    X = V0 + 1e-3 * rng.standard_normal(V0.shape) * np.array([1.0, 1.0, 0.1])
    X[:, 2] += 0.05 * np.sin(3 * V0[:, 0])
    return V0, F, X


def test_arap_value_is_the_measured_energy(deformed):
    V0, F, X = deformed
    assert ac.Arap.from_mesh(V0, F).value(X) == pytest.approx(sm.arap_energy(V0, X, F),
                                                              rel=1e-12)


def test_energy_gradient_passes_the_taylor_test(deformed, rng):
    V0, F, X = deformed
    arap, contact = ac.Arap.from_mesh(V0, F), ac.Contact(V0, F, 0.01)
    assert len(contact.collisions(X)) > 0  # the barrier is active
    kappa = 10.0

    def energy(Y):
        return arap.value(Y) + kappa * contact.value(Y)

    g = arap.gradient(X) + kappa * contact.gradient(X)
    V = rng.standard_normal(X.shape) * 1e-3
    assert taylor_slope(energy, float(g @ V.ravel()), X, V) > 1.9


def test_hessian_vector_product_passes_the_taylor_test(deformed, rng):
    # the Newton model: the global quadratic at fixed rotations (its gradient affine, so
    # exact to rounding) plus the barrier (the pairs in reach stay the same over the ε used)
    V0, F, X = deformed
    arap, contact = ac.Arap.from_mesh(V0, F), ac.Contact(V0, F, 0.01)
    R = arap.rotations(X)
    V = rng.standard_normal(X.shape) * 1e-3
    step = arap.gradient(X + V, R) - arap.gradient(X, R)
    assert np.allclose(step, arap.H @ V.ravel(), rtol=1e-9, atol=1e-12 * np.abs(step).max())
    u = rng.standard_normal(X.size)
    hv = float(u @ (contact.hessian(X, project=False) @ V.ravel()))
    slope = taylor_slope(lambda Y: float(u @ contact.gradient(Y)), hv, X, V,
                         eps=np.logspace(-3, -5, 5))
    assert slope > 1.9


def test_plain_arap_pushes_the_strip_through_the_sheet():
    case = push_case()
    U = bench.arap_incremental(case, 10)
    assert len(self_intersections(U, case.F)) > 0


def test_the_peer_keeps_the_two_sheets_apart():
    case = push_case()
    result = ac.arap_contact(case.V, case.F, case.handles, case.path, steps=5,
                             max_iterations=20)
    assert result.message == ""
    assert np.array_equal(result.points[case.handles], case.path(1.0))
    assert len(self_intersections(result.points, case.F)) == 0
    assert result.kappa > 0  # the sheets touched
