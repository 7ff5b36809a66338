"""Surface morphs with contact (:mod:`meshopt_toolkit.motion.surface.morph_contact`): a
flap moved from above a sheet to below it, whose straight-line interpolation passes through
the sheet, morphs around it with every frame clean by the exact kernel, the motion between
frames clean by ipctk's CCD, and every frame as healthy as the worse end; without contact
the morph is refused. Random pushes of the flap towards the sheet: every frame of the move
and of the morph back clean."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_morph_self_intersection import _surface_file, flap_through_sheet
from test_surface_contact_move import _pushed

import meshopt_toolkit as mt
from meshopt_toolkit.cli import main
from meshopt_toolkit.diagnostics import check_gradient
from meshopt_toolkit.errors import SelfIntersectionError
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.surface import aspect_ratios
from meshopt_toolkit.mesh import SurfaceMesh
from meshopt_toolkit.motion.engine.contact import ContactWarning, pair_contact
from meshopt_toolkit.motion.surface.mesh_morph import morph_surface_mesh
from meshopt_toolkit.motion.surface.morph import morph_surface
from meshopt_toolkit.motion.surface.morph_contact import PathContact
from meshopt_toolkit.motion.surface.move import SurfaceMoveOptions, move_surface
from meshopt_toolkit.motion.surface.path_system import PathSystem

ipctk = pytest.importorskip("ipctk")


def _crossings(frames, F) -> list[int]:
    return [len(self_intersections(np.asarray(Q), F)) for Q in frames]


def _steps_collision_free(frames, F) -> bool:
    """ipctk's own CCD over each straight segment between consecutive frames."""
    E = ipctk.edges(np.asarray(F, np.int32))
    mesh = ipctk.CollisionMesh(np.asarray(frames[0], float), E, np.asarray(F, np.int32))
    return all(ipctk.is_step_collision_free(mesh, np.asarray(a, float), np.asarray(b, float))
               for a, b in zip(frames[:-1], frames[1:]))


def _worst(Q, V0, F) -> float:
    return float((aspect_ratios(Q, F) / aspect_ratios(V0, F)).min())


def test_the_flap_morphs_around_the_sheet_with_clean_frames():
    src, tgt = flap_through_sheet()  # the straight line passes through the sheet
    F = src.triangles
    t = np.linspace(0.0, 1.0, 9)[:, None, None]
    assert max(_crossings((1 - t) * src.points + t * tgt.points, F)) > 0
    res = mt.morph(src, tgt, 9)
    frames = [f.points for f in res.frames]
    assert _crossings(frames, F) == [0] * 9
    assert _steps_collision_free(frames, F)
    floor = min(_worst(src.points, src.points, F), _worst(tgt.points, src.points, F))
    for Q in frames:  # as healthy as the worse end, to the rounding of the aspect ratios
        assert _worst(Q, src.points, F) >= floor * (1.0 - 1e-12)
    assert res.morph.initial_path == "detour"
    np.testing.assert_array_equal(frames[0], src.points)
    np.testing.assert_array_equal(frames[-1], tgt.points)
    with pytest.raises(SelfIntersectionError, match="at frame"):
        morph_surface_mesh(src, tgt, 9, contact=False)


def test_minimizing_with_the_barrier_active_keeps_every_frame_clean(monkeypatch):
    """Two poses of the flap pressed onto the sheet from either side (moves with
    contact), morphed to the energy tests alone: the barrier comes into play in the
    frames, every frame and every motion between frames stays clean; without contact the
    frames pass through the sheet."""
    import meshopt_toolkit.motion.surface.morph_contact as smc

    poses = []
    for push in ((0.2, 0.3), (-0.2, -0.3)):
        V, F, h, tg = _pushed(0.9, push)
        poses.append(SurfaceMesh(move_surface(V, F, h, tg).points, F))
    active, hessians = [], smc.PathContact.hessians

    def spy(self, path):
        out = hessians(self, path)
        active.append(sum(H is not None for H in out))
        return out

    monkeypatch.setattr(smc.PathContact, "hessians", spy)
    res = morph_surface_mesh(*poses, 9, stop_when_healthy=False, max_iterations=20)
    assert res.morph.iterations > 0 and max(active) > 0
    frames = [f.points for f in res.frames]
    assert _crossings(frames, F) == [0] * 9
    assert _steps_collision_free(frames, F)
    with pytest.raises(SelfIntersectionError, match="at frame"):
        morph_surface_mesh(*poses, 9, stop_when_healthy=False, contact=False)


