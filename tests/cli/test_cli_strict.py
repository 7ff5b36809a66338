"""What the command line promises besides its results: strict JSON, one-line errors for
failures of the machine and the file system, long user text cut in messages, and every
output checked before any work."""

from __future__ import annotations

import errno
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import one_line
from hypothesis import given
from hypothesis import strategies as st

from meshopt_toolkit import data_path, strict_json
from meshopt_toolkit.cli import main

DISC = data_path("disc_25.msh")


def _refuse(constant: str):
    raise ValueError(f"not JSON: {constant}")


def strict_loads(text: str):
    """``json.loads`` that refuses ``NaN``, ``Infinity`` and ``-Infinity``."""
    return json.loads(text, parse_constant=_refuse)


@pytest.fixture
def work(tmp_path):
    shutil.copy(DISC, tmp_path / "disc.msh")
    return tmp_path


# ------------------------------------------------------------------------- strict JSON
_leaf = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
                  st.booleans(), st.none(), st.text(max_size=5),
                  st.floats().map(np.float64), st.integers(-99, 99).map(np.int64))
_tree = st.recursive(_leaf, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.tuples(inner, inner),
    st.dictionaries(st.text(max_size=4), inner, max_size=4)), max_leaves=20)


def _expected(obj):
    """The independent reading of the rule: non-finite → None, containers recursively."""
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, (list, tuple)):
        return [_expected(v) for v in obj]
    if isinstance(obj, dict):
        return {k: _expected(v) for k, v in obj.items()}
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


@given(_tree)
def test_strict_json_is_json_with_null_for_non_finite_numbers(obj):
    text = strict_json.dumps(obj)
    assert strict_loads(text) == _expected(obj)


def test_strict_json_converts_numpy_arrays_and_refuses_what_it_cannot_write():
    out = strict_loads(strict_json.dumps({"a": np.array([1.0, np.nan, -np.inf]),
                                          "p": Path("x") / "y"}))
    assert out == {"a": [1.0, None, None], "p": str(Path("x") / "y")}
    with pytest.raises(TypeError):
        strict_json.dumps({"s": {1, 2}})


def test_morph_json_and_summary_are_strict_where_linear_interpolation_degenerates(work, capsys):
    """A half turn: linear interpolation collapses the mesh at t = 1/2, its quality is NaN."""
    from meshopt_toolkit.io import load, save

    mesh = load(work / "disc.msh").as_planar()
    save(mesh.with_points(-mesh.points), work / "turned.msh")
    assert main(["morph", str(work / "disc.msh"), str(work / "turned.msh"), "-o",
                 str(work / "mo"), "--frames", "3", "--no-plots", "--json"]) == 0
    printed = strict_loads(capsys.readouterr().out)
    written = strict_loads((work / "mo" / "summary.json").read_text())
    for summary in (printed, written):
        assert summary["linear"]["mean_quality"][1] is None  # NaN in the library's summary
        assert summary["linear"]["inverted"][1] > 0


def test_optimize_history_and_summary_are_strict(work, capsys):
    """The first history row has no gradient norm yet (NaN in the library's record)."""
    out = work / "opt"
    main(["optimize", str(work / "disc.msh"), "-o", str(out), "--max-iter", "2",
          "--no-plots", "--json"])
    strict_loads(capsys.readouterr().out)
    strict_loads((out / "summary.json").read_text())
    history = strict_loads((out / "history.json").read_text())
    assert history[0]["gradient_norm"] is None


def test_move_and_run_json_are_strict(work, capsys, monkeypatch):
    import meshopt_toolkit.motion.move as mv

    real = mv.move

    def with_nan(*args, **kwargs):
        result = real(*args, **kwargs)
        result.details["probe"] = [math.nan, math.inf]
        return result

    monkeypatch.setattr(mv, "move", with_nan)
    assert main(["move", str(work / "disc.msh"), "-o", str(work / "m.msh"), "--map", "x; y",
                 "--json"]) == 0
    assert strict_loads(capsys.readouterr().out)["probe"] == [None, None]
    pipe = work / "p.json"
    pipe.write_text(json.dumps({"filters": [
        {"name": "apply_coord_prescribed_motion", "params": {"map": "x; y"}}]}))
    assert main(["run", str(pipe), str(work / "disc.msh"), "-o", str(work / "r"), "--json"]) == 0
    for line in capsys.readouterr().out.splitlines():
        assert strict_loads(line)["results"][0]["probe"] == [None, None]


# ---------------------------------------------------------------- one-line failures
def _raising(exc: BaseException):
    def boom(*args, **kwargs):
        raise exc

    return boom


@pytest.mark.parametrize("exc,shown", [
    (MemoryError(), "out of memory while running 'meshopt move' on {disc}"),
    (FloatingPointError("overflow encountered in multiply"),
     "{disc}: floating-point error in the computation (overflow encountered in multiply)"),
    (FileExistsError(errno.EEXIST, "File exists", "{out}"),
     "{out}: exists (use --force to overwrite)"),
    (OSError(errno.ENOSPC, "No space left on device", "{out}"),
     "{out}: no space left on device"),
    (OSError(errno.ENOSPC, "No space left on device"), "{out}: no space left on device"),
    (ValueError("embedded null byte"), "{disc}: a path or expression contains a null byte"),
])
def test_machine_and_file_system_failures_are_one_line(work, capsys, monkeypatch, exc, shown):
    import meshopt_toolkit.motion.move as mv

    disc, out = work / "disc.msh", work / "out.msh"
    if isinstance(exc, OSError) and exc.filename:
        exc.filename = str(out)
    monkeypatch.setattr(mv, "move", _raising(exc))
    argv = ["move", str(disc), "-o", str(out), "--map", "x; y"]
    assert main(argv) == 1
    assert one_line(capsys).startswith("meshopt move: error: " + shown.format(disc=disc, out=out))
    with pytest.raises(type(exc)):
        main(["--debug", *argv])


