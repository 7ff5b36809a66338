"""File I/O: round trips of every format, files written by gmsh/pymeshlab/meshio, tags,
errors naming the file, refusal to overwrite and atomic writes."""

from __future__ import annotations

import os
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import grid_mesh

from meshopt_toolkit import io
from meshopt_toolkit.gmsh_session import gmsh_session
from meshopt_toolkit.errors import ReadError, WriteError
from meshopt_toolkit.mesh import PlanarMesh, TriangleMesh

EXACT = [  # (extension, binary) pairs whose coordinates must survive bit-exactly
    (".msh", True), (".msh", False), (".obj", None), (".off", None), (".ply", True),
    (".ply", False), (".vtk", True), (".vtk", False), (".vtu", True), (".vtu", False),
]


def exact_points(rng, mesh: PlanarMesh) -> np.ndarray:
    """Positions that have no short decimal form (0.1 + tiny random doubles)."""
    return mesh.points + 0.1 + 1e-3 * rng.standard_normal(mesh.points.shape)


@pytest.fixture
def planar(rng) -> PlanarMesh:
    m = grid_mesh(5, jitter=0.3)
    return m.with_points(exact_points(rng, m))


@pytest.fixture
def surface(rng) -> TriangleMesh:
    """A 3D surface (non-zero z) with two separate parts."""
    m = grid_mesh(3)
    z = np.sin(3 * m.points[:, :1]) + 0.1 + 1e-9 * rng.standard_normal((m.n_vertices, 1))
    pts = np.hstack([m.points, z])
    pts2 = pts + [5.0, 0.0, 1.0]
    tri = np.vstack([m.triangles, m.triangles + m.n_vertices])
    return TriangleMesh(np.vstack([pts, pts2]), tri)


def tagged(mesh: PlanarMesh) -> PlanarMesh:
    """Interleaved triangle tags (so element blocks must not reorder) and tagged boundary."""
    b = mesh.boundary_edges
    ttags = np.where(np.arange(mesh.n_triangles) % 3 == 0, 11, 12)
    ltags = np.where(np.arange(len(b)) % 2 == 0, 1, 2)
    names = {"left": (1, 1), "right": (2, 1), "a": (11, 2), "b": (12, 2)}
    return PlanarMesh(mesh.points, mesh.triangles, triangle_tags=ttags, lines=b,
                      line_tags=ltags, tag_names=names)


def roundtrip(mesh, path: Path, **kw):
    io.save(mesh, path, **kw)
    return io.load(path)


def assert_same(a, b, exact=True):
    assert type(a) is type(b)
    assert np.array_equal(a.triangles, b.triangles)
    if exact:
        assert np.array_equal(a.points, b.points), np.abs(a.points - b.points).max()
    else:
        np.testing.assert_allclose(a.points, b.points, rtol=0, atol=1e-6)


# -------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("ext,binary", EXACT)
def test_roundtrip_exact_planar(tmp_path, planar, ext, binary):
    out = roundtrip(planar, tmp_path / f"m{ext}", binary=binary)
    assert isinstance(out, PlanarMesh) and out.points.shape[1] == 2
    assert out.source == str(tmp_path / f"m{ext}")
    assert_same(planar, out)


@pytest.mark.parametrize("ext,binary", EXACT)
def test_roundtrip_exact_surface(tmp_path, surface, ext, binary):
    out = roundtrip(surface, tmp_path / f"s{ext}", binary=binary)
    assert not isinstance(out, PlanarMesh)
    assert_same(surface, out)


