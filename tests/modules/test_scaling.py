"""Unit-size work: exact power-of-two scaling, and deform/morph/move at 1e±300."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from cli_helpers import timeless

from meshopt_toolkit import data_path, strict_json
from meshopt_toolkit.cli import main
from meshopt_toolkit.errors import InvalidMeshError
from meshopt_toolkit.io import load, save
from meshopt_toolkit.scaling import UnitScale, at_unit_size, size_scale, unit_scale

DISC = load(data_path("disc_25.msh")).as_planar()


@settings(max_examples=60, deadline=None)
@given(exponent=st.integers(-1000, 1000), mantissa=st.floats(0.5, 2.0))
def test_scale_is_a_power_of_two_near_the_size_and_exact(exponent, mantissa):
    size = mantissa * 2.0 ** (exponent // 2) * 2.0 ** (exponent - exponent // 2)
    pts = DISC.points * size  # the disc has half-extent 1 (to rounding)
    s = unit_scale(pts)
    down = s.down(pts)
    half = 0.5 * (down.max(axis=0) - down.min(axis=0)).max()
    assert 2 ** -0.5 * (1 - 1e-12) <= half < 2 ** 0.5 * (1 + 1e-12)
    if np.isfinite(pts).all() and np.abs(pts).min(initial=np.inf) > 1e-300:
        assert np.array_equal(s.up(down), pts)  # exact both ways


def test_unit_size_meshes_are_untouched_and_edge_cases():
    assert unit_scale(DISC).exponent == 0
    assert unit_scale(DISC).mesh_down(DISC) == DISC
    assert unit_scale(np.zeros((3, 2))).is_identity  # all points coincide
    assert unit_scale(np.empty((0, 2))).is_identity
    assert unit_scale(np.array([[-1.7e308, 0.0], [1.7e308, 1.0]])).exponent == 1024
    with pytest.raises(InvalidMeshError, match="not finite"):
        unit_scale(np.array([[0.0, np.nan]]))


@settings(max_examples=60, deadline=None)
@given(k=st.integers(-990, 990), factor=st.floats(0.5, 2.0), seed=st.integers(0, 2**16))
def test_size_scale_brings_every_scale_to_one_problem(k, factor, seed):
    """The unit points of ``X`` and of ``2**k X`` are the same numbers, of ``c X`` (c not
    a power of two) the same to rounding; back at the user's scale to rounding, exactly
    where a point did not move."""
    X = DISC.points * factor
    unit = size_scale(X).down(X)
    half = 0.5 * (unit.max(axis=0) - unit.min(axis=0)).max()
    assert half == pytest.approx(1.0, rel=1e-15)
    big = np.ldexp(X, k)
    s = size_scale(big)
    assert np.array_equal(s.down(big), unit)  # powers of two: bitwise
    assert np.abs(size_scale(DISC.points).down(DISC.points) - unit).max() <= 4e-16
    moved = unit.copy()
    moved[np.random.default_rng(seed).integers(0, len(unit), 5)] += 1e-3
    back = s.points_up(moved, big)
    still = (moved == unit).all(axis=1)
    assert np.array_equal(back[still], big[still])
    assert np.allclose(back[~still], np.ldexp(X + 1e-3 * factor, k)[~still], rtol=1e-12)


def test_at_unit_size_leaves_a_unit_mesh_alone_and_scales_every_length():
    assert size_scale(DISC).is_identity and size_scale(np.zeros((2, 2))).is_identity
    seen = []
    assert at_unit_size(lambda *a: seen.append(a) or "same", size_scale(DISC), (DISC, 1.0),
                        lambda r, s: "scaled") == "same" and seen[0][0] is DISC
    s = size_scale(3.0 * DISC.points)
    mesh, targets, path, none = s.lengths_down(DISC.with_points(3.0 * DISC.points)), \
        s.lengths_down(np.array([6.0])), s.lengths_down(lambda t: np.array([3.0 * t])), \
        s.lengths_down(None)
    assert np.allclose(mesh.points, DISC.points, rtol=1e-15) and mesh.triangles is not None
    assert targets == pytest.approx([2.0]) and path(1.5) == pytest.approx([1.5])
    assert none is None and s.factor == pytest.approx(3.0, rel=1e-15)


def test_scaling_back_past_the_float_range_names_the_scale():
    s = UnitScale(1000)
    with pytest.raises(InvalidMeshError, match=r"scale 2\^1000 \(about 1\.07e\+301\)"):
        s.up(np.array([[1e10, 0.0]]))
    assert np.isinf(s.up(np.array([np.inf]))).all()  # already infinite: not an overflow


def _scaled_files(tmp_path, factor):
    save(DISC.with_points(DISC.points * factor), tmp_path / "m.msh")
    target = DISC.points * np.array([1.2, 0.9])
    save(DISC.with_points(target * factor), tmp_path / "t.msh")
    V = np.zeros_like(DISC.points)
    V[DISC.boundary_vertices, 0] = -0.4 * DISC.points[DISC.boundary_vertices, 0]
    np.save(tmp_path / "v.npy", V * factor)
    return tmp_path


# the CLI at 2**j gives the unit result times 2**j, bit for bit; at 1e±300 it works (no
# overflow, no underflow) and equals the unit-size result scaled by the same power of two
@pytest.mark.parametrize("factor", [2.0 ** 40, 2.0 ** -40, 1e300, 1e-300])
def test_deform_morph_move_work_at_any_scale(tmp_path, capsys, factor):
    (tmp_path / "unit").mkdir()
    (tmp_path / "big").mkdir()
    unit = _scaled_files(tmp_path / "unit", 1.0)
    big = _scaled_files(tmp_path / "big", factor)
    s = unit_scale(load(big / "m.msh"))
    rel = factor / s.factor  # 1 when factor is a power of two
    runs = {
        "deform": lambda d, o: ["deform", str(d / "m.msh"), "--displacement",
                                str(d / "v.npy"), "-o", str(o)],
        "move": lambda d, o: ["move", str(d / "m.msh"), "--map", "1.1*x; 1.1*y", "-o",
                              str(o)],
        "morph": lambda d, o: ["morph", str(d / "m.msh"), str(d / "t.msh"), "--frames", "3",
                               "--no-plots", "--metric", "scalar", "-o", str(o)],
    }
    for name, argv in runs.items():
        out = f"{name}.msh" if name != "morph" else name
        assert main(argv(big, big / out)) == 0, capsys.readouterr().err
        got = load(big / out if name != "morph" else big / out / "frame_001.msh").points
        assert np.isfinite(got).all()
        if rel == 1.0:  # a power of two: bit for bit the unit result, scaled
            assert main(argv(unit, unit / out)) == 0
            ref = load(unit / out if name != "morph" else unit / out / "frame_001.msh").points
            assert np.array_equal(got, ref * factor), name
        # every triangle positive at the file's scale (checked at unit size: no overflow)
        m = DISC.with_points(s.down(got[:, :2]))
        assert (m.signed_areas() > 0).all(), name
    summary = json.loads((big / "morph" / "summary.json").read_text())
    both = size_scale(load(big / "m.msh"), load(big / "t.msh"))  # one scale for both ends
    assert summary["unit_scale"] == both.factor and summary["admissible"]
    assert "error" not in capsys.readouterr().err


# the command hands the file's mesh to mt.deform, which alone works at unit size: its
# frames are mt.deform's on the mesh read from the file, bit for bit, at any scale
@pytest.mark.parametrize("factor", [3.7, 1e300, 1e-300])
def test_cli_deform_is_the_library_call_on_the_files_mesh(tmp_path, factor):
    import meshopt_toolkit as mt

    d = _scaled_files(tmp_path, factor)
    argv = ["deform", str(d / "m.msh"), "--displacement", str(d / "v.npy"), "--time", "0.5"]
    assert main([*argv, "-o", str(d / "out.msh")]) == 0
    assert main([*argv, "--frames", "3", "--no-plots", "-o", str(d / "frames")]) == 0
    mesh = load(d / "m.msh").as_planar()
    V = np.load(d / "v.npy")
    assert np.array_equal(load(d / "out.msh").points[:, :2],
                          mt.deform(mesh, V, time=0.5).mesh.points)
    ref = mt.deform(mesh, V, time=0.5, frames=3)
    for k in range(3):
        got = load(d / "frames" / f"frame_00{k}.msh").points[:, :2]
        assert np.array_equal(got, ref.points[k]), k


@pytest.mark.parametrize("factor", [3.7, 1e300, 1e-300])
def test_cli_move_is_the_library_call_on_the_files_mesh(tmp_path, capsys, factor):
    import meshopt_toolkit as mt

    d = _scaled_files(tmp_path, factor)
    mesh = load(d / "m.msh").as_planar()
    handles = mesh.boundary_vertices
    targets = 1.1 * mesh.points[handles]
    (d / "h.csv").write_text("".join(f"{i},{x!r},{y!r}\n"
                                     for i, (x, y) in zip(handles, targets.tolist())))
    assert main(["move", str(d / "m.msh"), "--targets", str(d / "h.csv"), "--json",
                 "-o", str(d / "out.msh")]) == 0
    ref = mt.move(mesh, handles, targets)
    assert np.array_equal(load(d / "out.msh").points[:, :2], ref.mesh.points)
    summary = json.loads(capsys.readouterr().out)
    assert summary["handle_error"] == ref.handle_error  # in the file's units
    assert summary["similarity"]["shift"] == [ref.similarity.shift.real, ref.similarity.shift.imag]


# the command hands the files' meshes to mt.morph, which alone works at unit size: its
# frames and summary are mt.morph's on the meshes read from the files, bit for bit
@pytest.mark.parametrize("metric", ["distortion", "scalar"])
@pytest.mark.parametrize("factor", [3.7, 1e300, 1e-300])
def test_cli_morph_is_the_library_call_on_the_files_mesh(tmp_path, capsys, factor, metric):
    import meshopt_toolkit as mt

    d = _scaled_files(tmp_path, factor)
    assert main(["morph", str(d / "m.msh"), str(d / "t.msh"), "--frames", "3", "--no-plots",
                 "--metric", metric, "--json", "-o", str(d / "morph")]) == 0
    source, target = load(d / "m.msh").as_planar(), load(d / "t.msh").as_planar()
    ref = mt.morph(source, target, 3, metric=metric)
    for k in range(3):
        got = load(d / "morph" / f"frame_00{k}.msh").points[:, :2]
        assert np.array_equal(got, ref.frames[k].points), k
    summary = timeless(json.loads(capsys.readouterr().out))
    expected = timeless(json.loads(strict_json.dumps(ref.summary())))
    assert summary["admissible"] and {**summary, **expected} == summary



# the figures mark the inverted triangles by the signs of their areas, taken at unit size:
# at 1e300 the areas overflow, at 1e-300 they underflow
@pytest.mark.parametrize("factor", [1.0, 1e300, 1e-300])
def test_the_figures_mark_the_inverted_triangles_at_any_scale(factor):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from meshopt_toolkit.plotting import draw_mesh

    points = DISC.points.copy()
    inner = np.setdiff1d(np.arange(DISC.n_vertices), DISC.boundary_vertices)[0]
    points[inner] = 0.5 * (points[inner] + DISC.points[DISC.boundary_vertices[0]]) * 3.0
    inverted = DISC.with_points(points).signed_areas() <= 0
    assert 0 < inverted.sum() < DISC.n_triangles
    fig, ax = plt.subplots()
    draw_mesh(ax, points * factor, DISC.triangles)
    red = [c for c in ax.collections if isinstance(c, PolyCollection)]
    plt.close(fig)
    assert len(red) == 1 and len(red[0].get_paths()) == inverted.sum()


@pytest.mark.parametrize("factor", [1e300, 1e-300])
def test_filters_work_at_any_scale(tmp_path, factor):
    from meshopt_toolkit.pipeline import Document
    from meshopt_toolkit.pipeline.filter import registry

    mesh = DISC.with_points(DISC.points * factor)
    V = np.zeros_like(DISC.points)
    V[DISC.boundary_vertices, 0] = -0.4 * DISC.points[DISC.boundary_vertices, 0] * factor
    np.save(tmp_path / "v.npy", V)
    doc = Document([mesh])
    registry.get("apply_coord_prescribed_motion")()(doc, map="1.1*x; 1.1*y")
    moved = doc.mesh.as_planar()
    b = DISC.boundary_vertices
    assert np.array_equal(moved.points[b], mesh.points[b] * 1.1)
    doc = Document([mesh])
    summary = registry.get("apply_coord_quality_preserving_deformation")()(
        doc, displacement=str(tmp_path / "v.npy"))
    assert summary["min_aspect_ratio"] > 0.3 and np.isfinite(doc.mesh.points).all()
    doc = Document([mesh, mesh.with_points(mesh.points * 1.2)])
    summary = registry.get("generate_geodesic_morph")()(doc, frames=3)
    assert summary["admissible"] and len(doc) == 5
    assert np.allclose(doc.mesh.points[:, :2] / factor, DISC.points * 1.2, rtol=0, atol=1e-12)
