"""Enclosed measure, barycenter and their exact constraint set (shape/constraints.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import Delaunay

from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.errors import InvalidMeshError, OptionError
from meshopt_toolkit.kernels.tetrahedra import signed_volumes
from meshopt_toolkit.mesh.volume import TetMesh
from meshopt_toolkit.shape.area import AreaConstraint
from meshopt_toolkit.shape.constraints import (
    ExactConstraints,
    barycenter,
    barycenter_gradient,
    body_facets,
    enclosed_measure,
    first_moments,
    measure_gradient,
    moments_gradient,
)


def loop(n: int, start: int = 0) -> np.ndarray:
    """Directed edges of the closed loop ``start, …, start + n − 1``."""
    i = np.arange(n)
    return np.column_stack([start + i, start + (i + 1) % n])


def ngon(n: int, radius: float = 1.0, centre=(0.0, 0.0)) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([np.cos(t), np.sin(t)]) * radius + centre


def oriented(points, tets) -> np.ndarray:
    tets = np.array(tets)
    neg = signed_volumes(points, tets) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return tets


def cube_mesh(n: int = 2) -> TetMesh:
    """[0, 1]³ cut into n³ cubes of six tetrahedra each."""
    x = np.linspace(0, 1, n + 1)
    pts = np.stack(np.meshgrid(x, x, x, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    corner = [idx[i:i + n or None, j:j + n or None, k:k + n or None].ravel()
              for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    paths = [(1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6)]  # Kuhn: 0 → a → b → 7
    tets = np.concatenate([np.column_stack([corner[0], corner[a], corner[b], corner[7]])
                           for a, b in paths])
    return TetMesh(pts, oriented(pts, tets))


def ball_points(seed: int, n_surface: int = 60, n_inner: int = 30, centre=(0.0, 0.0, 0.0)):
    r = np.random.default_rng(seed)
    s = r.standard_normal((n_surface, 3))
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    inner = r.standard_normal((n_inner, 3))
    inner *= (0.8 * r.uniform(size=(n_inner, 1)) ** (1 / 3)) / np.linalg.norm(inner, axis=1,
                                                                             keepdims=True)
    return np.concatenate([s, inner]) + centre


def ball_mesh(seed: int = 0, centre=(0.0, 0.0, 0.0)) -> TetMesh:
    pts = ball_points(seed, centre=centre)
    return TetMesh(pts, oriented(pts, Delaunay(pts).simplices))


# -- closed forms and peers ------------------------------------------------------------


def test_unit_square_and_disc_polygon():
    sq = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    assert enclosed_measure(sq, loop(4)) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(barycenter(sq, loop(4)), [0.5, 0.5], atol=1e-15)
    n, c = 64, np.array([0.3, -1.2])
    P = ngon(n, 2.0, c)
    assert enclosed_measure(P, loop(n)) == pytest.approx(0.5 * n * 4.0 * np.sin(2 * np.pi / n))
    np.testing.assert_allclose(barycenter(P, loop(n)), c, atol=1e-13)
    # clockwise: the signed area flips, the barycenter does not
    assert enclosed_measure(P, loop(n)[:, ::-1]) < 0
    np.testing.assert_allclose(barycenter(P, loop(n)[:, ::-1]), c, atol=1e-13)


def test_hole_is_a_body_of_its_own():
    """A square with a square hole: the domain's boundary is the outer loop CCW and the
    hole CW; the hole's body is the region it encloses, positive."""
    outer = np.array([[0.0, 0], [4, 0], [4, 4], [0, 4]])
    hole = np.array([[1.0, 1], [2, 1], [2, 2], [1, 2]])
    Q = np.concatenate([outer, hole])
    facets = np.concatenate([loop(4), loop(4, 4)[:, ::-1]])
    assert enclosed_measure(Q, facets) == pytest.approx(15.0)
    np.testing.assert_allclose(first_moments(Q, facets), 16 * 2.0 - 1 * 1.5)
    inner = body_facets(Q, facets, np.arange(4, 8))
    assert enclosed_measure(Q, inner) == pytest.approx(1.0)
    np.testing.assert_allclose(barycenter(Q, inner), [1.5, 1.5])


def test_obstacle_of_a_physical_group(tmp_path):
    """The channel's rotated 0.3 × 0.3 square obstacle, found by its physical group."""
    pytest.importorskip("gmsh")
    from meshopt_toolkit.io import load
    from meshopt_toolkit.shape.cases import user_mesh

    mesh = load(user_mesh("channel", tmp_path / "channel.msh", 0.2)).as_planar()
    Q, E = np.asarray(mesh.points), mesh.boundary_edges
    square = body_facets(Q, E, mesh.tagged_vertices("square"))
    disc = body_facets(Q, E, mesh.tagged_vertices("disc"))
    assert enclosed_measure(Q, square) == pytest.approx(0.09, abs=1e-14)
    np.testing.assert_allclose(barycenter(Q, square), [1.95, 0.5], atol=1e-14)
    assert enclosed_measure(Q, E) == pytest.approx(
        3.0 - 0.09 - enclosed_measure(Q, disc), abs=1e-14)


