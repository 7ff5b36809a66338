"""``mt.move`` and ``mt.morph`` give a meshio, trimesh or pymeshlab object back of its type
with everything it carries; only the points change (normals are those of the new points)."""

from __future__ import annotations

import copy
import warnings

import meshio
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import meshopt_toolkit as mt
from meshopt_toolkit.conversions import Carried, DataLossWarning
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.kernels.tetrahedra import signed_volumes
from meshopt_toolkit.results import Result

trimesh = pytest.importorskip("trimesh")

#: a quarter turn about z: exact in floating point, so a rigid motion is known bitwise
TURN = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def sphere():
    s = trimesh.creation.icosphere(subdivisions=2)
    return np.array(s.vertices), np.array(s.faces)


def cap(V):
    """A cap of handles: the rest of the sphere has to follow them."""
    return np.flatnonzero(V[:, 2] > 0.5)


def assert_turned(moved, V):
    np.testing.assert_allclose(moved, V @ TURN.T, atol=1e-12)


# ----------------------------------------------------------------------------- trimesh
@pytest.fixture
def textured(rng):
    from PIL import Image

    V, F = sphere()
    image = Image.fromarray(rng.integers(0, 256, (8, 8, 3), dtype=np.uint8))
    visual = trimesh.visual.TextureVisuals(uv=rng.random((len(V), 2)), image=image)
    return trimesh.Trimesh(V, F, visual=visual, process=False,
                           vertex_attributes={"temperature": rng.random(len(V))},
                           face_attributes={"region": np.arange(len(F)) % 3},
                           metadata={"name": "ball", "units": "mm"})


def assert_same_trimesh_data(out, t):
    assert isinstance(out, trimesh.Trimesh) and out.visual.kind == t.visual.kind
    assert type(out.visual) is type(t.visual)
    assert np.array_equal(out.faces, t.faces)
    assert out.vertex_attributes.keys() == t.vertex_attributes.keys()
    assert out.face_attributes.keys() == t.face_attributes.keys()
    for name, value in t.vertex_attributes.items():
        assert np.array_equal(out.vertex_attributes[name], value)
    for name, value in t.face_attributes.items():
        assert np.array_equal(out.face_attributes[name], value)
    assert out.metadata == t.metadata


def test_moved_trimesh_keeps_uv_material_attributes_and_metadata(textured):
    V = np.array(textured.vertices)
    before = textured.vertex_normals.copy()
    h = cap(V)
    r = mt.move(textured, h, V[h] @ TURN.T, frames=3)
    assert isinstance(r, Result) and len(r.frames) == 3
    for out in [r.mesh, *r.frames]:
        assert_same_trimesh_data(out, textured)
        assert np.array_equal(out.visual.uv, textured.visual.uv)
        assert np.array_equal(np.asarray(out.visual.material.image),
                              np.asarray(textured.visual.material.image))
    assert_turned(r.mesh.vertices, V)
    np.testing.assert_allclose(r.mesh.vertex_normals, before @ TURN.T, atol=1e-12)
    assert np.abs(r.mesh.vertex_normals - before).max() > 0.5  # not the stale ones
    assert np.array_equal(textured.vertices, V)  # the input is left as it was
    assert r.motion is r.result.motion  # the solver's result is read through


@pytest.mark.parametrize("where", ["vertex", "face"])
def test_moved_trimesh_keeps_its_colours(rng, where):
    V, F = sphere()
    colours = rng.integers(0, 256, (len(V) if where == "vertex" else len(F), 4),
                           dtype=np.uint8)
    t = trimesh.Trimesh(V, F, process=False, **{f"{where}_colors": colours})
    h = cap(V)
    r = mt.move(t, h, V[h] @ TURN.T)
    assert r.frames[0] is t  # the first frame is the input
    assert_same_trimesh_data(r.mesh, t)
    assert np.array_equal(getattr(r.mesh.visual, f"{where}_colors"), colours)
    assert_turned(r.mesh.vertices, V)


def test_morphed_trimesh_frames_keep_the_source_data(textured):
    V = np.array(textured.vertices)
    target = trimesh.Trimesh(V @ TURN.T, textured.faces, process=False)
    r = mt.morph(textured, target, 3)
    assert len(r.frames) == 3
    for out in r.frames:
        assert_same_trimesh_data(out, textured)
        assert np.array_equal(out.visual.uv, textured.visual.uv)
    assert_turned(r.frames[-1].vertices, V)


def test_morph_of_a_trimesh_into_another_type_is_refused(textured):
    ours = Carried.of(textured).mesh
    for source, target in ((textured, ours), (ours, textured)):
        with pytest.raises(InvalidMeshError, match="both of one type"):
            mt.morph(source, target, 3)


def test_not_a_mesh_of_the_library_is_refused():
    with pytest.raises(InvalidMeshError, match="trimesh.Scene is not a mesh"):
        mt.move(trimesh.Scene(), [0], [[0.0, 0.0, 0.0]])


