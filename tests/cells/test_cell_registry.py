"""kind_of/cells_of on every mesh object the package takes, their errors, and metric_for:
each kind's default metric implements mt.Metric on (N, d) points and is the morph's."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from cell_meshes import planar, surface, tets

import meshopt_toolkit as mt
from meshopt_toolkit.cells.planar import PLANAR
from meshopt_toolkit.cells.registry import KINDS, cells_of, kind_of, metric_for
from meshopt_toolkit.cells.surface import SURFACE
from meshopt_toolkit.cells.tetrahedra import TETRAHEDRA
from meshopt_toolkit.errors import InvalidMeshError, NotAdmissibleError, OptionError
from meshopt_toolkit.motion.planar.metric import GraphMetric
from meshopt_toolkit.motion.surface.morph import _PathProblem
from meshopt_toolkit.motion.tets.metric import TetGraphMetric
from meshopt_toolkit.riemannian.metrics import MetricNotImplementedError


def _ours():
    P, T = planar()
    V, F = surface()
    X, C = tets()
    return {"planar": mt.PlanarMesh(P, T), "triangle": mt.TriangleMesh(P, T),
            "z0": mt.TriangleMesh(np.column_stack([P, np.zeros(len(P))]), T),
            "surface": mt.SurfaceMesh(V, F), "tets": mt.TetMesh(X, C)}


def test_kind_of_our_meshes():
    m = _ours()
    assert kind_of(m["planar"]) is PLANAR and kind_of(m["triangle"]) is PLANAR
    kind, points, cells = cells_of(m["z0"])
    assert kind is PLANAR and points.shape[1] == 2
    assert kind_of(m["surface"]) is SURFACE and kind_of(m["tets"]) is TETRAHEDRA
    assert set(KINDS) == {"planar triangles", "surface triangles", "tetrahedra"}


def test_kind_of_trimesh_and_pymeshlab_meshes():
    trimesh = pytest.importorskip("trimesh")
    pymeshlab = pytest.importorskip("pymeshlab")
    V, F = surface()
    kind, points, cells = cells_of(trimesh.Trimesh(V, F, process=False))
    assert kind is SURFACE
    np.testing.assert_array_equal(points, V)
    np.testing.assert_array_equal(cells, F)
    kind, points, cells = cells_of(pymeshlab.Mesh(V, F))
    assert kind is SURFACE
    np.testing.assert_array_equal(points, V)
    np.testing.assert_array_equal(cells, F)


def test_kind_of_meshio_meshes():
    P, T = planar()
    V, F = surface()
    X, C = tets()
    assert kind_of(meshio.Mesh(P, [("triangle", T)])) is PLANAR
    assert kind_of(meshio.Mesh(np.column_stack([P, np.zeros(len(P))]),
                               [("triangle", T), ("line", T[:, :2])])) is PLANAR
    assert kind_of(meshio.Mesh(V, [("triangle", F), ("vertex", [[0]])])) is SURFACE
    # tetrahedra with their tagged boundary triangles beside them
    kind, points, cells = cells_of(meshio.Mesh(X, [("triangle", C[:, :3]), ("tetra", C)]))
    assert kind is TETRAHEDRA
    np.testing.assert_array_equal(cells, C)


@pytest.mark.parametrize("blocks, named", [
    ([("hexahedron", np.arange(8)[None])], "hexahedra"),
    ([("tetra", np.arange(4)[None]), ("hexahedron", np.arange(8)[None])], "hexahedra"),
    ([("triangle", [[0, 1, 2]]), ("quad", [[0, 1, 2, 3]])], "quadrilaterals"),
    ([("line", [[0, 1]])], "only lines"),
    ([], "no cells"),
])
def test_cells_no_kind_takes_are_named(blocks, named):
    mesh = meshio.Mesh(np.random.default_rng(0).random((8, 3)), blocks)
    with pytest.raises(InvalidMeshError, match=f"has {named}; move supports triangles and "
                                               "tetrahedra"):
        kind_of(mesh, "move")


def test_anything_else_is_an_option_error():
    for thing in (object(), np.zeros((3, 2)), "mesh.msh"):
        with pytest.raises(OptionError, match="takes a PlanarMesh"):
            kind_of(thing)


def test_metric_for_is_a_metric_on_each_kind_s_points():
    trimesh = pytest.importorskip("trimesh")
    m = _ours()
    V, F = surface()
    for mesh in (m["planar"], m["surface"], m["tets"], trimesh.Trimesh(V, F, process=False)):
        metric = metric_for(mesh)
        assert isinstance(metric, mt.Metric)
        assert mt.metric_for is metric_for and mt.kind_of is kind_of
    assert isinstance(mt.EuclideanMetric(), mt.Metric)
    assert not isinstance(object(), mt.Metric)
    assert not isinstance(SURFACE.distortion(V, F), mt.Metric)


def test_metric_for_is_the_morphs_metric():
    m = _ours()
    g = metric_for(m["planar"])
    ref = GraphMetric(m["planar"].points, m["planar"].triangles, 1.0)
    assert type(g) is GraphMetric and g.weight == ref.weight
    np.testing.assert_array_equal(g.mass, ref.mass)
    t = metric_for(m["tets"])
    assert type(t) is TetGraphMetric and t.weight == 1.0
    s = metric_for(m["surface"])
    V, F = m["surface"].points, m["surface"].triangles
    problem = _PathProblem(V, V, F, 1.0, 0.1)  # mt.morph's defaults for surfaces
    Q = V + 0.01 * np.random.default_rng(3).standard_normal(V.shape)
    assert (s.jacobian(Q) != problem.jacobian(Q)).nnz == 0


@pytest.mark.parametrize("name", ["planar", "surface", "tets"])
def test_the_metrics_riesz_map_inverts_inner_on_free_vertices(name):
    make = {"planar": planar, "surface": surface, "tets": tets}[name]
    P, C = make()
    kind = {"planar": PLANAR, "surface": SURFACE, "tets": TETRAHEDRA}[name]
    metric = kind.default_metric(P, C)
    rng = np.random.default_rng(7)
    Q = P + 0.01 * rng.standard_normal(P.shape)
    D, V = rng.standard_normal(P.shape), rng.standard_normal(P.shape)
    free = rng.random(len(P)) < 0.7
    V[~free] = 0.0
    G = metric.riesz(Q, D, free)
    assert not G[~free].any()
    np.testing.assert_allclose(metric.inner(Q, G, V), np.vdot(D, V), rtol=1e-8)
    # inner is the assembled matrix's quadratic form, symmetric and positive
    A = metric.matrix(Q)
    np.testing.assert_allclose(metric.inner(Q, D, V), D.ravel() @ (A @ V.ravel()), rtol=1e-10)
    np.testing.assert_allclose(metric.inner(Q, D, V), metric.inner(Q, V, D), rtol=1e-10)
    assert metric.norm(Q, D) ** 2 == pytest.approx(metric.inner(Q, D, D), rel=1e-12)
    assert metric.norm(Q, D) > 0
    with pytest.raises(MetricNotImplementedError, match=f"{type(metric).__name__}.exp"):
        metric.exp(Q, D)


@pytest.mark.parametrize("name", ["surface", "tets"])
def test_the_metrics_refuse_a_mesh_they_are_not_defined_at(name):
    make = {"surface": surface, "tets": tets}[name]
    P, C = make()
    kind = {"surface": SURFACE, "tets": TETRAHEDRA}[name]
    Q = P.copy()
    Q[C[0, 1]] = Q[C[0, 0]]  # a cell collapsed
    with pytest.raises(NotAdmissibleError):
        kind.default_metric(P, C).riesz(Q, np.ones_like(P))
