"""Tetrahedral meshes: kernels against closed forms, TetMesh topology and admissibility,
lossless round trips between .msh (2.2/4.1), .vtu, .vtk and Medit .mesh, meshopt info."""

from __future__ import annotations

import json
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from test_tet_move import cube_tets

from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import InvalidMeshError, NotAdmissibleError, ReadError, WriteError
from meshopt_toolkit.io import CellMesh, load_cells, save_cells
from meshopt_toolkit.kernels.tetrahedra import (dihedral_angles, edge_lengths, mean_ratios,
                                                signed_volumes, tet_quality_summary)
from meshopt_toolkit.mesh import TetMesh

REGULAR = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
CORNER = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
ONE = np.array([[0, 1, 2, 3]])


def positive(points):
    """The one tet on ``points`` in positive order (swap two vertices if needed)."""
    return ONE if signed_volumes(points, ONE)[0] > 0 else np.array([[0, 2, 1, 3]])


# ----------------------------------------------------------------------------- kernels
def test_regular_tet_closed_forms():
    t = positive(REGULAR)
    assert mean_ratios(REGULAR, t)[0] == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(dihedral_angles(REGULAR, t), np.arccos(1 / 3), rtol=1e-14)
    np.testing.assert_allclose(edge_lengths(REGULAR, t), np.sqrt(8), rtol=1e-15)
    # edge a = 2√2: V = a³ / (6√2) = 8/3
    assert signed_volumes(REGULAR, t)[0] == pytest.approx(8 / 3, rel=1e-15)


def test_right_corner_tet_closed_forms():
    assert signed_volumes(CORNER, ONE)[0] == 1 / 6
    # Σℓ² = 3·1 + 3·2 = 9, (3V)^(2/3) = (1/2)^(2/3): q = 12 · 2^(-2/3) / 9
    assert mean_ratios(CORNER, ONE)[0] == pytest.approx(12 * 2 ** (-2 / 3) / 9, rel=1e-14)
    ang = np.degrees(dihedral_angles(CORNER, ONE)[0])
    # edges at the corner (0-1, 0-2, 0-3): right angles; the others: arccos(1/√3)
    np.testing.assert_allclose(ang[:3], 90.0, atol=1e-12)
    np.testing.assert_allclose(ang[3:], np.degrees(np.arccos(1 / np.sqrt(3))), rtol=1e-13)


def test_volume_matches_exact_rational_determinant(rng):
    pts = rng.integers(-50, 50, (40, 3)).astype(float)
    tets = np.array([rng.choice(40, 4, replace=False) for _ in range(30)])
    got = signed_volumes(pts, tets)
    for k, t in enumerate(tets):
        p = [[Fraction(int(x)) for x in pts[i]] for i in t]
        a, b, c = ([p[j][m] - p[0][m] for m in range(3)] for j in (1, 2, 3))
        det = (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
               + a[2] * (b[0] * c[1] - b[1] * c[0]))
        assert got[k] == pytest.approx(float(det / 6), abs=1e-12)


def test_inverted_and_flat_tets_have_nonpositive_quality():
    flipped = np.array([[0, 2, 1, 3]])
    assert signed_volumes(CORNER, flipped)[0] < 0
    assert mean_ratios(CORNER, flipped)[0] == pytest.approx(-mean_ratios(CORNER, ONE)[0])
    flat = CORNER.copy()
    flat[3] = [0.3, 0.3, 0.0]
    assert mean_ratios(flat, ONE)[0] == 0.0
    # a mirrored tet has its mirror image's dihedral angles
    np.testing.assert_allclose(np.sort(dihedral_angles(CORNER, flipped)),
                               np.sort(dihedral_angles(CORNER, ONE)), rtol=1e-14)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(1e-3, 1e3),
       shift=st.floats(-100, 100))