def test_a_null_byte_in_an_argument_is_one_line(work, capsys):
    for argv in (["move", str(work / "disc.msh"), "-o", "o\0.msh", "--map", "x; y"],
                 ["move", str(work / "disc.msh"), "-o", "o.msh", "--targets", "t\0.csv"],
                 ["convert", str(work / "disc.msh"), "-o", "o\0.vtu"]):
        assert main(argv) == 1
        assert "contains a null byte" in one_line(capsys)
    assert list(work.iterdir()) == [work / "disc.msh"]


@pytest.mark.parametrize("option", ["--map", "--where"])
def test_long_expressions_are_cut_in_messages(work, capsys, option):
    long = "x+" * 50_000 + "x"
    extra = ["--map", f"{long}; y"] if option == "--map" else \
        ["--map", "x; y", "--where", f"{long} < 1"]
    assert main(["move", str(work / "disc.msh"), "-o", str(work / "o.msh"), *extra]) == 1
    line = one_line(capsys)
    assert len(line) < 400, len(line)
    assert f"({len(extra[-1])} chars)" in line and option in line


def test_evaluation_messages_cut_the_expression():
    from meshopt_toolkit.errors import ExpressionError
    from meshopt_toolkit.expressions import SHOWN_CHARS, parse_expression, quoted

    assert quoted("x + y") == "'x + y'"
    text = "log(x) + 0." + "0" * 200 + "1"  # long but shallow
    assert quoted(text) == f"{text[:SHOWN_CHARS]!r}… ({len(text)} chars)"
    with pytest.raises(ExpressionError) as info:
        parse_expression(text)(np.array([[-1.0, 0.0]]))
    assert quoted(text) in str(info.value) and text not in str(info.value)


# ---------------------------------------------------- outputs checked before any work
@pytest.fixture
def no_read(monkeypatch):
    """Fail the test if an input mesh is read (the outputs must be refused first)."""
    import meshopt_toolkit.io as mio

    def boom(*args, **kwargs):
        raise AssertionError("an input was read before the outputs were checked")

    monkeypatch.setattr(mio, "load", boom)
    monkeypatch.setattr(mio, "load_cells", boom)


def test_unknown_output_formats_are_refused_before_reading(work, capsys, no_read):
    disc = str(work / "disc.msh")
    np.save(work / "v.npy", np.zeros((25, 2)))
    cases = [
        (["move", disc, "--map", "x; y", "-o", str(work / "o.xyz")], "o.xyz: unknown mesh format"),
        (["move", disc, "--map", "x; y", "--frames", "3", "--format", "xyz", "-o",
          str(work / "f")], "--format xyz: unknown mesh format '.xyz'"),
        (["deform", disc, "--displacement", str(work / "v.npy"), "-o", str(work / "o.xyz")],
         "o.xyz: unknown mesh format"),
        (["deform", disc, "--displacement", str(work / "v.npy"), "--frames", "3", "--format",
          "xyz", "-o", str(work / "f")], "--format xyz: unknown mesh format"),
        (["morph", disc, disc, "--format", "xyz", "-o", str(work / "mo")],
         "--format xyz: unknown mesh format"),
        (["optimize", disc, "-o", str(work / "res.msh")], "a directory is written here"),
        (["run", str(work / "p.json"), disc, "-o", str(work / "r"), "--to", "xyz"],
         "--to xyz: unknown mesh format"),
    ]
    (work / "p.json").write_text(json.dumps({"filters": [
        {"name": "compute_scalar_by_shape_quality_per_face", "params": {}}]}))
    for argv, shown in cases:
        assert main(argv) == 1, argv
        line = one_line(capsys)
        assert shown in line and "known: " in line and ".msh," in line or "directory" in line, line
    assert sorted(p.name for p in work.iterdir()) == ["disc.msh", "p.json", "v.npy"]


def test_existing_outputs_are_refused_before_reading(work, capsys, no_read):
    disc = str(work / "disc.msh")
    (work / "mo").mkdir()
    (work / "mo" / "frame_001.msh").write_text("mine")
    (work / "opt").mkdir()
    (work / "opt" / "summary.json").write_text("mine")
    (work / "mv").mkdir()
    (work / "mv" / "notes.txt").write_text("mine")
    (work / "taken.vtu").write_text("mine")
    for argv, shown in (
            (["morph", disc, disc, "--frames", "3", "-o", str(work / "mo")],
             f"{work / 'mo' / 'frame_001.msh'}: exists"),
            (["optimize", disc, "-o", str(work / "opt")],
             f"{work / 'opt' / 'summary.json'}: exists"),
            (["move", disc, "--map", "x; y", "--frames", "3", "-o", str(work / "mv")],
             f"{work / 'mv'}: directory is not empty"),
            (["convert", disc, "-o", str(work / "taken.vtu")],
             f"{work / 'taken.vtu'}: already exists"),
            (["convert", disc, "-o", str(work / "missing" / "o.vtu")], "does not exist")):
        assert main(argv) == 1, argv
        assert shown in one_line(capsys)
    assert (work / "taken.vtu").read_text() == "mine"
