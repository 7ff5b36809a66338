"""The cell kinds (meshopt_toolkit/cells): each kind agrees with the kernels it delegates to,
with closed forms and with independent peers, and keeps the invariants of its measures,
quality, distortion and admissibility under similarities and reflections."""

from __future__ import annotations

import numpy as np
import pytest
from cell_meshes import CASES, perturbed, rotation
from hypothesis import given, settings
from hypothesis import strategies as st

from meshopt_toolkit.cells.base import CellKind, SimplexKind, scale_free_mass
from meshopt_toolkit.cells.planar import PLANAR
from meshopt_toolkit.cells.surface import SURFACE
from meshopt_toolkit.cells.tetrahedra import TETRAHEDRA
from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.kernels import surface as ks
from meshopt_toolkit.kernels import tetrahedra as kt
from meshopt_toolkit.kernels import triangles as ktri
from meshopt_toolkit.mesh import SurfaceMesh, TetMesh, TriangleMesh
from meshopt_toolkit.motion.surface import move as surface_move
from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.motion.surface.distortion import SurfaceDistortion
from meshopt_toolkit.motion.tets.distortion import TetDistortion
from meshopt_toolkit.motion.tets.metric import TetGraphMetric

FAST = settings(max_examples=12, deadline=None)
KINDS = pytest.mark.parametrize("name", sorted(CASES))
seeds = st.integers(0, 2**31 - 1)


def test_every_kind_implements_the_interface():
    for kind in (PLANAR, SURFACE, TETRAHEDRA):
        assert isinstance(kind, CellKind) and isinstance(kind, SimplexKind)
    assert not isinstance(object(), CellKind)


def test_the_kinds_agree_with_the_kernels_they_delegate_to():
    P, T = CASES["planar"][1]()
    np.testing.assert_array_equal(PLANAR.measures(P, T), ktri.signed_areas(P, T))
    np.testing.assert_array_equal(PLANAR.quality(P, T), ktri.aspect_ratios(P, T))
    np.testing.assert_array_equal(PLANAR.lumped_mass(P, T),
                                  scale_free_mass(P, T, np.abs(ktri.signed_areas(P, T))))
    np.testing.assert_array_equal(GraphMetric(P, T).mass, PLANAR.lumped_mass(P, T))
    np.testing.assert_array_equal(PLANAR.boundary_facets(P, T), TriangleMesh(P, T).boundary_edges)
    V, F = CASES["surface"][1]()
    np.testing.assert_array_equal(SURFACE.measures(V, F), ks.areas(V, F))
    np.testing.assert_array_equal(SURFACE.quality(V, F), ks.aspect_ratios(V, F))
    np.testing.assert_array_equal(SURFACE.lumped_mass(V, F), surface_move.lumped_mass(V, F))
    np.testing.assert_array_equal(SURFACE.boundary_facets(V, F), SurfaceMesh(V, F).boundary_edges)
    W = perturbed(V, 1, 0.02)
    np.testing.assert_array_equal(SURFACE.jacobians(W, F, V), SurfaceDistortion(V, F).affine_maps(W))
    X, C = CASES["tets"][1]()
    np.testing.assert_array_equal(TETRAHEDRA.measures(X, C), kt.signed_volumes(X, C))
    np.testing.assert_array_equal(TETRAHEDRA.quality(X, C), kt.mean_ratios(X, C))
    np.testing.assert_array_equal(TETRAHEDRA.lumped_mass(X, C),
                                  scale_free_mass(X, C, np.abs(kt.signed_volumes(X, C))))
    np.testing.assert_array_equal(TetGraphMetric(X, C).mass, TETRAHEDRA.lumped_mass(X, C))
    np.testing.assert_array_equal(TETRAHEDRA.boundary_facets(X, C), TetMesh(X, C).boundary_faces)
    Y = perturbed(X, 2, 0.02)
    np.testing.assert_array_equal(TETRAHEDRA.jacobians(Y, C, X), TetDistortion(X, C).affine_maps(Y))