def test_far_from_contact_the_morph_is_the_one_without_bitwise():
    """No pair comes within d̂ and no step is capped: contact changes nothing."""
    from test_surface_morph import PAIRS

    V0, F, V1 = PAIRS["sphere"]()
    on = morph_surface(V0, V1, F, 6, stop_when_healthy=False)
    off = morph_surface(V0, V1, F, 6, stop_when_healthy=False, contact=False)
    assert on.iterations > 0
    np.testing.assert_array_equal(on.points, off.points)


@pytest.mark.slow
def test_too_few_frames_for_a_detour_are_refused():
    src, tgt = flap_through_sheet()
    with pytest.raises(SelfIntersectionError, match="no path free of self-contact"):
        morph_surface_mesh(src, tgt, 3)


def test_an_end_through_itself_is_morphed_without_contact_with_one_warning():
    src, tgt = flap_through_sheet()
    inside = SurfaceMesh(flap_through_sheet(1.0)[1].points, src.triangles)
    pairs = len(self_intersections(inside.points, src.triangles))
    assert pairs > 0
    with pytest.warns(ContactWarning, match=rf"the target intersects itself \({pairs} pairs"):
        assert morph_surface_mesh(src, inside, 5).n_frames == 5


def _near_contact_path():
    """The flap lowered to within d̂ of the sheet in the middle frame of three."""
    src, _ = flap_through_sheet()
    V0, F = np.asarray(src.points), src.triangles
    contact = pair_contact(V0, V0, F)
    low = V0.copy()
    low[16:, 2] -= 0.5 - 0.4 * contact.dhat  # the flap's bottom 0.4 d̂ above the sheet
    return [V0, low, V0], F, contact


def test_barrier_gradient_of_the_path_passes_the_taylor_test():
    path, F, contact = _near_contact_path()
    pc = PathContact(contact, 3, np.ones(path[0].size))
    assert pc.set_stiffness(path, np.ones(path[0].size))
    assert pc.energy(path) > 0

    def at(x):
        return [path[0], x.reshape(-1, 3), path[2]]

    rng = np.random.default_rng(3)
    v = rng.standard_normal(path[1].size)
    r = check_gradient(lambda x: pc.energy(at(x)), lambda x: pc.gradient(at(x)),
                       path[1].ravel(), v, eps0=1e-4 * contact.dhat)
    assert r.passed, (r.order, r.remainders)


def test_the_path_system_adds_each_frames_barrier_block():
    """``product`` against the assembled matrix ``𝔻ᵀ(T ⊗ I)𝔻 + λ diag + blockdiag B``."""
    import scipy.sparse as sp

    rng = np.random.default_rng(5)
    D = [sp.random(12, 6, density=0.5, random_state=k, format="csr") for k in range(3)]
    B = [None, sp.csr_matrix(np.diag(rng.uniform(1, 2, 6))), None]
    system = PathSystem(4)
    system.update(D, 0.1, True, B)
    H = sp.block_diag(D).T @ sp.kron(system.T, sp.eye(12)) @ sp.block_diag(D)
    H = H.toarray()
    full = H + 0.1 * np.diag(np.diag(H)) + sp.block_diag(
        [b if b is not None else sp.csr_matrix((6, 6)) for b in B]).toarray()
    v = rng.standard_normal(18)
    np.testing.assert_allclose(system.product(v), full @ v, rtol=1e-12, atol=1e-12)
    x = system.solve(full @ v, rtol=1e-12, max_iterations=200)
    np.testing.assert_allclose(x, v, rtol=1e-6, atol=1e-8)


def test_steps_are_capped_before_the_sheet_and_crossing_paths_are_not_clean():
    path, F, contact = _near_contact_path()
    pc = PathContact(contact, 3, np.ones(path[0].size))
    down = np.zeros_like(path[1])
    down[16:, 2] = -1.0  # through the sheet
    cap = pc.cap(path, down.ravel())
    assert 0.0 < cap < 1.0
    stopped = path[1] + cap * down
    assert not len(self_intersections(stopped, F))
    assert not pc.clean([path[0], path[1] + down, path[2]])
    assert pc.clean(path)