@pytest.mark.parametrize("version", ["2.2", "4.1"])
@pytest.mark.parametrize("binary", [True, False])
def test_msh_versions_keep_tags(tmp_path, planar, version, binary):
    mesh = tagged(planar)
    path = tmp_path / "t.msh"
    io.save(mesh, path, binary=binary, msh_version=version)
    assert path.read_bytes().startswith(f"$MeshFormat\n{version} {int(binary)} 8".encode())
    out = io.load(path)
    assert_same(mesh, out)
    assert np.array_equal(out.triangle_tags, mesh.triangle_tags)
    assert np.array_equal(out.lines, mesh.lines)
    assert np.array_equal(out.line_tags, mesh.line_tags)
    assert out.tag_names == mesh.tag_names
    np.testing.assert_array_equal(out.tagged_vertices("left"), mesh.tagged_vertices(1))
    # meshio reads our file, tags included (its own ASCII writer cannot, under numpy 2)
    m = meshio.read(path)
    assert np.array_equal(m.points[:, :2], mesh.points)
    assert np.array_equal(np.concatenate(m.cell_data["gmsh:physical"]),
                          np.concatenate([mesh.line_tags, mesh.triangle_tags]))


@pytest.mark.parametrize("binary", [True, False])
def test_stl_reads_unordered(tmp_path, planar, binary):
    out = roundtrip(planar, tmp_path / "m.stl", binary=binary)
    assert out.n_vertices == planar.n_vertices and out.n_triangles == planar.n_triangles
    # same triangles as sets of corners (float32 in binary STL, exact in ASCII STL),
    # whatever the vertex numbering
    f32 = planar.points.astype(np.float32).astype(float) if binary else planar.points
    assert np.array_equal(np.sort(out.points, axis=0), np.sort(f32, axis=0))
    np.testing.assert_array_equal(out.points[out.triangles], f32[planar.triangles])


def test_binary_flag_refused_for_text_formats(tmp_path, planar):
    for ext in (".obj", ".off"):
        with pytest.raises(WriteError, match=ext[1:].upper()):
            io.save(planar, tmp_path / f"m{ext}", binary=True)
        assert not (tmp_path / f"m{ext}").exists()


# ------------------------------------------------------------------- other writers/readers
@pytest.fixture(scope="module")
def gmsh_files(tmp_path_factory):
    """A tiny rectangle meshed by gmsh itself, written in 2.2/4.1 ASCII/binary, with the
    reference coordinates of each triangle's and line's nodes from the gmsh API."""
    pytest.importorskip("gmsh")
    d = tmp_path_factory.mktemp("gmsh")
    with gmsh_session() as gmsh:
        gmsh.model.add("rect")
        s = gmsh.model.occ.addRectangle(0, 0, 0, 2, 1)
        gmsh.model.occ.synchronize()
        curves = [c for _, c in gmsh.model.getBoundary([(2, s)], oriented=False)]
        gmsh.model.addPhysicalGroup(2, [s], 7, "domain")
        gmsh.model.addPhysicalGroup(1, curves[:1], 3, "bottom")
        gmsh.model.addPhysicalGroup(1, curves[1:], 4, "walls")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        xyz = np.zeros((int(tags.max()) + 1, 3))
        xyz[tags.astype(int)] = coords.reshape(-1, 3)
        _, _, tri_nodes = gmsh.model.mesh.getElements(2)
        tri_ref = xyz[tri_nodes[0].astype(int).reshape(-1, 3)]
        bottom = {int(n) for n in gmsh.model.mesh.getNodesForPhysicalGroup(1, 3)[0]}
        n_bottom = len(bottom)
        files = {}
        for version in (2.2, 4.1):
            for binary in (0, 1):
                gmsh.option.setNumber("Mesh.MshFileVersion", version)
                gmsh.option.setNumber("Mesh.Binary", binary)
                path = d / f"rect_{version}_{binary}.msh"
                gmsh.write(str(path))
                files[(version, binary)] = path
    return files, tri_ref, n_bottom


@pytest.mark.parametrize("key", [(2.2, 0), (2.2, 1), (4.1, 0), (4.1, 1)])
def test_reads_gmsh_written_files(gmsh_files, key):
    files, tri_ref, n_bottom = gmsh_files
    mesh = io.load(files[key])
    assert isinstance(mesh, PlanarMesh)
    if key[1]:  # binary doubles: exact; gmsh's ASCII keeps 16 significant digits
        assert np.array_equal(mesh.points[mesh.triangles], tri_ref[:, :, :2])
    else:
        np.testing.assert_allclose(mesh.points[mesh.triangles], tri_ref[:, :, :2], rtol=1e-15,
                                   atol=1e-16)
    assert set(np.unique(mesh.triangle_tags)) == {7}
    assert set(np.unique(mesh.line_tags)) == {3, 4}
    assert mesh.tag_names == {"domain": (7, 2), "bottom": (3, 1), "walls": (4, 1)}
    assert len(mesh.tagged_vertices("bottom")) == n_bottom