def test_quality_invariant_under_similarity(seed, scale, shift):
    r = np.random.default_rng(seed)
    pts = r.normal(size=(4, 3))
    t = positive(pts)
    if abs(signed_volumes(pts, t)[0]) < 1e-3:
        return  # nearly flat: rounding dominates
    rot = Rotation.from_quat(r.normal(size=4)).as_matrix()
    moved = scale * pts @ rot.T + shift
    assert mean_ratios(moved, t)[0] == pytest.approx(mean_ratios(pts, t)[0], rel=1e-8)
    np.testing.assert_allclose(dihedral_angles(moved, t), dihedral_angles(pts, t),
                               atol=1e-8)
    assert signed_volumes(moved, t)[0] == pytest.approx(scale**3 * signed_volumes(pts, t)[0],
                                                        rel=1e-8)
    assert 0 < mean_ratios(pts, t)[0] <= 1 + 1e-12


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_mean_ratio_is_knupps_jacobian_form(seed):
    # η = 3 det(S)^(2/3) / |S|_F² with S = J W⁻¹, W the edge matrix of the unit regular tet
    pts = np.random.default_rng(seed).normal(size=(4, 3))
    t = positive(pts)
    q = pts[t[0]]
    jac = np.column_stack([q[1] - q[0], q[2] - q[0], q[3] - q[0]])
    w = np.array([[1, 0.5, 0.5], [0, np.sqrt(3) / 2, np.sqrt(3) / 6], [0, 0, np.sqrt(2 / 3)]])
    s = jac @ np.linalg.inv(w)
    eta = 3 * np.linalg.det(s) ** (2 / 3) / np.sum(s * s)
    assert mean_ratios(pts, t)[0] == pytest.approx(eta, rel=1e-9, abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_dihedral_angles_satisfy_the_sine_law(seed):
    # sin θ_ij = 3 V ℓ_ij / (2 A_k A_l): A_k, A_l the areas of the faces meeting at edge ij
    pts = np.random.default_rng(seed).normal(size=(4, 3))
    vol = abs(signed_volumes(pts, ONE)[0])
    if vol < 1e-3:
        return
    def area(i, j, k):
        return 0.5 * np.linalg.norm(np.cross(pts[j] - pts[i], pts[k] - pts[i]))

    ang = dihedral_angles(pts, ONE)[0]
    for e, (i, j) in enumerate([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]):
        k, m = sorted({0, 1, 2, 3} - {i, j})
        expect = 3 * vol * np.linalg.norm(pts[i] - pts[j]) / (2 * area(i, j, m) * area(i, j, k))
        assert np.sin(ang[e]) == pytest.approx(expect, rel=1e-8)


def test_dihedral_angles_sum_rule():
    # the 6 dihedral angles of a tet sum to between 2π and 3π
    r = np.random.default_rng(3)
    pts = r.normal(size=(200, 3))
    tets = np.array([r.choice(200, 4, replace=False) for _ in range(100)])
    s = dihedral_angles(pts, tets).sum(axis=1)
    assert np.all(s > 2 * np.pi - 1e-9) and np.all(s < 3 * np.pi + 1e-9)


# ----------------------------------------------------------------------------- TetMesh
def test_cube_boundary_is_outward_and_closed():
    pts, tets = cube_tets(3)
    m = TetMesh(pts, tets)
    assert m.is_admissible and m.problems == []
    assert len(m.boundary_faces) == 6 * 2 * 3 * 3
    np.testing.assert_array_equal(m.boundary_vertices,
                                  np.flatnonzero((pts == 0).any(1) | (pts == 1).any(1)))
    surf = m.boundary_surface()
    assert surf.is_closed and surf.is_manifold and surf.is_oriented
    assert surf.genera == [0]
    # outward: the enclosed volume is the cube's, positive
    assert surf.enclosed_volume() == pytest.approx(1.0, rel=1e-14)
    assert m.signed_volumes.sum() == pytest.approx(1.0, rel=1e-14)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_boundary_is_independent_of_numbering(seed):
    # renumber vertices, shuffle tets and rotate each tet's vertices (an even permutation
    # keeps the orientation): the same outward boundary faces, as oriented cycles
    r = np.random.default_rng(seed)
    pts, tets = cube_tets(2)
    perm = r.permutation(len(pts))
    inverse = np.argsort(perm)
    even = np.array([[0, 1, 2, 3], [1, 2, 0, 3], [0, 2, 3, 1], [3, 1, 0, 2]])
    t2 = inverse[tets][r.permutation(len(tets))]
    t2 = np.take_along_axis(t2, even[r.integers(0, 4, len(t2))], axis=1)
    a, b = TetMesh(pts, tets), TetMesh(pts[perm], t2)
    assert b.is_admissible

    def cycles(faces, relabel):
        f = relabel[faces]
        k = np.argmin(f, axis=1)[:, None]
        return {tuple(row) for row in np.take_along_axis(f, (k + np.arange(3)) % 3, axis=1)}

    assert cycles(a.boundary_faces, np.arange(len(pts))) == cycles(b.boundary_faces, perm)


def test_inverted_tets_are_named():
    pts, tets = cube_tets(2)
    tets = tets.copy()
    tets[[3, 17]] = tets[[3, 17]][:, [1, 0, 2, 3]]
    m = TetMesh(pts, tets, source="c.msh")
    assert not m.is_admissible
    np.testing.assert_array_equal(m.inverted, [3, 17])
    assert "2 tetrahedra are inverted" in m.problems[0] and "3, 17" in m.problems[0]
    with pytest.raises(NotAdmissibleError, match=r"c\.msh: 2 tetrahedra.*3, 17"):
        m.require_admissible()
    assert tet_quality_summary(pts, tets).n_inverted == 2


def test_readable_checks():
    pts, tets = cube_tets(1)
    with pytest.raises(InvalidMeshError, match=r"points must have shape \(N, 3\)"):
        TetMesh(pts[:, :2], tets)
    with pytest.raises(InvalidMeshError, match="out of range"):
        TetMesh(pts, tets + 1)
    with pytest.raises(InvalidMeshError, match="no tetrahedra"):
        TetMesh(pts, np.zeros((0, 4), int))
    bad = pts.copy()
    bad[2, 1] = np.nan
    with pytest.raises(InvalidMeshError, match="vertex 2"):
        TetMesh(bad, tets)
    m = TetMesh(pts, tets)
    with pytest.raises(ValueError):
        m.points[0, 0] = 1.0  # immutable


def test_face_in_three_tets_is_a_problem():
    pts = np.vstack([CORNER, [[0.2, 0.2, -1.0], [1, 1, 1]]])
    tets = np.array([[0, 1, 2, 3], [0, 2, 1, 4], [0, 1, 2, 5]])
    m = TetMesh(pts, tets)
    assert any("more than two tetrahedra" in p for p in m.problems)


# ----------------------------------------------------------------------------- files
def box_with_hole(path, size: float = 0.35):
    """A gmsh tet mesh of [-1, 1]³ minus a ball of radius 0.4 (physical groups)."""
    from meshopt_toolkit.gmsh_session import gmsh_session

    with gmsh_session(deterministic=True) as gmsh:
        box = gmsh.model.occ.addBox(-1, -1, -1, 2, 2, 2)
        ball = gmsh.model.occ.addSphere(0, 0, 0, 0.4)
        gmsh.model.occ.cut([(3, box)], [(3, ball)])
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [t for _, t in gmsh.model.getEntities(3)], 1,
                                    name="solid")
        gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getEntities(2)], 2,
                                    name="walls")
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    return path