def _pushed_poses(push, other, options=None) -> list:
    """The flap's top pushed down and sideways towards the sheet by two motions (moves with
    contact, ``options`` of :func:`move_surface`), every frame of the moves clean by the
    exact kernel: the two poses."""
    poses = []
    for drop, dx, dy in (push, other):
        V, F, h, tg = _pushed(drop, (dx, dy))
        moved = move_surface(V, F, h, tg, options=options)
        assert _crossings(moved.frames, F) == [0] * len(moved.frames)
        poses.append(SurfaceMesh(moved.points, F))
    return poses


def _pushes_move_and_morph_clean(push, other, options=None):
    """:func:`_morphs_clean` of :func:`_pushed_poses` in five frames."""
    _morphs_clean(_pushed_poses(push, other, options), 5)


#: the moves that made the poses the search below found: the last increment stopped
#: after its first 30 steps (the poses are the morph's input; other moves give others)
SEARCHED_MOVE = SurfaceMoveOptions(final_late_iterations=0)


def _morphs_clean(poses, n_frames: int):
    """The morph from one pose to the other: every frame clean by the exact kernel, the
    motion between frames by ipctk's CCD, every frame as healthy as the worse end."""
    F = poses[0].triangles
    res = mt.morph(*poses, n_frames)
    frames = [f.points for f in res.frames]
    assert _crossings(frames, F) == [0] * n_frames
    assert _steps_collision_free(frames, F)
    V0 = poses[0].points
    floor = min(_worst(V0, V0, F), _worst(poses[1].points, V0, F))
    for Q in frames:  # as healthy as the worse end, to the rounding of the aspect ratios
        assert _worst(Q, V0, F) >= floor * (1.0 - 1e-12)