# ----------------------------------------------------------------------------- pymeshlab
@pytest.fixture
def coloured_pymeshlab(rng):
    pymeshlab = pytest.importorskip("pymeshlab")
    V, F = sphere()
    nf = len(F)
    return pymeshlab.Mesh(
        V, F.astype(np.int32), edge_matrix=F[:, :2].astype(np.int32),
        v_scalar_array=rng.random(len(V)),
        f_scalar_array=rng.random(nf), v_color_matrix=rng.random((len(V), 4)),
        f_color_matrix=rng.random((nf, 4)), v_tex_coords_matrix=rng.random((len(V), 2)),
        w_tex_coords_matrix=rng.random((3 * nf, 2)))


PYMESHLAB_DATA = ("vertex_scalar_array", "face_scalar_array", "vertex_color_matrix",
                  "face_color_matrix", "vertex_tex_coord_matrix", "wedge_tex_coord_matrix",
                  "face_matrix", "edge_matrix")


def test_moved_pymeshlab_mesh_keeps_tex_coords_colours_and_quality(coloured_pymeshlab):
    import pymeshlab

    m = coloured_pymeshlab
    V = m.vertex_matrix()
    h = cap(V)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataLossWarning)  # nothing is lost here
        r = mt.move(m, h, V[h] @ TURN.T, frames=3)
    for out in [r.mesh, *r.frames]:
        assert isinstance(out, pymeshlab.Mesh)
        assert out.has_wedge_tex_coord() and out.has_vertex_tex_coord()
        for name in PYMESHLAB_DATA:
            assert np.array_equal(getattr(out, name)(), getattr(m, name)()), name
    assert_turned(r.mesh.vertex_matrix(), V)
    fresh = pymeshlab.Mesh(r.mesh.vertex_matrix(), m.face_matrix())
    assert np.array_equal(r.mesh.vertex_normal_matrix(), fresh.vertex_normal_matrix())
    assert np.abs(r.mesh.vertex_normal_matrix() - m.vertex_normal_matrix()).max() > 0.5


def test_what_pymeshlab_cannot_set_is_named_in_one_warning(tmp_path):
    pymeshlab = pytest.importorskip("pymeshlab")
    from PIL import Image

    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(tmp_path / "tex.png")
    (tmp_path / "a.mtl").write_text("newmtl m\nmap_Kd tex.png\n")
    (tmp_path / "a.obj").write_text(
        "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
        "vt 0 1\nusemtl m\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(tmp_path / "a.obj"))
    ms.compute_selection_by_condition_per_vertex(condselect="x > 0.5")
    m = ms.current_mesh()
    assert m.texture_number() == 1 and m.selected_vertex_number() > 0
    V = m.vertex_matrix()
    with pytest.warns(DataLossWarning) as caught:
        r = mt.move(m, np.arange(len(V)), V @ TURN.T)
    assert [str(w.message) for w in caught] == [
        "pymeshlab.Mesh: its textures (tex.png) and its selection cannot be set on a new "
        "mesh; the results have none"]
    assert np.array_equal(r.mesh.wedge_tex_coord_matrix(), m.wedge_tex_coord_matrix())
    assert_turned(r.mesh.vertex_matrix(), V)


# ----------------------------------------------------------------------------- meshio
def assert_same_meshio_data(out, m):
    assert isinstance(out, meshio.Mesh) and out.points.shape == m.points.shape
    assert [(c.type, c.data.tolist()) for c in out.cells] == \
        [(c.type, c.data.tolist()) for c in m.cells]
    for a, b in ((out.point_data, m.point_data), (out.field_data, m.field_data),
                 (out.point_sets, m.point_sets)):
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in b)
    for a, b in ((out.cell_data, m.cell_data), (out.cell_sets, m.cell_sets)):
        assert a.keys() == b.keys()
        assert all(np.array_equal(x, y) for k in b for x, y in zip(a[k], b[k], strict=True))


def with_data(m: meshio.Mesh, rng) -> meshio.Mesh:
    m.point_data["temperature"] = rng.random(len(m.points))
    m.point_data["velocity"] = rng.random((len(m.points), 3))
    m.cell_data["pressure"] = [rng.random(len(c.data)) for c in m.cells]
    m.field_data["inlet"] = np.array([7, 1])
    m.point_sets["corner"] = np.array([0, 1])
    m.cell_sets["some"] = [np.array([0]) for _ in m.cells]
    return m