@pytest.mark.parametrize("version", ["2.2", "4.1"])
@pytest.mark.parametrize("binary", [True, False])
def test_gmsh_reads_our_files(tmp_path, planar, version, binary):
    pytest.importorskip("gmsh")
    mesh = tagged(planar)
    path = tmp_path / "ours.msh"
    io.save(mesh, path, binary=binary, msh_version=version)
    with gmsh_session() as gmsh:
        gmsh.open(str(path))
        tags, coords, _ = gmsh.model.mesh.getNodes()
        xyz = np.zeros((int(tags.max()) + 1, 3))
        xyz[tags.astype(int)] = coords.reshape(-1, 3)
        etypes, etags, enodes = gmsh.model.mesh.getElements(2)
        groups = {(d, t): gmsh.model.getPhysicalName(d, t)
                  for d, t in gmsh.model.getPhysicalGroups()}
    order = np.argsort(etags[0])
    tri = enodes[0].astype(int).reshape(-1, 3)[order]
    assert np.array_equal(xyz[tri][:, :, :2], mesh.points[mesh.triangles])
    assert groups == {(1, 1): "left", (1, 2): "right", (2, 11): "a", (2, 12): "b"}


def test_meshio_reads_ours(tmp_path, planar, surface):
    for mesh in (planar, surface):
        for ext in (".msh", ".vtk", ".vtu", ".obj", ".off", ".ply"):
            path = tmp_path / f"m{ext}"
            io.save(mesh, path)
            m = meshio.read(path)
            pts = np.hstack([m.points, np.zeros((len(m.points), 3 - m.points.shape[1]))])
            ref = np.hstack([mesh.points, np.zeros((mesh.n_vertices, 3 - mesh.dim))])
            assert np.array_equal(pts, ref), ext
            assert np.array_equal(m.get_cells_type("triangle"), mesh.triangles), ext


def test_reads_meshio_files(tmp_path, surface):
    m = meshio.Mesh(surface.points, [("triangle", surface.triangles)])
    for ext, fmt, kw in [(".vtu", "vtu", {}), (".vtk", "vtk", {}), (".msh", "gmsh", {}),
                         (".msh", "gmsh22", {}), (".ply", "ply", {}), (".off", "off", {}),
                         (".obj", "obj", {}), (".vtk", "vtk", {"binary": False})]:
        path = tmp_path / f"meshio{ext}"
        meshio.write(path, m, file_format=fmt, **kw)
        out = io.load(path)
        assert np.array_equal(out.triangles, surface.triangles), fmt
        np.testing.assert_allclose(out.points, surface.points, rtol=1e-15, atol=1e-15)


def test_pymeshlab_interop(tmp_path, surface):
    pymeshlab = pytest.importorskip("pymeshlab")
    from meshopt_toolkit.conversions import to_pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(to_pymeshlab(surface))
    for ext in (".ply", ".obj", ".off"):
        theirs = tmp_path / f"pml{ext}"
        ms.save_current_mesh(str(theirs), save_vertex_color=False, save_vertex_normal=False) \
            if ext == ".ply" else ms.save_current_mesh(str(theirs))
        out = io.load(theirs)
        assert np.array_equal(out.triangles, surface.triangles), ext
        tol = 0 if ext == ".ply" else 1e-15
        np.testing.assert_allclose(out.points, surface.points, rtol=tol, atol=tol)
        ours = tmp_path / f"ours{ext}"
        io.save(surface, ours)
        ms2 = pymeshlab.MeshSet()
        ms2.load_new_mesh(str(ours))
        back = ms2.current_mesh()
        assert np.array_equal(back.face_matrix(), surface.triangles), ext
        np.testing.assert_allclose(back.vertex_matrix(), surface.points, rtol=1e-15, atol=1e-15)