def test_unit_cube():
    mesh = cube_mesh(3)
    Q, F = np.asarray(mesh.points), mesh.boundary_faces
    assert enclosed_measure(Q, F) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(barycenter(Q, F), [0.5, 0.5, 0.5], atol=1e-14)


def test_ball_against_tets_and_trimesh():
    trimesh = pytest.importorskip("trimesh")
    mesh = ball_mesh(3, centre=(0.2, -0.1, 0.4))
    Q, F, T = np.asarray(mesh.points), mesh.boundary_faces, np.asarray(mesh.tets)
    vol = signed_volumes(Q, T)
    centroids = Q[T].mean(axis=1)
    assert enclosed_measure(Q, F) == pytest.approx(vol.sum(), rel=1e-13)
    np.testing.assert_allclose(first_moments(Q, F), vol @ centroids, rtol=1e-12, atol=1e-14)
    surface = trimesh.Trimesh(Q, F, process=False)
    assert enclosed_measure(Q, F) == pytest.approx(surface.volume, rel=1e-12)
    np.testing.assert_allclose(barycenter(Q, F), surface.center_mass, atol=1e-12)


def test_one_body_among_two():
    a, b = ball_mesh(1), ball_mesh(2, centre=(3.0, 0.0, 0.0))
    Q = np.concatenate([a.points, b.points])
    T = np.concatenate([a.tets, np.asarray(b.tets) + len(a.points)])
    mesh = TetMesh(Q, T)
    F = body_facets(Q, mesh.boundary_faces, np.arange(len(a.points), len(Q)))
    vb = signed_volumes(Q, T[len(a.tets):])
    assert enclosed_measure(Q, F) == pytest.approx(vb.sum(), rel=1e-13)
    np.testing.assert_allclose(barycenter(Q, F),
                               vb @ Q[T[len(a.tets):]].mean(axis=1) / vb.sum(), atol=1e-12)


# -- Taylor tests ----------------------------------------------------------------------


def cases():
    r = np.random.default_rng(5)
    P = ngon(12, 1.0, (0.4, 0.1)) + 0.05 * r.standard_normal((12, 2))
    ball = ball_mesh(4, centre=(0.5, 0.2, -0.3))
    return [(P, loop(12)), (np.asarray(ball.points), ball.boundary_faces)]


@pytest.mark.parametrize("case", [0, 1], ids=["2d", "3d"])
def test_taylor(case, rng):
    Q, F = cases()[case]
    v = rng.standard_normal(Q.shape)
    res = check_gradient(lambda X: enclosed_measure(X, F), lambda X: measure_gradient(X, F),
                         Q, v, eps0=1e-2)
    assert res.passed and res.usable.sum() >= 4, res
    for i in range(Q.shape[1]):
        for f, g in ((first_moments, moments_gradient), (barycenter, barycenter_gradient)):
            res = check_gradient(lambda X: f(X, F)[i], lambda X: g(X, F)[i], Q, v, eps0=1e-2)
            assert res.passed and res.usable.sum() >= 4, (f.__name__, i, res)


# -- the constraint set ----------------------------------------------------------------


def diagonal_riesz(weights, free):
    """``G⁻¹P`` for ``G = diag(weights)`` on the free vertices, zero on the fixed ones."""
    def riesz(Q, P):
        return np.where(free[:, None], P / weights[:, None], 0.0)
    return riesz


@settings(max_examples=25, deadline=None)
@given(case=st.sampled_from([0, 1]), seed=st.integers(0, 2**31 - 1),
       size=st.floats(1e-4, 3e-2), which=st.sampled_from([(True, False), (False, True),
                                                          (True, True)]))
def test_restore_and_project(case, seed, size, which):
    Q0, F = cases()[case]
    r = np.random.default_rng(seed)
    n, d = Q0.shape
    free = r.uniform(size=n) < 0.7
    weights = r.uniform(0.5, 2.0, n)
    c = ExactConstraints(F, Q0, diagonal_riesz(weights, free), measure=which[0],
                         barycenter=which[1])
    X = Q0 + size * r.standard_normal(Q0.shape)
    J, N, _ = c.normals(Q0)
    R = c.restore(X, N)
    assert R is not None
    assert np.all(np.abs(c.values(R) - c.target) <= 1e-10 * c.scale)
    np.testing.assert_array_equal(R[~free], X[~free])
    # projection: tangent (∇c·W = 0 means G-orthogonal to every N_j) and idempotent
    V = np.where(free[:, None], r.standard_normal(Q0.shape), 0.0)  # a direction: G⁻¹P
    W = c.project(Q0, V)
    np.testing.assert_array_equal(W[~free], 0.0)
    tangent = np.einsum("inx,nx->i", J, W)
    assert np.all(np.abs(tangent) <= 1e-12 * np.linalg.norm(J.reshape(len(J), -1), axis=1)
                  * np.linalg.norm(V))
    np.testing.assert_allclose(c.project(Q0, W), W, atol=1e-12 * np.linalg.norm(V))
    # V − W lies in span N, G-orthogonal to the tangent W: <V − W, W>_G = 0
    gap = weights[:, None] * (V - W)
    assert abs(np.sum(gap * W)) <= 1e-10 * np.linalg.norm(V) ** 2 * weights.max()