@pytest.fixture(scope="module")
def box_msh(tmp_path_factory):
    return box_with_hole(tmp_path_factory.mktemp("box") / "box.msh")


def per_type(cm: CellMesh):
    """``{type: (cells, physical tags)}`` with the blocks of each type concatenated."""
    phys = cm.cell_data.get("gmsh:physical")
    out = {}
    for i, (t, c) in enumerate(cm.cells):
        tags = np.zeros(len(c), int) if phys is None else np.asarray(phys[i]).reshape(-1)
        a, b = out.get(t, (np.zeros((0, c.shape[1]), int), np.zeros(0, int)))
        out[t] = (np.concatenate([a, c]), np.concatenate([b, tags]))
    return out


def assert_same_tets(a: CellMesh, b: CellMesh, names: bool = True):
    assert a.points.tobytes() == b.points.tobytes()
    pa, pb = per_type(a), per_type(b)
    assert list(pa) == list(pb)
    for t in pa:
        np.testing.assert_array_equal(pa[t][0], pb[t][0], err_msg=t)
        np.testing.assert_array_equal(pa[t][1], pb[t][1], err_msg=t)
    if names:
        assert {k: list(v) for k, v in a.field_data.items()} == \
            {k: list(v) for k, v in b.field_data.items()}


def test_gmsh_box_is_admissible_with_plausible_quality(box_msh):
    m = load_cells(box_msh).to_tet_mesh()
    assert m.is_admissible and m.n_tets > 500
    q = m.quality()
    assert 0.2 < q.min_mean_ratio < 0.5 and 0.7 < q.mean_mean_ratio < 0.95
    assert 0 < q.min_dihedral_deg < 70.5 < q.max_dihedral_deg < 180
    # volume of the box minus the ball, within the faceting of the sphere
    assert q.total_volume == pytest.approx(8 - 4 / 3 * np.pi * 0.4**3, rel=0.02)
    assert m.tag_names == {"solid": (1, 3), "walls": (2, 2)}
    assert set(m.tet_tags.tolist()) == {1} and set(m.triangle_tags.tolist()) == {2}
    # the tagged walls are exactly the boundary faces
    key = lambda f: {tuple(sorted(r)) for r in f.tolist()}  # noqa: E731
    assert key(m.triangles) == key(m.boundary_faces)
    surf = m.boundary_surface()
    assert surf.n_components == 2 and surf.genera == [0, 0] and surf.is_oriented
    # outward faces: the volume they enclose is the tets' volume
    assert surf.enclosed_volume() == pytest.approx(q.total_volume, rel=1e-12)


