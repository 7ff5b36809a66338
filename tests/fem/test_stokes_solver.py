"""The Stokes solves (fem.stokes_solver): block MINRES over the scalar Laplacian's factor
against the Schur complement's direct solve, the true residual it reaches, the size rule,
and the pressure mass and scalar Laplacian against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from fem_helpers import box_mesh
from test_stokes import obstacle
from meshopt_toolkit.fem.simplex import LagrangeSpace, geometry
from meshopt_toolkit.fem.stokes import StokesDissipation
from meshopt_toolkit.fem.stokes_solver import (MINRES_FROM_3D, pressure_mass, scalar_laplacian,
                                               stokes_method, stokes_saddle_solve)


def obstacle_flow(d, solver, rtol=1e-11):
    """The unit box without its central cube, the cube moving along ``x``."""
    P, T, outer, body = obstacle(d, 4, jitter=0.2)
    j = StokesDissipation(P, T, [(outer, np.zeros(d)), (body, np.eye(d)[0])], mu=0.7,
                          solver=solver, rtol=rtol)
    return P, j


@pytest.mark.parametrize("d", [2, 3])
def test_minres_over_the_laplacian_equals_the_direct_solve(d):
    P, direct = obstacle_flow(d, "direct")
    _, minres = obstacle_flow(d, "minres")
    assert minres.method == "minres" and direct.method == "direct"
    # both solves to the residual 1e-11 (each in its own norm): agreement to ~1e-7
    assert np.isclose(minres.value(P), direct.value(P), rtol=1e-9)
    np.testing.assert_allclose(minres.velocity(P), direct.velocity(P), atol=1e-6)
    np.testing.assert_allclose(minres.pressure(P), direct.pressure(P),
                               atol=2e-6 * np.abs(direct.pressure(P)).max())
    np.testing.assert_allclose(minres.derivative(P), direct.derivative(P),
                               atol=1e-7 * np.abs(direct.derivative(P)).max())


@pytest.mark.parametrize("method", ["minres", "amg"])
def test_minres_meets_the_residual(method):
    P, j = obstacle_flow(3, "direct")
    geo = geometry(P, j.cells)
    A, B = j.matrices(P, geo)
    free = np.setdiff1d(np.arange(A.shape[0]), j.dirichlet)
    nodes = free[::3] // 3
    g = j._lift(P)  # the Dirichlet velocities' lift: the solves' right-hand side
    b = -np.concatenate([(A @ g)[free], (B @ g)[1:]])
    A, B = A[free][:, free], B[1:, free]
    mass = pressure_mass(geo, j.cells, len(P))[1:, 1:]
    rtol = 1e-9
    x = stokes_saddle_solve(method, A, B, mass, 0.7, rtol, space=j.space, geo=geo,
                            free_nodes=nodes, node_points=j.space.dof_points(P)[nodes])(b)
    K = sp.bmat([[A, B.T], [B, None]], format="csr")
    # MINRES stops on the preconditioned residual (scaled by its estimate of ‖K‖‖x‖): the
    # Euclidean one, mixing velocity and pressure rows, is within a few orders
    assert np.linalg.norm(b - K @ x) <= 1e4 * rtol * np.linalg.norm(b)


def test_the_size_rule():
    assert stokes_method("auto", MINRES_FROM_3D - 1, 3) == "direct"
    assert stokes_method("auto", MINRES_FROM_3D, 3) == "minres"
    assert stokes_method("auto", MINRES_FROM_3D, 2) == "direct"
    assert stokes_method("direct", 10 * MINRES_FROM_3D, 3) == "direct"
    assert stokes_method("minres", 10, 2) == "minres"
    with pytest.raises(ValueError):
        obstacle_flow(2, "cholesky")


@pytest.mark.parametrize("d", [2, 3])
def test_pressure_mass_and_laplacian_against_closed_forms(d):
    lengths = np.array([2.0, 1.0, 1.5][:d])
    P, T, _ = box_mesh(d, 3, jitter=0.3, lengths=lengths)
    geo = geometry(P, T)
    M = pressure_mass(geo, T, len(P))
    x, y = P[:, 0], P[:, 1]
    volume = np.prod(lengths)
    # P1 holds x and y exactly: ∫ x y over the box
    assert np.isclose(x @ M @ y, volume * lengths[0] * lengths[1] / 4, rtol=1e-12)
    space = LagrangeSpace(T, len(P), degree=2)
    L = scalar_laplacian(space, geo, 0.7)
    X = space.dof_points(P)
    f = X[:, 0] ** 2  # P2 holds x²: ∫ |∇x²|² = 4 ∫ x² = 4 |Ω| Lx² / 3
    assert np.isclose(f @ L @ f, 0.7 * 4 * volume * lengths[0] ** 2 / 3, rtol=1e-12)
    assert np.abs(L @ np.ones(len(X))).max() < 1e-12
