"""The objective registry (shape.objectives): every objective by name on planar and tet
meshes with physical groups, the planar Poisson objectives unchanged through it."""

from __future__ import annotations

import numpy as np
import pytest

from fem_helpers import box_mesh
from meshopt_toolkit.fem.simplex import all_boundary_facets as boundary_facets
from meshopt_toolkit.errors import OptionError
from meshopt_toolkit.fem.linear_elasticity import ComplianceObjective
from meshopt_toolkit.fem.poisson import PoissonObjective
from meshopt_toolkit.fem.poisson_simplex import SimplexPoisson
from meshopt_toolkit.fem.stokes import StokesDissipation
from meshopt_toolkit.mesh import PlanarMesh, TetMesh
from meshopt_toolkit.shape.objectives import (OBJECTIVE_REGISTRY, make_objective,
                                              register_objective)
from meshopt_toolkit.shape.spec import ProblemSpec

pytest.importorskip("skfem")


def tagged(d, n=3, jitter=0.2):
    """The unit box with its facets tagged ``left`` (x = 0, tag 1), ``right`` (x = 1, tag
    2) and ``wall`` (tag 3)."""
    P, T, _ = box_mesh(d, n, jitter=jitter)
    F = boundary_facets(T)
    x = P[F][..., 0]
    tags = np.where(np.all(x < 1e-12, axis=1), 1, np.where(np.all(x > 1 - 1e-12, axis=1), 2, 3))
    names = {"left": (1, d - 1), "right": (2, d - 1), "wall": (3, d - 1)}
    if d == 2:
        return PlanarMesh(P, T, lines=F, line_tags=tags, tag_names=names)
    return TetMesh(P, T, triangles=F, triangle_tags=tags, tag_names=names)


def test_every_objective_is_registered_for_both_dimensions():
    assert set(OBJECTIVE_REGISTRY) >= {"integral", "tracking", "compliance", "dissipation"}
    for entry in OBJECTIVE_REGISTRY.values():
        assert entry.dims == (2, 3) and entry.description


@pytest.mark.parametrize("objective", ["integral", "tracking: x*y"])
def test_planar_problem_spec_objective_is_unchanged(objective):
    mesh = tagged(2)
    spec = ProblemSpec(dirichlet={"left": 0.5}, neumann={"right": 1.0}, objective=objective,
                       rhs="1 + x")
    j = spec.make_objective(mesh)
    target = None if objective == "integral" else "x*y"
    ref = PoissonObjective(mesh, rhs="1 + x", tracking=target, dirichlet={"left": 0.5},
                           neumann={"right": 1.0})
    assert isinstance(j, PoissonObjective)
    Q = mesh.points
    assert j.value(Q) == ref.value(Q)
    np.testing.assert_array_equal(j.derivative(Q), ref.derivative(Q))


def test_poisson_on_a_tet_mesh_by_groups():
    mesh = tagged(3)
    j = make_objective("tracking", mesh, target="z", rhs=2.0, dirichlet={"left": 0.5})
    lift = np.zeros(mesh.n_vertices)
    lift[mesh.tagged_vertices("left")] = 0.5
    b = mesh.boundary_vertices
    ref = SimplexPoisson(mesh.tets, b, 2.0, dirichlet_values=lift[b], tracking="z")
    assert np.isclose(j.value(mesh.points), ref.value(mesh.points), rtol=1e-14)
    with pytest.raises(OptionError):
        make_objective("integral", mesh, neumann={"right": 1.0})


@pytest.mark.parametrize("d", [2, 3])
def test_compliance_by_groups(d):
    mesh = tagged(d)
    stress = np.eye(d)
    j = make_objective("compliance", mesh, clamped="left", tractions={"right": stress,
                                                                     "wall": 0.2}, degree=2)
    assert isinstance(j, ComplianceObjective)
    P = np.asarray(mesh.points)
    # Σ N_F vanishes over the closed boundary and is e_1 on x = 1: the pressure on the
    # walls (neither x = 0 nor x = 1) sums to zero, the total load is the pull (1, 0, …)
    np.testing.assert_allclose(j.load(P).sum(axis=0), np.eye(d)[0], atol=1e-13)
    facets = np.asarray(mesh.triangles if d == 3 else mesh.lines)
    tags = mesh.triangle_tags if d == 3 else mesh.line_tags
    cells = mesh.tets if d == 3 else mesh.triangles
    ref = ComplianceObjective(P, cells, facets[tags == 1],
                              [(facets[tags == 2], stress), (facets[tags == 3], -0.2 * np.eye(d))],
                              degree=2)
    assert np.isclose(j.value(P), ref.value(P), rtol=1e-13)


@pytest.mark.parametrize("d", [2, 3])
def test_dissipation_by_groups(d):
    mesh = tagged(d)
    e = np.eye(d)[1]
    j = make_objective("dissipation", mesh, velocities={"right": e}, mu=2.0, solver="direct")
    assert isinstance(j, StokesDissipation)
    # u = e on x = 1 only, u = 0 on every other boundary facet
    u = j.velocity(mesh.points)
    right = np.unique(j.space.facet_dofs(np.asarray(mesh.triangles if d == 3 else mesh.lines)[
        (mesh.triangle_tags if d == 3 else mesh.line_tags) == 2]))
    np.testing.assert_array_equal(u[right], np.broadcast_to(e, (len(right), d)))
    assert j.value(mesh.points) > 0


def test_unknown_names_and_dimensions_are_refused():
    with pytest.raises(OptionError, match="unknown objective"):
        make_objective("drag", tagged(2))

    @register_objective("planar-only test", (2,), "a test entry")
    def planar_only(mesh):
        return mesh

    try:
        with pytest.raises(OptionError, match="dimensions"):
            make_objective("planar-only test", tagged(3))
        with pytest.raises(OptionError, match="registered already"):
            register_objective("planar-only test", (2,), "again")(planar_only)
    finally:
        del OBJECTIVE_REGISTRY["planar-only test"]
