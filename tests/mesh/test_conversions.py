"""Conversions to and from meshio, trimesh and pymeshlab keep order and connectivity."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from conftest import grid_mesh

from meshopt_toolkit.conversions import (
    from_meshio,
    from_pymeshlab,
    from_trimesh,
    to_meshio,
    to_pymeshlab,
    to_trimesh,
)
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.mesh import PlanarMesh, TriangleMesh


@pytest.fixture
def planar(rng) -> PlanarMesh:
    m = grid_mesh(4, jitter=0.3)
    return m.with_points(m.points + 0.1 + 1e-3 * rng.standard_normal(m.points.shape))


@pytest.fixture
def with_duplicates() -> TriangleMesh:
    """Two triangles that touch at equal coordinates but do not share vertex indices, and a
    vertex listed after the ones using it: merging or reordering would show."""
    pts = [[1, 0, 2], [0, 0, 0], [1, 0, 2], [0, 1, 0], [1, 1, 1], [0, 1, 0]]
    return TriangleMesh(pts, [[1, 0, 3], [2, 4, 5]])


def test_meshio_roundtrip_with_tags(planar):
    b = planar.boundary_edges
    mesh = PlanarMesh(planar.points, planar.triangles,
                      triangle_tags=np.arange(planar.n_triangles) % 2 + 5, lines=b,
                      line_tags=np.full(len(b), 3), tag_names={"wall": (3, 1), "x": (5, 2)})
    m = to_meshio(mesh)
    assert m.points.shape == (mesh.n_vertices, 3) and not m.points[:, 2].any()
    assert [c.type for c in m.cells] == ["line", "triangle"]
    assert np.array_equal(m.cell_data["gmsh:physical"][1], mesh.triangle_tags)
    back = from_meshio(m, source="x")
    assert isinstance(back, PlanarMesh) and back == mesh and back.source == "x"
    assert np.array_equal(back.triangle_tags, mesh.triangle_tags)
    assert np.array_equal(back.lines, b) and np.array_equal(back.line_tags, mesh.line_tags)
    assert back.tag_names == mesh.tag_names
    assert to_meshio(mesh, pad_z=False).points.shape == (mesh.n_vertices, 2)


def test_from_meshio_keeps_block_order_and_skips_vertex_cells():
    pts = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [2, 2]], float)
    m = meshio.Mesh(pts, [("triangle", [[0, 1, 2]]), ("vertex", [[4]]),
                          ("triangle", [[1, 3, 2]])])
    out = from_meshio(m)
    assert out.triangles.tolist() == [[0, 1, 2], [1, 3, 2]]
    assert out.n_vertices == 5 and out.triangle_tags is None


def test_from_meshio_refuses_quads_naming_them():
    pts = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [2, 2]], float)
    m = meshio.Mesh(pts, [("triangle", [[0, 1, 2]]), ("quad", [[0, 1, 3, 2]]),
                          ("polygon", [[0, 1, 4, 3, 2]])])
    with pytest.raises(InvalidMeshError, match=r"m\.vtu: has 1 quad, 1 polygon cells; only "
                                                r"triangles are supported"):
        from_meshio(m, source="m.vtu")


def test_from_meshio_no_triangles():
    m = meshio.Mesh(np.zeros((3, 3)), [("line", [[0, 1]])])
    with pytest.raises(InvalidMeshError, match="f.msh: mesh has no triangles"):
        from_meshio(m, source="f.msh")


def test_surface_stays_3d(with_duplicates):
    out = from_meshio(to_meshio(with_duplicates))
    assert type(out) is TriangleMesh and out == with_duplicates


def test_trimesh_keeps_order(with_duplicates, planar):
    t = to_trimesh(with_duplicates)
    assert len(t.vertices) == 6  # not merged
    assert np.array_equal(t.faces, with_duplicates.triangles)
    assert from_trimesh(t) == with_duplicates
    tp = to_trimesh(planar)
    assert tp.vertices.shape == (planar.n_vertices, 3)
    back = from_trimesh(tp)
    assert isinstance(back, PlanarMesh) and back == planar


def test_pymeshlab_keeps_order(with_duplicates, planar):
    pymeshlab = pytest.importorskip("pymeshlab")
    m = to_pymeshlab(with_duplicates)
    assert isinstance(m, pymeshlab.Mesh) and m.vertex_number() == 6
    assert from_pymeshlab(m) == with_duplicates
    ms = pymeshlab.MeshSet()
    ms.add_mesh(to_pymeshlab(planar))
    ms.compute_scalar_by_aspect_ratio_per_face()  # a filter that keeps topology
    back = from_pymeshlab(ms.current_mesh())
    assert isinstance(back, PlanarMesh) and back == planar
    assert len(ms.current_mesh().face_scalar_array()) == planar.n_triangles


def test_lazy_imports():
    import subprocess
    import sys

    code = ("import sys, meshopt_toolkit.conversions, meshopt_toolkit.io; "
            "print('trimesh' in sys.modules, 'pymeshlab' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