def test_moved_planar_meshio_mesh_keeps_point_cell_and_field_data(rng):
    m = with_data(meshio.read(mt.data_path("disc_146.msh")), rng)
    kept = copy.deepcopy(m)
    b = Carried.of(m).mesh.boundary_vertices
    P = m.points[:, :2]
    r = mt.move(m, b, P[b] @ TURN[:2, :2].T, frames=3)
    for out in [r.mesh, *r.frames]:
        assert_same_meshio_data(out, kept)
        assert not out.points[:, 2].any()
    np.testing.assert_allclose(r.mesh.points[:, :2], P @ TURN[:2, :2].T, atol=1e-12)
    assert np.array_equal(r.mesh.points[b, :2], P[b] @ TURN[:2, :2].T)
    assert np.array_equal(m.points, kept.points)


def test_moved_2d_meshio_points_stay_2d(rng):
    m = meshio.read(mt.data_path("disc_146.msh"))
    m = with_data(meshio.Mesh(m.points[:, :2], m.cells, cell_data=m.cell_data,
                              field_data=m.field_data), rng)
    b = Carried.of(m).mesh.boundary_vertices
    r = mt.move(m, b, m.points[b] @ TURN[:2, :2].T)
    assert_same_meshio_data(r.mesh, m)


def test_moved_tet_meshio_mesh_keeps_its_data(rng):
    skfem = pytest.importorskip("skfem")
    cube = skfem.MeshTet().refined(1)
    p, t = cube.p.T.copy(), cube.t.T.copy()
    flip = signed_volumes(p, t) < 0
    t[flip] = t[flip][:, [0, 2, 1, 3]]
    m = with_data(meshio.Mesh(p, [("tetra", t)]), rng)
    b = np.unique(cube.facets[:, cube.boundary_facets()])
    r = mt.move(m, b, p[b] @ TURN.T, frames=3)
    for out in [r.mesh, *r.frames]:
        assert_same_meshio_data(out, m)
    assert_turned(r.mesh.points, p)


def test_moved_surface_meshio_mesh_keeps_its_data(rng):
    V, F = sphere()
    m = with_data(meshio.Mesh(V, [("triangle", F)]), rng)
    h = cap(V)
    r = mt.move(m, h, V[h] @ TURN.T)
    assert_same_meshio_data(r.mesh, m)
    assert_turned(r.mesh.points, V)


def test_morphed_planar_meshio_frames_keep_the_source_data(rng):
    m = with_data(meshio.read(mt.data_path("disc_146.msh")), rng)
    target = copy.deepcopy(m)
    target.points = m.points @ TURN.T
    r = mt.morph(m, target, 3)
    for out in r.frames:
        assert_same_meshio_data(out, m)
    np.testing.assert_allclose(r.mesh.points, target.points, atol=1e-12)


def test_deformed_planar_meshio_mesh_keeps_its_data(rng):
    m = with_data(meshio.read(mt.data_path("disc_146.msh")), rng)
    P = m.points[:, :2]
    r = mt.deform(m, 0.2 * (P - P.mean(axis=0)), frames=3)
    assert len(r.frames) == 3
    for out, points in zip(r.frames, r.points, strict=True):
        assert_same_meshio_data(out, m)
        assert np.array_equal(out.points[:, :2], points) and not out.points[:, 2].any()
    assert np.array_equal(r.mesh.points, r.frames[-1].points)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(["2d", "z = 0", "3d"]),
       widths=st.lists(st.integers(1, 4), min_size=0, max_size=3))
def test_with_points_changes_the_points_only(seed, kind, widths):
    """Any data of any shape on a meshio mesh and a trimesh: the copy has exactly the new
    points and equal data, and the object given is left as it was."""
    rng = np.random.default_rng(seed)
    V, F = sphere()
    points = {"2d": V[:, :2], "z = 0": V * [1, 1, 0], "3d": V}[kind]
    m = meshio.Mesh(points, [("triangle", F)])
    t = trimesh.Trimesh(V, F, process=False)
    for k, w in enumerate(widths):
        m.point_data[f"p{k}"] = rng.random((len(V), w))
        m.cell_data[f"c{k}"] = [rng.integers(0, 9, (len(F), w))]
        t.vertex_attributes[f"p{k}"] = rng.random((len(V), w))
        t.face_attributes[f"c{k}"] = rng.integers(0, 9, (len(F), w))
        t.metadata[f"m{k}"] = rng.random(w).tolist()
    kept_m, kept_t = copy.deepcopy(m), t.copy()
    Q = rng.random((len(V), 3))
    carried = Carried.of(m)
    d = carried.mesh.points.shape[1]  # 2 for planar points
    assert d == (3 if kind == "3d" else 2)
    out = carried.with_points(Q[:, :d])
    assert_same_meshio_data(out, kept_m)
    assert np.array_equal(out.points[:, :d], Q[:, :d])
    assert np.array_equal(out.points[:, d:], points[:, d:])  # z = 0 stays as it was
    assert_same_meshio_data(m, kept_m)
    assert np.array_equal(m.points, kept_m.points)
    moved = Carried.of(t).with_points(Q)
    assert_same_trimesh_data(moved, kept_t)
    assert np.array_equal(moved.vertices, Q)
    assert np.array_equal(t.vertices, V)