@pytest.mark.slow
@settings(max_examples=4, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(push=st.tuples(st.floats(0.35, 0.9), st.floats(-0.2, 0.2), st.floats(-0.3, 0.3)),
       other=st.tuples(st.floats(0.0, 0.9), st.floats(-0.2, 0.2), st.floats(-0.3, 0.3)))
def test_random_pushes_towards_contact_move_and_morph_clean(push, other):
    """:func:`_pushes_move_and_morph_clean` on random pushes (the same draws on every
    machine; the pair below is one such a search found)."""
    _pushes_move_and_morph_clean(push, other)


@pytest.mark.slow
def test_a_deep_push_and_a_sideways_push_morph_clean():
    """Two pushes a random search found (the second at the deepest drop, its flap's foot
    slid off the sheet's edge): both ends lie within 10⁻⁵ of the sheet; a homotopy pressed
    onto it by a barrier as thin as that gap creeps behind its guide, one with the
    surface's own d̂ slides round the edge."""
    _pushes_move_and_morph_clean((0.6460327268859277, 0.0, 0.0),
                                 (0.9, 0.1666557411386091, -0.1057174463745035))


@pytest.mark.slow
def test_a_push_off_the_far_edge_and_one_off_the_near_edge_morph_clean():
    """Two pushes a random search found: the flap's foot slid past the sheet's far edge at
    one end, off its near edge at the other, so it slides across the whole sheet."""
    _pushes_move_and_morph_clean(
        (0.6909579028414907, -0.12514264538371248, -0.03911195257404665),
        (0.795530218249932, -0.049850393192214515, 0.1265289319179202))


@pytest.mark.slow
def test_a_push_onto_the_sheet_and_one_draped_over_its_far_edge_morph_clean():
    """Two pushes a random search found: at the target an edge of the flap's foot lies over
    the sheet's far edge, 3·10⁻⁵ of the sheet's size from it (0.31 at the source). A
    segment between frames may bring a pair from any distance down to a floor (10⁻⁴ of the
    diagonal) and below it by fivefold at most, so five frames close in on that pair."""
    poses = _pushed_poses(
        (0.46946621693681967, -0.07392690114262734, -0.14511548888724699),
        (0.8804710235827953, 0.17640239786057393, -0.09558829448609454), SEARCHED_MOVE)
    _morphs_clean(poses, 5)


def test_cli_contact_on_writes_clean_frames_off_refuses(tmp_path, capsys):
    src, tgt = flap_through_sheet()
    a, b = _surface_file(tmp_path / "s.vtu", src), _surface_file(tmp_path / "t.vtu", tgt)
    out = tmp_path / "frames"
    args = ["morph", str(a), str(b), "-o", str(out), "--frames", "7"]
    assert main(args + ["--contact", "off"]) == 1
    assert "intersect itself at frame" in capsys.readouterr().err
    assert not out.exists()
    assert main(args) == 0
    from meshopt_toolkit.io import load_cells

    frames = [load_cells(p).points for p in sorted(out.glob("frame_*.vtu"))]
    assert len(frames) == 7 and _crossings(frames, src.triangles) == [0] * 7


def test_filter_morphs_around_the_sheet_and_without_contact_refuses():
    from meshopt_toolkit.errors import FilterError
    from meshopt_toolkit.pipeline import Document
    from meshopt_toolkit.pipeline.filter import registry

    src, tgt = flap_through_sheet()
    doc = Document([src, tgt])
    with pytest.raises(FilterError, match="intersect itself at frame"):
        registry.get("generate_geodesic_morph")()(doc, frames=5, contact=False)
    assert len(doc) == 2
    registry.get("generate_geodesic_morph")()(doc, frames=5)
    frames = [np.asarray(e.mesh.points) for e in doc.entries[2:]]
    assert len(frames) == 5 and _crossings(frames, src.triangles) == [0] * 5


def test_cli_names_the_file_of_an_end_through_itself(tmp_path, capsys):
    src, _ = flap_through_sheet()
    inside = SurfaceMesh(flap_through_sheet(1.0)[1].points, src.triangles)
    pairs = len(self_intersections(inside.points, src.triangles))
    a = _surface_file(tmp_path / "s.vtu", src)
    b = _surface_file(tmp_path / "inside.vtu", inside)
    assert main(["morph", str(a), str(b), "-o", str(tmp_path / "f"), "--frames", "3"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "warning" in err[0]
    assert f"inside.vtu intersects itself ({pairs} pairs of triangles)" in err[0]


def _squashed(seed: int, lift: float):
    """The flap squashed to half its height, its bottom edge ``lift`` d̂ above the sheet,
    its points shaken within its plane: the path (source, it, source), the morph's path
    problem and its contact."""
    from meshopt_toolkit.motion.surface.metric import BENDING, WEIGHT
    from meshopt_toolkit.motion.surface.morph import _PathProblem

    src, _ = flap_through_sheet()
    V0, F = np.asarray(src.points), src.triangles
    contact = pair_contact(V0, V0, F)
    rng = np.random.default_rng(seed)
    low = V0.copy()
    low[16:, 0] += rng.uniform(-0.03, 0.03, 16)
    low[16:, 2] = 0.5 * (low[16:, 2] - 0.5) + rng.uniform(-0.05, 0.05, 16)
    low[16::4, 2] = lift * contact.dhat  # the flap's bottom edge (v = 0)
    problem = _PathProblem(V0, V0, F, WEIGHT, BENDING)
    return [V0, low, V0], F, problem, PathContact(contact, 3, problem.sqrt_m ** 2)


@pytest.mark.slow
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), lift=st.floats(0.1, 0.9))
def test_polished_frames_rise_and_stay_clean(seed, lift):
    """A middle frame of :func:`_squashed` (below the ends' quality): the polish of the
    morph's frames raises its worst relative quality or leaves the frame, every frame clean
    by the exact kernel and every segment by ipctk's CCD, the ends bitwise."""
    from hypothesis import assume

    from meshopt_toolkit.motion.surface.morph_polish import polish_frames

    path, F, problem, guard = _squashed(seed, lift)
    V0, low = path[0], path[1]
    assume(problem.embed(low) is not None and problem.admissible(low) and guard.clean(path))
    out, polished = polish_frames(problem, path, guard)
    assert out[0] is V0 and out[2] is V0
    assert _worst(out[1], V0, F) >= _worst(low, V0, F)
    assert polished == int(out[1] is not low)
    assert _crossings(out, F) == [0] * 3
    assert _steps_collision_free(out, F)


def test_the_polish_without_contact_passes_the_flap_through_the_sheet():
    """The constraint matters: polished without contact, the squashed flap stretches down
    through the sheet."""
    from meshopt_toolkit.motion.surface.morph_polish import polish_frames

    path, F, problem, guard = _squashed(0, 0.1)
    assert guard.clean(path)
    out, polished = polish_frames(problem, path)
    assert polished == 1 and not guard.clean(out)
    assert max(_crossings(out, F)) > 0