@pytest.mark.parametrize("binary", [True, False])
def test_tets_round_trip_through_every_format(tmp_path, box_msh, binary):
    # the TetMesh's own cell blocks: its gmsh entities are the physical groups, which Medit
    # keeps (the gmsh writers number them again)
    start = CellMesh.from_tet_mesh(load_cells(box_msh).to_tet_mesh())
    chain = [("a.msh", "4.1"), ("b.msh", "2.2"), ("c.vtu", None), ("d.mesh", None),
             ("e.msh", "4.1"), ("f.mesh", None), ("g.msh", "2.2"), ("h.vtu", None)]
    current = start
    for name, version in chain:
        b = None if name.endswith(".mesh") else binary
        save_cells(current, tmp_path / name, binary=b, msh_version=version or "4.1")
        current = load_cells(tmp_path / name)
        assert_same_tets(start, current)
    # legacy .vtk holds no physical names: round trip without them
    plain = CellMesh(start.points, start.cells, cell_data=start.cell_data)
    save_cells(plain, tmp_path / "i.vtk", binary=binary)
    back = load_cells(tmp_path / "i.vtk")
    assert_same_tets(plain, back)
    save_cells(back, tmp_path / "j.mesh")
    assert_same_tets(plain, load_cells(tmp_path / "j.mesh"))


def test_convert_cli_round_trip(tmp_path, box_msh, capsys):
    start = tmp_path / "s.msh"
    save_cells(CellMesh.from_tet_mesh(load_cells(box_msh).to_tet_mesh()), start)
    assert main(["convert", str(start), "-o", str(tmp_path / "s.mesh")]) == 0
    assert main(["convert", str(tmp_path / "s.mesh"), "-o", str(tmp_path / "t.msh"),
                 "--msh-version", "2.2"]) == 0
    assert main(["convert", str(tmp_path / "t.msh"), "-o", str(tmp_path / "t.vtu")]) == 0
    assert_same_tets(load_cells(start), load_cells(tmp_path / "t.vtu"))


