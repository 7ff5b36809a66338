"""Compliance of a body with no clamped group: rigid motions pinned without stress."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fem_helpers import box_mesh, random_direction
from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.fem.linear_elasticity import (ComplianceObjective, elastic_lame,
                                                   rigid_modes, rigid_pins)
from meshopt_toolkit.fem.simplex import all_boundary_facets

pytest.importorskip("skfem")


def _uniform_compliance(sigma, volume, E, nu):
    """``σ : C⁻¹ σ |Ω|`` of a uniform stress (closed form: the strain is uniform)."""
    d = len(sigma)
    lam, mu = elastic_lame(E, nu, d)
    tr = np.trace(sigma)
    eps = (sigma - lam / (2 * mu + d * lam) * tr * np.eye(d)) / (2 * mu)
    return float(np.sum(sigma * eps)) * volume


@pytest.mark.parametrize("d, degree", [(2, 1), (2, 2), (3, 1), (3, 2)])
def test_uniform_stress_on_a_floating_box_has_the_closed_form(d, degree):
    # a box under a uniform boundary stress: the state is the uniform strain C⁻¹σ
    lengths = [2.0, 1.0, 1.5][:d]
    P, T, _ = box_mesh(d, 3, jitter=0.3, lengths=lengths)
    sigma = np.array([[2.0, 0.5, 0.1], [0.5, 1.0, -0.3], [0.1, -0.3, 0.7]])[:d, :d]
    J = ComplianceObjective(P, T, np.zeros((0, d), int), [(all_boundary_facets(T), sigma)],
                            E=3.0, nu=0.25, degree=degree)
    assert J.value(P) == pytest.approx(_uniform_compliance(sigma, np.prod(lengths), 3.0, 0.25),
                                       rel=1e-9)


@pytest.mark.parametrize("d", [2, 3])
def test_floating_compliance_derivative_is_exact(d):
    P, T, _ = box_mesh(d, 3, jitter=0.3)
    sigma = np.diag([2.0, 1.0, 0.5][:d])
    J = ComplianceObjective(P, T, np.zeros((0, d), int), [(all_boundary_facets(T), sigma)])
    res = check_gradient(J.value, J.derivative, P, random_direction(P), eps0=1e-2)
    assert abs(res.order - 2) < 0.1, res


@settings(max_examples=25, deadline=None)
@given(st.integers(2, 3), st.integers(0, 10_000))
def test_pins_remove_exactly_the_rigid_motions(d, seed):
    P = np.random.default_rng(seed).standard_normal((12, d))
    pins = rigid_pins(P)
    R = rigid_modes(P)
    assert len(pins) == d * (d + 1) // 2 == R.shape[1]
    assert np.linalg.matrix_rank(R[pins]) == R.shape[1]