@KINDS
@FAST
@given(seed=seeds)
def test_jacobians_map_rest_measures_to_current_ones(name, seed):
    # the closed form: |cell| = √det(AᵀA)·|rest cell| (det A·|rest| where A is square)
    kind, make = CASES[name]
    P, C = make(seed=seed % 1000)
    Q = perturbed(P, seed, 0.01)
    A = kind.jacobians(Q, C, P)
    assert A.shape == (len(C), kind.point_dimension, kind.cell_dimension)
    gram = np.linalg.det(np.swapaxes(A, 1, 2) @ A)
    np.testing.assert_allclose(np.sqrt(gram) * np.abs(kind.measures(P, C)),
                               np.abs(kind.measures(Q, C)), rtol=1e-9)
    if kind.point_dimension == kind.cell_dimension:
        np.testing.assert_allclose(np.linalg.det(A) * kind.measures(P, C), kind.measures(Q, C),
                                   rtol=1e-9)
    if name != "surface":  # the identity at the rest shape itself
        np.testing.assert_allclose(kind.jacobians(P, C, P), np.broadcast_to(
            np.eye(kind.point_dimension), A.shape), atol=1e-12)


@pytest.mark.parametrize("name", ["planar", "tets"])
@FAST
@given(seed=seeds)
def test_the_lumped_mass_integrates_linear_functions_exactly(name, seed):
    # the unit square and cube (boundary not jittered): Σ m_i x_i / Σ m_i is the centroid ½
    kind, make = CASES[name]
    P, C = make(seed=seed % 1000)
    m = kind.lumped_mass(P, C)
    np.testing.assert_allclose(m @ P / m.sum(), 0.5, rtol=1e-12)
    # Σ m_i |x_i − c|² = 1: the mass is divided by its own mean squared spread
    np.testing.assert_allclose(m @ np.sum((P - 0.5) ** 2, axis=1), 1.0, rtol=1e-12)
    assert (m > 0).all()


def test_surface_areas_and_boundary_agree_with_trimesh():
    trimesh = pytest.importorskip("trimesh")
    V, F = CASES["surface"][1]()
    tm = trimesh.Trimesh(V, F, process=False)
    np.testing.assert_allclose(SURFACE.measures(V, F), tm.area_faces, rtol=1e-12)
    ours = {frozenset(e) for e in SURFACE.boundary_facets(V, F).tolist()}
    edges, counts = np.unique(np.sort(tm.edges, axis=1), axis=0, return_counts=True)
    assert ours == {frozenset(e) for e in edges[counts == 1].tolist()}


@KINDS
@FAST
@given(seed=seeds, log_scale=st.floats(-3, 3), shift=st.floats(-10, 10))
def test_similarities_scale_measures_and_keep_quality_and_shape(name, seed, log_scale, shift):
    kind, make = CASES[name]
    P, C = make(seed=seed % 1000)
    Q = perturbed(P, seed, 0.01)
    s = float(np.exp(log_scale))
    R = rotation(kind, seed)
    S = s * Q @ R.T + shift
    d = kind.cell_dimension
    np.testing.assert_allclose(kind.measures(S, C), s**d * kind.measures(Q, C), rtol=1e-9)
    np.testing.assert_allclose(kind.quality(S, C), kind.quality(Q, C), rtol=1e-8, atol=1e-12)
    phi_q = kind.distortion(P, C).values(Q)
    phi_s = kind.distortion(P, C).values(S)
    # a scaling by s moves the first (volumetric) component by √d·log s only
    np.testing.assert_allclose(phi_s[:, 0], phi_q[:, 0] + np.sqrt(d) * np.log(s), atol=1e-8)
    np.testing.assert_allclose(phi_s[:, 1:], phi_q[:, 1:], atol=1e-8)
    rigid = Q @ R.T + shift
    np.testing.assert_allclose(kind.distortion(P, C).values(rigid), phi_q, atol=1e-9)
    np.testing.assert_allclose(kind.lumped_mass(S, C), kind.lumped_mass(Q, C) / s**2,
                               rtol=1e-8)
    assert kind.admissibility_problem(S, C) is None
    assert not kind.fold_test(S, C, P).any()