def test_newton_matches_the_area_quadratic():
    """Measure only in 2D: Newton along N reaches the point AreaConstraint's quadratic root
    gives."""
    Q0, F = cases()[0]
    r = np.random.default_rng(9)
    free = np.ones(len(Q0), bool)
    riesz = diagonal_riesz(r.uniform(0.5, 2, len(Q0)), free)
    c = ExactConstraints(F, Q0, riesz)
    area = AreaConstraint(F, enclosed_measure(Q0, F), riesz)
    X = Q0 + 0.02 * r.standard_normal(Q0.shape)
    _, N, _ = c.normals(Q0)
    np.testing.assert_allclose(c.restore(X, N), area.restore(X, N[0]), rtol=0, atol=1e-13)
    np.testing.assert_allclose(c.project(Q0, X), area.project(Q0, X), atol=1e-13)


def test_restore_fails_without_free_vertices():
    Q0, F = cases()[1]
    c = ExactConstraints(F, Q0, diagonal_riesz(np.ones(len(Q0)), np.zeros(len(Q0), bool)),
                         barycenter=True)
    _, N, _ = c.normals(Q0)
    assert c.restore(Q0 + 1e-3, N) is None


def test_far_from_the_origin():
    """A unit ball 1000 away from the origin: values and restoration keep their digits."""
    Q0 = np.asarray(ball_mesh(4).points)
    F = ball_mesh(4).boundary_faces
    shift = np.array([1e3, 1e3, 0.0])
    assert enclosed_measure(Q0 + shift, F) == pytest.approx(enclosed_measure(Q0, F), rel=1e-13)
    np.testing.assert_allclose(barycenter(Q0 + shift, F) - shift, barycenter(Q0, F), atol=1e-12)
    c = ExactConstraints(F, Q0 + shift, diagonal_riesz(np.ones(len(Q0)), np.ones(len(Q0), bool)),
                         barycenter=True)
    X = Q0 + shift + 0.01 * np.random.default_rng(1).standard_normal(Q0.shape)
    R = c.restore(X, c.normals(Q0 + shift)[1])
    assert R is not None and np.all(np.abs(c.values(R) - c.target) <= 1e-12 * c.scale)


def test_curve_stays_on_the_constraints_with_tangent_velocities():
    """The retraction curve: points hold ``c``, velocities are tangent at them and are the
    curve's derivative (central differences, error O(h²))."""
    Q0, F = cases()[1]
    r = np.random.default_rng(3)
    free = r.uniform(size=len(Q0)) < 0.8
    c = ExactConstraints(F, Q0, diagonal_riesz(r.uniform(0.5, 2, len(Q0)), free),
                         barycenter=True)
    d = c.project(Q0, np.where(free[:, None], r.standard_normal(Q0.shape), 0.0))
    d *= 0.1 / np.abs(d).max()
    retract = c.curve(Q0)
    (R,), (V,) = retract(Q0, d, [0.5])
    assert np.all(np.abs(c.values(R) - c.target) <= 1e-12 * c.scale)
    J = c.jacobian(R)
    assert np.all(np.abs(np.einsum("inx,nx->i", J, V)) <= 1e-12 * np.abs(J).sum() * np.abs(V).max())
    errors = []
    for h in (1e-2, 5e-3):
        (Rp, Rm), _ = retract(Q0, d, [0.5 + h, 0.5 - h])
        errors.append(np.abs((Rp - Rm) / (2 * h) - V).max())
    assert errors[1] < 0.3 * errors[0] and errors[1] < 1e-3 * np.abs(V).max()


def test_refusals():
    sq = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    with pytest.raises(InvalidMeshError, match="do not bound"):
        enclosed_measure(sq, np.array([[0, 1, 2]]))
    with pytest.raises(InvalidMeshError, match="no boundary facet"):
        body_facets(sq, loop(4), [0, 2])
    riesz = diagonal_riesz(np.ones(4), np.ones(4, bool))
    with pytest.raises(OptionError, match="no constraint"):
        ExactConstraints(loop(4), sq, riesz, measure=False)
    with pytest.raises(InvalidMeshError, match="encloses no"):
        ExactConstraints(np.array([[0, 1], [1, 0]]), sq, riesz, barycenter=True)
