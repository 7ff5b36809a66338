"""Morphs in space never write a frame whose tet boundary or surface passes through itself:
``mt.morph`` / ``meshopt morph`` refuse ends that cross (naming the end) and a morph with a
crossing frame (``SelfIntersectionGuard.of_morph``, checked exactly by the kernel; a
surface morph without contact here, with contact in test_surface_morph_contact.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from test_tet_move import cube_tets

import meshopt_toolkit as mt
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import SelfIntersectionError
from meshopt_toolkit.io import save_cells
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.tetrahedra import signed_volumes
from meshopt_toolkit.mesh import SurfaceMesh, TetMesh
from meshopt_toolkit.motion.engine.contact import ContactWarning
from meshopt_toolkit.motion.engine.handles import SelfIntersectionGuard
from meshopt_toolkit.motion.surface.mesh_morph import morph_surface_mesh
from meshopt_toolkit.motion.engine.similarity_3d import tet_boundary_faces
from meshopt_toolkit.motion.tets.metric import TetGraphMetric
from meshopt_toolkit.motion.tets.morph import _initial_path, morph_tets
from meshopt_toolkit.motion.tets.path import TetPath

CUBE_P, CUBE_T = cube_tets(1)  # the unit cube in six tets


def _two_blocks(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One tet mesh of two six-tet blocks with corners ``a`` and ``b``."""
    return np.vstack([a, b]), np.vstack([CUBE_T, CUBE_T + len(a)])


#: a wall: the slab 0 ≤ x ≤ 0.2 (y, z in [-0.5, 1.5]); a half-size cube left of it
WALL = CUBE_P * [0.2, 2.0, 2.0] + [0.0, -0.5, -0.5]
CUBE = CUBE_P * 0.5 + [-1.0, 0.25, 0.25]


def cube_through_wall(shift: float = 1.7) -> tuple[TetMesh, TetMesh]:
    """The cube left of the wall and, as the target, moved by ``shift`` along x (1.7: to
    the right of it; any path of rigid translations passes through the wall)."""
    P0, T = _two_blocks(CUBE, WALL)
    P1, _ = _two_blocks(CUBE + [shift, 0.0, 0.0], WALL)
    return TetMesh(P0, T), TetMesh(P1, T)