@pytest.mark.parametrize("name", ["planar", "tets"])
def test_a_reflected_cell_is_negative_inadmissible_and_folded(name):
    kind, make = CASES[name]
    P, C = make()
    mirror = P.copy()
    mirror[:, 0] *= -1
    assert (kind.measures(mirror, C) < 0).all() and (kind.quality(mirror, C) < 0).all()
    assert kind.fold_test(mirror, C, P).all()
    assert "inverted" in kind.admissibility_problem(mirror, C) or "area" in \
        kind.admissibility_problem(mirror, C)
    one = C[:1]
    assert kind.admissibility_problem(P, one) is None
    assert kind.admissibility_problem(mirror, one) is not None


def across_a_facet(P, C):
    """``P`` with the interior vertex nearest the centre reflected through the plane (line)
    of its opposite facet in its first cell, and that cell."""
    v = int(np.argmin(np.linalg.norm(P - 0.5, axis=1)))
    c = int(np.flatnonzero((C == v).any(1))[0])
    base = P[[i for i in C[c] if i != v]]
    if P.shape[1] == 2:
        n = np.array([base[0, 1] - base[1, 1], base[1, 0] - base[0, 0]])
    else:
        n = np.cross(base[1] - base[0], base[2] - base[0])
    n /= np.linalg.norm(n)
    Q = P.copy()
    Q[v] -= 2 * np.dot(P[v] - base[0], n) * n
    return Q, c


@pytest.mark.parametrize("name", ["planar", "tets"])
def test_one_vertex_across_its_opposite_facet_folds_exactly_the_negative_cells(name):
    kind, make = CASES[name]
    P, C = make(jitter=0.0)
    Q, c = across_a_facet(P, C)
    folded = kind.fold_test(Q, C, P)
    assert folded[c]
    np.testing.assert_array_equal(folded, kind.measures(Q, C) <= 0)
    assert kind.admissibility_problem(Q, C) is not None


def test_a_flat_surface_folds_where_the_plane_does():
    # a surface in z = 0 against the planar kind's exact orientations (an independent test)
    P, T = CASES["planar"][1](n=6, jitter=0.2)
    Q, c = across_a_facet(P, T)
    expect = PLANAR.fold_test(Q, T, P)
    assert expect[c]
    lift = np.zeros((len(P), 1))
    np.testing.assert_array_equal(SURFACE.fold_test(np.hstack([Q, lift]), T,
                                                    np.hstack([P, lift])), expect)


def test_surface_admissibility_names_collinear_and_crossing_triangles():
    V, F = CASES["surface"][1]()
    assert SURFACE.admissibility_problem(V, F) is None
    flat = V.copy()
    flat[F[0, 2]] = 0.5 * (V[F[0, 0]] + V[F[0, 1]])
    assert "collinear" in SURFACE.admissibility_problem(flat, F)
    # a second sheet standing in the plane y = 0.5 cuts through the bump
    wall = np.column_stack([V[:, 0], np.full(len(V), 0.5), V[:, 1] - 0.5])
    both = np.vstack([V, wall]), np.vstack([F, F + len(V)])
    assert "intersect" in SURFACE.admissibility_problem(*both)
    apart = np.vstack([V, wall + [0.0, 2.0, 0.0]]), both[1]
    assert SURFACE.admissibility_problem(*apart) is None
    bad = V.copy()
    bad[3, 1] = np.nan
    assert "vertex 3" in SURFACE.admissibility_problem(bad, F)


@KINDS
@FAST
@given(seed=seeds, amount=st.floats(0.0, 0.01))
def test_distortion_gradient_through_the_interface_taylor(name, seed, amount):
    kind, make = CASES[name]
    P, C = make(seed=seed % 1000)
    Q = perturbed(P, seed, amount)
    m = kind.distortion(P, C).n_components
    rho = np.random.default_rng(seed + 1).standard_normal((len(C), m))

    def f(X):
        return float(np.sum(rho * kind.distortion(P, C).values(X)))

    def grad(X):
        return kind.distortion_gradient(X, C, P, rho)[1]

    result = check_gradient(f, grad, Q, eps0=1e-3, rng=seed)
    assert result.order > 1.8, result