def test_medit_refuses_what_it_cannot_hold(tmp_path, box_msh, capsys):
    # gmsh's CAD entities are not the physical groups: Medit has no place for them
    assert main(["convert", str(box_msh), "-o", str(tmp_path / "b.mesh")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "gmsh:geometrical" in err
    assert not (tmp_path / "b.mesh").exists()
    cm = CellMesh(CORNER, [("tetra", ONE)], point_data={"u": np.ones(4)})
    with pytest.raises(WriteError, match="cannot hold u point data"):
        save_cells(cm, tmp_path / "u.mesh")
    with pytest.raises(WriteError, match="text format"):
        save_cells(CellMesh(CORNER, [("tetra", ONE)]), tmp_path / "v.mesh", binary=True)


def test_medit_keeps_2d_points_and_awkward_names(tmp_path):
    cm = CellMesh(np.array([[0, 0], [1, 0], [0, 1.0]]) / 3, [("triangle", np.array([[0, 1, 2]]))],
                  cell_data={"gmsh:physical": [np.array([4])]},
                  field_data={'a "b" c': np.array([4, 2]), "Vertices": np.array([5, 1])})
    save_cells(cm, tmp_path / "two.mesh")
    back = load_cells(tmp_path / "two.mesh")
    assert back.points.shape == (3, 2) and back.points.tobytes() == cm.points.tobytes()
    assert {k: list(v) for k, v in back.field_data.items()} == {'a "b" c': [4, 2],
                                                                 "Vertices": [5, 1]}
    with pytest.raises(WriteError, match="field data"):
        save_cells(CellMesh(cm.points, cm.cells, field_data={"a\nb": np.array([1, 2])}),
                   tmp_path / "nl.mesh")


def test_medit_reads_references_and_refuses_skipped_sections(tmp_path, capsys):
    text = ("MeshVersionFormatted 2\nDimension 3\nVertices\n4\n0 0 0 1\n1 0 0 0\n0 1 0 0\n"
            "0 0 1 0\nTetrahedra\n1\n1 2 3 4 7\nTriangles\n1\n1 3 2 5\nEnd\n")
    (tmp_path / "a.mesh").write_text(text)
    cm = load_cells(tmp_path / "a.mesh")
    m = cm.to_tet_mesh()
    assert m.tet_tags.tolist() == [7] and m.triangle_tags.tolist() == [5]
    np.testing.assert_array_equal(cm.point_data["medit:ref"], [1, 0, 0, 0])
    (tmp_path / "r.mesh").write_text(text.replace("End", "Ridges\n1\n1\nEnd"))
    assert main(["convert", str(tmp_path / "r.mesh"), "-o", str(tmp_path / "r.vtu")]) == 1
    assert "Ridges" in capsys.readouterr().err
    (tmp_path / "big.mesh").write_text(text.replace("Vertices\n4", "Vertices\n99999999999"))
    with pytest.raises(ReadError, match="announces"):
        load_cells(tmp_path / "big.mesh")


def test_to_tet_mesh_refuses_other_cells():
    cm = CellMesh(CORNER, [("tetra", ONE), ("hexahedron", np.zeros((1, 8), int))],
                  source="h.vtu")
    with pytest.raises(InvalidMeshError, match=r"h\.vtu: has 1 hexahedron cells"):
        cm.to_tet_mesh()
    with pytest.raises(InvalidMeshError, match="no tetrahedra"):
        CellMesh(CORNER, [("triangle", np.array([[0, 1, 2]]))]).to_tet_mesh()


# ----------------------------------------------------------------------------- info
def test_info_on_tets(tmp_path, box_msh, capsys):
    assert main(["info", "--json", str(box_msh)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["cell_kind"] == "tetrahedra" and info["admissible"]
    assert info["n_inverted"] == 0 and info["inverted"] == []
    assert 0.3 <= info["min_mean_ratio"] <= 0.45
    assert info["boundary_closed"] and info["boundary_components"] == 2
    pts, tets = cube_tets(2)
    tets[[4, 9]] = tets[[4, 9]][:, [1, 0, 2, 3]]
    save_cells(CellMesh(pts, [("tetra", tets)]), tmp_path / "bad.vtu")
    assert main(["info", str(tmp_path / "bad.vtu")]) == 0
    out = capsys.readouterr().out
    assert "cell kind            tetrahedra" in out
    assert "problem: 2 tetrahedra are inverted or flat (signed volume <= 0): 4, 9" in out