def _grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The unit square in ``2n²`` triangles: (u, v) of the vertices, the triangles."""
    x = np.linspace(0.0, 1.0, n + 1)
    U, V = np.meshgrid(x, x, indexing="ij")
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = (idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(),
                  idx[:-1, 1:].ravel())
    return np.stack([U.ravel(), V.ravel()], 1), np.vstack([np.stack([a, b, c], 1),
                                                          np.stack([a, c, d], 1)])


def flap_through_sheet(drop: float = 2.0) -> tuple[SurfaceMesh, SurfaceMesh]:
    """A fixed sheet z = 0 over [0, 1]² and an upright flap (y = 0.5, x in [0.3, 0.7],
    z in [0.5, 1.5]) above it; the target has the flap ``drop`` lower (2: below it)."""
    uv, F = _grid(3)
    sheet = np.c_[uv, np.zeros(len(uv))]
    flap = np.c_[0.3 + 0.4 * uv[:, 0], np.full(len(uv), 0.5), 0.5 + uv[:, 1]]
    tris = np.vstack([F, F + len(uv)])
    return (SurfaceMesh(np.vstack([sheet, flap]), tris),
            SurfaceMesh(np.vstack([sheet, flap - [0.0, 0.0, drop]]), tris))


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


# ------------------------------------------------------------------ the library
def test_the_pairs_cross_between_their_ends():
    """The constructions do what they claim: clean ends, crossing linear frames."""
    for src, tgt, tri in ((*cube_through_wall(), None), (*flap_through_sheet(), None)):
        tri = src.boundary_faces if isinstance(src, TetMesh) else src.triangles
        assert not len(self_intersections(src.points, tri))
        assert not len(self_intersections(tgt.points, tri))
        middle = 0.5 * (src.points + tgt.points)
        assert len(self_intersections(middle, tri))
        if isinstance(src, TetMesh):
            assert (signed_volumes(middle, src.tets) > 0).all()  # no tet inverts


def test_tet_morph_through_a_wall_is_refused():
    src, tgt = cube_through_wall()
    with pytest.raises(SelfIntersectionError,
                       match=r"the morph makes the boundary intersect itself at frame \d"):
        mt.morph(src, tgt, 9)
    with pytest.raises(SelfIntersectionError):  # avoidance cannot help: the start crosses
        morph_tets(src, tgt, 9, avoid_crossings=True)
    # the same motion short of the wall is fine, every frame clean
    near = TetMesh(cube_through_wall(0.4)[1].points, src.tets)
    res = mt.morph(src, near, 5)
    for Q in res.points:
        assert not len(self_intersections(Q, src.boundary_faces))


@pytest.mark.parametrize("end", ["source", "target"])
def test_tet_ends_that_cross_are_refused_naming_the_end(end):
    src, tgt = cube_through_wall()
    inside = TetMesh(cube_through_wall(0.8)[1].points, src.tets)  # the cube in the wall
    pair = (inside, tgt) if end == "source" else (src, inside)
    with pytest.raises(SelfIntersectionError,
                       match=rf"^the morph's {end}: the boundary intersects itself: \d+ pairs"
                             r" of triangles \(e\.g\. on vertices \(\d+, \d+, \d+\) and"):
        mt.morph(*pair, 5)
    named = TetMesh(inside.points, src.tets, source="inside.msh")
    with pytest.raises(SelfIntersectionError, match=r"^inside\.msh: the boundary"):
        mt.morph(named, tgt, 5)


def test_surface_morph_through_a_sheet_is_refused_without_contact():
    src, tgt = flap_through_sheet()
    with pytest.raises(SelfIntersectionError,
                       match=r"the morph makes the surface intersect itself at frame \d"):
        morph_surface_mesh(src, tgt, 9, contact=False)
    trimesh = pytest.importorskip("trimesh")
    as_trimesh = [trimesh.Trimesh(m.points, m.triangles, process=False) for m in (src, tgt)]
    for frame in mt.morph(*as_trimesh, 9).frames:  # trimesh in: with contact, clean
        assert not len(self_intersections(np.asarray(frame.vertices), src.triangles))
    # the flap lowered to just above the sheet: every frame clean
    res = mt.morph(src, flap_through_sheet(0.4)[1], 5)
    for frame in res.frames:
        assert not len(self_intersections(frame.points, src.triangles))
    # a surface end through itself is the user's: such a morph is not checked
    inside = SurfaceMesh(flap_through_sheet(1.0)[1].points, src.triangles)
    assert len(self_intersections(inside.points, src.triangles))
    with pytest.warns(ContactWarning, match="the source intersects itself"):
        assert mt.morph(inside, tgt, 5).n_frames == 5


def test_guard_of_a_morph_checks_arrays_and_can_leave_the_target():
    src, tgt = cube_through_wall()
    guard = SelfIntersectionGuard.of_morph(src, tgt)
    t = np.linspace(0.0, 1.0, 5)[:, None, None]
    frames = (1 - t) * src.points + t * tgt.points
    with pytest.raises(SelfIntersectionError, match="at frame 2"):
        guard.check(frames, motion="the morph", last=False)
    guard.check(frames[[0, 4]], motion="the morph", last=False)  # nothing in between
    bad_last = frames[[0, 2]]
    guard.check(bad_last, last=False)
    with pytest.raises(SelfIntersectionError, match="the motion .* at the result"):
        guard.check(bad_last)


# ------------------------------------------------------------------ avoidance in the path
def test_tet_path_refuses_a_trial_through_itself():
    src, tgt = cube_through_wall()
    faces = tet_boundary_faces(src.tets)
    metric = TetGraphMetric(src.points, src.tets, 1.0)
    t = np.linspace(0.0, 1.0, 3)[:, None, None]
    frames = (1 - t) * src.points + t * tgt.points  # the middle frame crosses
    crosses = lambda Q: bool(len(self_intersections(Q, faces)))  # noqa: E731
    assert TetPath(metric, frames).admissible(frames)  # every tet positive
    assert not TetPath(metric, frames, crosses=crosses).admissible(frames)
    clean = frames.copy()
    clean[1] = src.points
    assert TetPath(metric, clean, crosses=crosses).admissible(clean)


def test_auto_start_skips_a_linear_path_through_itself():
    src, tgt = cube_through_wall()
    faces = tet_boundary_faces(src.tets)
    metric = TetGraphMetric(src.points, src.tets, 1.0)
    times = np.linspace(0.0, 1.0, 5)
    b = np.unique(faces)
    args = (metric, src.points, tgt.points, src.tets, b, times)
    assert _initial_path(*args, "auto", 12, None)[1] == "linear"  # not asked
    crosses = lambda Q: bool(len(self_intersections(Q, faces)))  # noqa: E731
    assert _initial_path(*args, "auto", 12, crosses)[1] == "continuation"
    assert _initial_path(*args, "linear", 12, crosses)[1] == "linear"  # as asked
    # a clean linear path is kept
    near = cube_through_wall(0.4)[1].points
    assert _initial_path(metric, src.points, near, src.tets, b, times, "auto", 12,
                         crosses)[1] == "linear"


def test_avoidance_reaches_the_geodesic_on_request(monkeypatch):
    import meshopt_toolkit.motion.tets.metric as tet_metric

    seen = []

    class Spy(TetPath):
        def __init__(self, metric, frames, crosses=None):
            seen.append(crosses)
            super().__init__(metric, frames, crosses)

    monkeypatch.setattr(tet_metric, "TetPath", Spy)  # the tet metric's path model
    P, T = cube_tets(2, 0.2, 1)
    Q = P * [1.0, 1.0, 1.3] + 0.05 * np.sin(3.0 * P[:, [1, 2, 0]])
    res = morph_tets(TetMesh(P, T), TetMesh(Q, T), 4, avoid_crossings=True)
    plain = morph_tets(TetMesh(P, T), TetMesh(Q, T), 4)
    assert callable(seen[0]) and seen[1] is None
    through = P.copy()
    through[0] = [1.5, 1.5, 1.5]  # the corner (0, 0, 0) pulled out through the face x = 1
    assert not seen[0](res.points[1]) and seen[0](through)
    np.testing.assert_array_equal(res.points, plain.points)  # no trial crossed here


# ------------------------------------------------------------------ random admissible morphs
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), angle=st.floats(0.0, 170.0),
       noise=st.floats(0.0, 0.06), frames=st.integers(3, 6), avoid=st.booleans())
def test_random_small_morphs_write_only_clean_frames(seed, angle, noise, frames, avoid):
    """A jittered 2×2×2 cube and its rigid image with the vertices perturbed: every
    frame returned has every tet positive and a boundary free of self-intersections."""
    P, T = cube_tets(2, 0.2, seed % 1000)
    rng = np.random.default_rng(seed)
    axis = rng.standard_normal(3)
    R = Rotation.from_rotvec(np.radians(angle) * axis / np.linalg.norm(axis))
    Q = R.apply(P) + rng.uniform(-2, 2, 3) + noise * rng.uniform(-1, 1, P.shape)
    if not (signed_volumes(Q, T) > 0).all():
        Q = R.apply(P)  # the perturbation inverted a tet: the rigid image
    src, tgt = TetMesh(P, T), TetMesh(Q, T)
    res = (morph_tets(src, tgt, frames, max_iterations=30, avoid_crossings=True) if avoid
           else mt.morph(src, tgt, frames, max_iterations=30))
    for X in res.points:
        assert (signed_volumes(X, T) > 0).all()
        assert not len(self_intersections(X, src.boundary_faces))


# ------------------------------------------------------------------ command line
def _tet_file(path, mesh: TetMesh):
    save_cells(CellMesh(np.asarray(mesh.points), [("tetra", np.asarray(mesh.tets))]), path)
    return path


def _surface_file(path, mesh: SurfaceMesh):
    save_cells(CellMesh(np.asarray(mesh.points), [("triangle", np.asarray(mesh.triangles))]),
               path)
    return path


def test_cli_morph_through_itself_writes_nothing(tmp_path, capsys):
    src, tgt = cube_through_wall()
    a, b = _tet_file(tmp_path / "a.vtu", src), _tet_file(tmp_path / "b.vtu", tgt)
    out = tmp_path / "frames"
    assert main(["morph", str(a), str(b), "-o", str(out), "--frames", "9"]) == 1
    assert "the morph makes the boundary intersect itself at frame" in _one_line(capsys)
    assert not out.exists()
    s, t = flap_through_sheet()
    a, b = _surface_file(tmp_path / "s.vtu", s), _surface_file(tmp_path / "t.vtu", t)
    assert main(["morph", str(a), str(b), "-o", str(out), "--frames", "9",
                 "--contact", "off"]) == 1
    assert "the morph makes the surface intersect itself at frame" in _one_line(capsys)
    assert not out.exists()


def test_cli_crossing_end_is_named(tmp_path, capsys):
    src, tgt = cube_through_wall()
    inside = TetMesh(cube_through_wall(0.8)[1].points, src.tets)
    a = _tet_file(tmp_path / "a.vtu", src)
    bad = _tet_file(tmp_path / "inside.vtu", inside)
    out = tmp_path / "frames"
    assert main(["morph", str(a), str(bad), "-o", str(out)]) == 1
    line = _one_line(capsys)
    assert "inside.vtu" in line and "the boundary intersects itself" in line
    assert "pairs of triangles (e.g. on vertices" in line
    assert not out.exists()