def test_2d_points_padded_with_zero_z(tmp_path, planar):
    for ext in (".obj", ".off", ".ply", ".vtu"):
        path = tmp_path / f"p{ext}"
        io.save(planar, path)
        m = meshio.read(path)
        assert m.points.shape == (planar.n_vertices, 3) and not m.points[:, 2].any(), ext


# ------------------------------------------------------------------------------ errors
def _write(path: Path, data) -> Path:
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return path


def assert_read_error(path, pattern: str):
    with pytest.raises(ReadError, match=pattern) as info:
        io.load(path)
    assert str(path) in str(info.value)
    return info.value


def test_missing_file(tmp_path):
    assert_read_error(tmp_path / "nope.msh", "no such file")


def test_unknown_extension(tmp_path):
    assert_read_error(_write(tmp_path / "m.xyz", "1 2 3"), "unknown mesh format")
    with pytest.raises(WriteError, match="unknown mesh format"):
        io.save(grid_mesh(2), tmp_path / "m.xyz")


@pytest.mark.parametrize("ext", [".msh", ".obj", ".off", ".ply", ".vtk", ".vtu", ".stl"])
def test_garbage_content(tmp_path, ext):
    assert_read_error(_write(tmp_path / f"g{ext}", "this is not a mesh\n" * 3), "not a|cannot read")


@pytest.mark.parametrize("ext", [".msh", ".obj", ".off", ".ply", ".vtk", ".vtu"])
def test_out_of_range_index(tmp_path, ext):
    good = PlanarMesh([[0, 0], [1, 0], [0, 1], [1, 1]], [[0, 1, 2], [1, 3, 2]])
    path = tmp_path / f"r{ext}"
    m = meshio.Mesh(np.hstack([good.points, np.zeros((4, 1))]),
                    [("triangle", [[0, 1, 2], [1, 7, 2]])])
    if ext == ".msh":
        # a gmsh file whose element names node 8 of 4
        text = ("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n"
                "4 1 1 0\n$EndNodes\n$Elements\n2\n1 2 2 0 1 1 2 3\n2 2 2 0 1 2 8 3\n"
                "$EndElements\n")
        _write(path, text)
        assert_read_error(path, ".")  # meshio's gmsh reader fails on the unknown node 8
        return
    if ext in (".obj", ".off", ".ply"):
        # our writers do not validate against the mesh: write the file by hand
        io.save(good, path, binary=False)
        text = path.read_text()
        if ext == ".obj":
            text = text.replace("f 2 4 3", "f 2 8 3")
        else:
            text = text.replace("3 1 3 2", "3 1 7 2")
        _write(path, text)
    else:
        meshio.write(path, m)
    assert_read_error(path, "out of range")


@pytest.mark.parametrize("ext", [".msh", ".obj", ".off", ".ply", ".vtu"])
def test_nan_coordinate(tmp_path, ext):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], float)
    path = tmp_path / f"n{ext}"
    if ext == ".msh":
        text = ("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 nan 0\n"
                "$EndNodes\n$Elements\n1\n1 2 2 0 1 1 2 3\n$EndElements\n")
        _write(path, text)
    else:
        meshio.write(path, meshio.Mesh(pts, [("triangle", [[0, 1, 2]])]))
    assert_read_error(path, "non-finite")


