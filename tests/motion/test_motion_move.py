"""move (motion/move.py): similarity motions followed exactly, handles exact, no
triangle inverted where the harmonic extension inverts, the proven bound, bad input,
and the filter and CLI over it.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh
from hypothesis import given
from hypothesis import strategies as st
from motion_helpers import FAST, _similar

from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.kernels.triangles import aspect_ratios, inverse_shape_quality
from meshopt_toolkit.motion.move import move
from meshopt_toolkit.motion.planar.distortion import shape_quality_bound


@FAST
@given(angle=st.floats(-3.1, 3.1), scale=st.floats(0.2, 5), shift=st.tuples(
    st.floats(-5, 5), st.floats(-5, 5)))
def test_move_by_a_similarity_moves_the_whole_mesh_by_it(angle, scale, shift):
    mesh = grid_mesh(3, jitter=0.3)
    handles = np.unique(mesh.boundary_edges)
    targets = _similar(mesh.points[handles], angle, scale, shift)
    result = move(mesh, handles, targets, frames=3)
    assert np.array_equal(result.mesh.points[handles], targets)
    expected = _similar(mesh.points, angle, scale, shift)
    np.testing.assert_allclose(result.mesh.points, expected, atol=1e-9 * (1 + scale))
    for frame in result.frames:
        np.testing.assert_allclose(aspect_ratios(frame.points, mesh.triangles),
                                   aspect_ratios(mesh.points, mesh.triangles), rtol=1e-9)


def _harmonic_inverts(mesh, handles, targets) -> int:
    """Harmonic extension with the same handles (the classical reference): inverted count."""
    import scipy.sparse.linalg as spla

    from meshopt_toolkit.fem.elasticity import p1_gradients

    P, T = mesh.points, mesh.triangles
    grads, area = p1_gradients(P, T)
    Ke = np.einsum("t,tid,tjd->tij", area, grads, grads)
    rows = np.repeat(T, 3, axis=1).ravel()
    cols = np.tile(T, (1, 3)).ravel()
    import scipy.sparse as sp

    L = sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(len(P),) * 2)
    free = np.setdiff1d(np.arange(len(P)), handles)
    Q = P.copy()
    Q[handles] = targets
    rhs = -(L[free][:, handles] @ targets)
    Q[free] = spla.spsolve(L[free][:, free].tocsc(), rhs)
    return int(np.sum(mesh.with_points(Q).signed_areas() <= 0))


@pytest.mark.parametrize("degrees", [90, 180])
def test_move_turns_the_annulus_hole_without_inverting(annulus, degrees):
    from meshopt_toolkit.generate import rotate_inner_boundary

    handles, targets = rotate_inner_boundary(annulus, degrees)
    assert _harmonic_inverts(annulus, handles, targets) > 0  # the classical method fails here
    result = move(annulus, handles, targets, frames=4)
    assert np.array_equal(result.mesh.points[handles], targets)  # bitwise
    for frame in result.frames:
        assert (frame.signed_areas() > 0).all()
    assert result.inverted == 0 and result.handle_error == 0.0
    assert np.array_equal(result.mesh.triangles, annulus.triangles)


def test_move_finishes_every_frame_and_keeps_the_proven_bound(annulus):
    """``frames=K``: every intermediate frame gets the quality step (it keeps the best of
    its rounds and the unfinished frame, so no frame gets worse — by construction; that
    some frame improves is what shows the step ran), the handles stay where
    the motion puts them at that time, and the quality bound 1/ψ ≤ exp(asinh(√2ℓ/w))/ψ0
    holds along the frames returned."""
    from meshopt_toolkit.generate import rotate_inner_boundary

    handles, targets = rotate_inner_boundary(annulus, 90)
    raw = move(annulus, handles, targets, frames=5, finish_frames=False)
    seen = []
    done = move(annulus, handles, targets, frames=5, progress=seen.append)
    assert np.all(np.diff(seen) >= 0) and seen[-1] == 1.0  # the frames' steps are counted
    assert (done.min_aspect_ratio >= raw.min_aspect_ratio).all()
    assert done.min_aspect_ratio[1:-1].min() > raw.min_aspect_ratio[1:-1].min()
    q0 = inverse_shape_quality(annulus.points, annulus.triangles)
    for a, b, ell in zip(raw.frames, done.frames, done.strain_bound):
        assert np.array_equal(a.points[handles], b.points[handles])
        assert (b.signed_areas() > 0).all()
        assert (inverse_shape_quality(b.points, annulus.triangles)
                <= shape_quality_bound(q0, np.full(len(q0), ell)) * (1 + 1e-9)).all()


def test_move_rejects_bad_input(annulus):
    b = np.unique(annulus.boundary_edges)
    # the words of the checks every kind of mesh shares (motion/engine/handles.py)
    with pytest.raises(InvalidMeshError, match=rf"handles\[0\] = {annulus.n_vertices} is out "
                       "of range"):
        move(annulus, np.array([annulus.n_vertices]), np.zeros((1, 2)))
    with pytest.raises(InvalidMeshError, match=r"targets\[0\] \(of vertex \d+\) is not finite"):
        move(annulus, b[:2], np.array([[0.0, np.nan], [1.0, 1.0]]))
    with pytest.raises(InvalidMeshError, match="twice with different targets"):
        move(annulus, np.array([b[0], b[0]]), np.array([[0.0, 0.0], [1.0, 1.0]]))
    crossing = annulus.points[b].copy()
    inner = np.hypot(*crossing.T) < 0.5
    crossing[inner] += [0.9, 0.0]  # the hole's circle cuts the outer circle
    with pytest.raises(InvalidMeshError, match="cross itself"):
        move(annulus, b, crossing)


def test_move_reports_targets_without_admissible_interior(annulus):
    from meshopt_toolkit.motion.engine.continuation import NoAdmissiblePathError

    b = np.unique(annulus.boundary_edges)
    outside = annulus.points[b].copy()
    inner = np.hypot(*outside.T) < 0.5
    outside[inner] *= 4.0  # the hole would enclose the outer circle: no mesh fits between
    with pytest.raises(NoAdmissiblePathError, match="no admissible"):
        move(annulus, b, outside, steps=2, max_splits=3)


def test_move_filter_and_cli_agree(annulus, tmp_path):
    """The pipeline filter and ``meshopt move`` run the same operation."""
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import load, save
    from meshopt_toolkit.pipeline import Pipeline

    src = tmp_path / "annulus.msh"
    save(annulus, src)
    mapping = "x*cos(pi/3) - y*sin(pi/3); x*sin(pi/3) + y*cos(pi/3)"
    where = "x**2 + y**2 < 0.25"
    assert main(["move", str(src), "-o", str(tmp_path / "cli.msh"), "--map", mapping,
                 "--where", where]) == 0
    pipe = Pipeline.from_dict({"filters": [
        {"name": "apply_coord_prescribed_motion", "params": {"map": mapping, "where": where}}]})
    from meshopt_toolkit.pipeline import Document

    doc = Document()
    doc.add(annulus, name="annulus")
    pipe.run(doc)
    cli = load(tmp_path / "cli.msh")
    assert (cli.signed_areas() > 0).all()
    assert np.array_equal(doc.current_entry.mesh.points, cli.points)


def test_move_cli_errors_are_one_line(annulus, tmp_path, capsys):
    from meshopt_toolkit.cli import main
    from meshopt_toolkit.io import save

    src = tmp_path / "annulus.msh"
    save(annulus, src)
    for extra, expected in ((["--map", "1/0; y"], "--map '1/0; y'"),
                            (["--map", "x; y +"], "--map 'x; y +': invalid syntax"),
                            (["--map", "x; q"], "--map 'x; q': unknown name 'q'"),
                            (["--map", "x; y", "--where", "x <"], "--where 'x <'"),
                            (["--map", "x; y", "--where", "z < 1"],
                             "--where 'z < 1': 'z': z is not defined for a planar mesh"),
                            (["--map", "x; y", "--frames", "1"], "--frames")):
        assert main(["move", str(src), "-o", str(tmp_path / "o.msh"), *extra]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expected in err[0] and "internal error" not in err[0]
        assert "syntax: invalid syntax" not in err[0]
    assert not (tmp_path / "o.msh").exists()
