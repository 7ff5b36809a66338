"""Surface moves with contact (:mod:`meshopt_toolkit.motion.engine.contact` in
:func:`~meshopt_toolkit.motion.surface.move.move_surface`): an upright flap over a fixed
sheet, its top pushed down past the point where a rigid flap would pierce the sheet. With
contact every frame is free of self-intersections by the exact kernel, the handles land
exactly and nothing folds; without, the frames pass through the sheet."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import meshopt_toolkit as mt
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import SelfIntersectionError
from meshopt_toolkit.io import save_cells
from meshopt_toolkit.io.cells import CellMesh
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.mesh import SurfaceMesh
from meshopt_toolkit.motion.engine.contact import ContactWarning
from meshopt_toolkit.motion.surface.move import SurfaceMoveOptions, move_surface

pytest.importorskip("ipctk")

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from bench_surface_morph_pushes import flap_on_sheet  # noqa: E402


def _pushed(drop: float, shift=(0.0, 0.0)):
    V, F, h, tg, n_sheet = flap_on_sheet()
    tg[n_sheet:] += [shift[0], shift[1], -drop]
    return V, F, h, tg


def _clean(frames, F) -> list[int]:
    return [len(self_intersections(Q, F)) for Q in frames]


def test_without_contact_the_flap_passes_through_the_sheet():
    V, F, h, tg = _pushed(0.6)
    res = move_surface(V, F, h, tg, contact=False)
    assert max(_clean(res.frames, F)) > 0


def test_with_contact_every_frame_is_clean_and_the_handles_exact():
    V, F, h, tg = _pushed(0.6)
    res = move_surface(V, F, h, tg)
    assert _clean(res.frames, F) == [0] * len(res.frames)
    np.testing.assert_array_equal(res.points[h], tg)
    assert res.folds == 0 and res.handle_error == 0.0


def test_mt_move_writes_clean_frames_and_without_contact_refuses():
    V, F, h, tg = _pushed(0.6)
    mesh = SurfaceMesh(V, F)
    res = mt.move(mesh, h, tg, frames=4)
    for frame in res.frames:
        assert not len(self_intersections(frame.points, F))
    with pytest.raises(SelfIntersectionError):
        mt.move(mesh, h, tg, frames=4, contact=False)


def test_a_rest_through_itself_is_moved_with_one_warning():
    V, F, h, tg, n_sheet = flap_on_sheet(gap=-0.5)  # the flap through the sheet
    pairs = len(self_intersections(V, F))
    assert pairs > 0
    tg[n_sheet:] += [0.0, 0.0, 0.1]
    with pytest.warns(ContactWarning, match=rf"intersects itself at rest \({pairs} pairs"):
        res = move_surface(V, F, h, tg)
    np.testing.assert_array_equal(res.points[h], tg)


def _file(path, V, F):
    save_cells(CellMesh(np.asarray(V), [("triangle", np.asarray(F))]), path)
    return path


def test_cli_contact_on_writes_off_refuses(tmp_path, capsys):
    V, F, h, tg = _pushed(0.6)
    src = _file(tmp_path / "flap.vtu", V, F)
    rows = "\n".join(f"{i},{x!r},{y!r},{z!r}" for i, (x, y, z) in zip(h, tg.tolist()))
    (tmp_path / "t.csv").write_text(rows + "\n")
    out = tmp_path / "moved.vtu"
    args = ["move", str(src), "--targets", str(tmp_path / "t.csv"), "--free-boundary",
            "-o", str(out)]
    assert main(args + ["--contact", "off"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0]  # through the sheet, or a fold
    assert not out.exists()
    assert main(args) == 0
    assert out.exists()


@pytest.mark.slow
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(drop=st.floats(0.35, 0.9), dx=st.floats(-0.2, 0.2), dy=st.floats(-0.3, 0.3))
def test_random_pushes_towards_contact_give_clean_frames(drop, dx, dy):
    """The flap's top pushed down and sideways by random amounts, most of them past
    contact: every frame clean by the exact kernel, handles exact, no fold."""
    V, F, h, tg = _pushed(drop, (dx, dy))
    res = move_surface(V, F, h, tg)
    assert _clean(res.frames, F) == [0] * len(res.frames)
    np.testing.assert_array_equal(res.points[h], tg)
    assert res.folds == 0


def test_the_polish_takes_only_trials_clear_of_contact():
    """A sheared flap the polish improves; with every straight path reported in contact
    it moves nothing, and with the CCD of the contact it moves only along clean paths."""
    from meshopt_toolkit.motion.engine.contact import SurfaceContact
    from meshopt_toolkit.motion.surface.polish import polish_worst_triangles

    V, F, h, tg = _pushed(0.3, (0.4, 0.0))
    P = move_surface(V, F, h, tg, options=SurfaceMoveOptions(polish=0)).points
    seen = []

    def never(a, b):
        seen.append(True)
        return False

    assert polish_worst_triangles(V, F, P, h)[1]["polish_vertices"] > 0
    out, info = polish_worst_triangles(V, F, P, h, clear=never)
    assert seen and info["polish_vertices"] == 0
    np.testing.assert_array_equal(out, P)
    contact = SurfaceContact(V, F)
    out, _ = polish_worst_triangles(V, F, P, h, clear=lambda a, b: contact.stepsize(a, b) >= 1)
    assert contact.stepsize(P, out) >= 1.0


def test_cli_warns_in_one_line_naming_the_file_of_a_rest_through_itself(tmp_path, capsys):
    V, F, h, tg, n_sheet = flap_on_sheet(gap=-0.5)  # the flap through the sheet
    tg[n_sheet:] += [0.0, 0.0, 0.1]
    src = _file(tmp_path / "through.vtu", V, F)
    rows = "\n".join(f"{i},{x!r},{y!r},{z!r}" for i, (x, y, z) in zip(h, tg.tolist()))
    (tmp_path / "t.csv").write_text(rows + "\n")
    out = tmp_path / "moved.vtu"
    assert main(["move", str(src), "--targets", str(tmp_path / "t.csv"), "--free-boundary",
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    pairs = len(self_intersections(V, F))
    assert len(err) == 1 and "warning" in err[0] and "through.vtu" in err[0]
    assert f"({pairs} pairs of triangles)" in err[0] and out.exists()