@pytest.mark.parametrize("ext", [".msh", ".obj", ".off", ".ply", ".vtu"])
def test_zero_triangles(tmp_path, ext):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    path = tmp_path / f"z{ext}"
    if ext == ".obj":
        _write(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    elif ext == ".off":
        _write(path, "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n")
    elif ext == ".ply":
        _write(path, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 0\nproperty list uchar int vertex_indices\n"
                     "end_header\n0 0 0\n1 0 0\n0 1 0\n")
    else:
        meshio.write(path, meshio.Mesh(pts, [("line", [[0, 1], [1, 2]])]),
                     **({"file_format": "gmsh22", "binary": False} if ext == ".msh" else {}))
    assert_read_error(path, "no triangles")


@pytest.mark.parametrize("ext,version", [(".msh", "4.1"), (".msh", "2.2"), (".ply", None),
                                         (".vtu", None), (".vtk", None)])
def test_truncated_binary_file(tmp_path, planar, ext, version):
    path = tmp_path / f"t{ext}"
    io.save(planar, path, binary=True, **({"msh_version": version} if version else {}))
    data = path.read_bytes()
    _write(path, data[: len(data) * 2 // 3])
    assert_read_error(path, "truncated|newline|corrupt")


def test_directory_is_not_a_mesh(tmp_path):
    (tmp_path / "d.msh").mkdir()
    assert_read_error(tmp_path / "d.msh", "directory")


def test_obj_quads_refused_and_relative_indices(tmp_path):
    assert_read_error(_write(tmp_path / "q.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"),
                      "only triangles")
    out = io.load(_write(tmp_path / "r.obj",
                         "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3/1/1 -2//2 -1\nv 1 1 0\nf 2 4 -2\n"))
    assert out.triangles.tolist() == [[0, 1, 2], [1, 3, 2]]


# --------------------------------------------------------------- overwrite and atomicity
def test_overwrite_refused(tmp_path, planar):
    path = tmp_path / "m.ply"
    io.save(planar, path)
    before = path.read_bytes()
    with pytest.raises(WriteError, match="already exists") as info:
        io.save(grid_mesh(2), path, overwrite=False)
    assert str(path) in str(info.value)
    assert path.read_bytes() == before
    io.save(grid_mesh(2), path)  # overwrite=True is the default
    assert io.load(path) == grid_mesh(2)


def test_atomic_write_keeps_old_file(tmp_path, planar, monkeypatch):
    path = tmp_path / "m.obj"
    io.save(planar, path)
    before = path.read_bytes()

    def broken_writer(p, mesh, binary=None):
        with open(p, "w") as fh:
            fh.write("v 0 0 0\n" * 10)
            fh.flush()
            raise OSError(28, "No space left on device")

    monkeypatch.setitem(io.WRITERS, ".obj", broken_writer)
    with pytest.raises(WriteError, match="No space left") as info:
        io.save(grid_mesh(2), path)
    assert str(path) in str(info.value)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["m.obj"]
    with pytest.raises(WriteError):
        io.save(grid_mesh(2), tmp_path / "new.obj")
    assert sorted(os.listdir(tmp_path)) == ["m.obj"]


def test_missing_directory(tmp_path, planar):
    with pytest.raises(WriteError, match="does not exist"):
        io.save(planar, tmp_path / "no" / "m.msh")


def test_register_format_adds_a_format_to_load_save_and_convert(tmp_path):
    """A format registered by extension is used by load/save and by the lossless path."""
    import meshopt_toolkit.io as mio
    from meshopt_toolkit.datasets import data_path
    from meshopt_toolkit.io import obj

    saved = {k: dict(t) for k, t in (("r", mio.READERS), ("w", mio.WRITERS),
                                     ("rc", mio.CELL_READERS), ("wc", mio.CELL_WRITERS))}
    try:
        mio.register_format("OBJX", read_cells=obj.read_cells, write_cells=obj.write_cells)
        assert ".objx" in mio.supported_extensions("read")
        mesh = mio.load(data_path("disc_25.msh"))
        mio.save(mesh, tmp_path / "m.objx")
        again = mio.load(tmp_path / "m.objx")
        assert np.array_equal(again.triangles, mesh.triangles)
        assert mio.load_cells(tmp_path / "m.objx").points.shape[0] == mesh.n_vertices
    finally:
        for table, key in ((mio.READERS, "r"), (mio.WRITERS, "w"), (mio.CELL_READERS, "rc"),
                           (mio.CELL_WRITERS, "wc")):
            table.clear()
            table.update(saved[key])
    assert ".objx" not in mio.supported_extensions("read")
