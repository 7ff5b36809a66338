"""The table logic of ``benchmarks/compare_revisions.py``: the equal-or-better rule on the
worst quality, the time limit, the summary of repeated runs and the report's list of the
rows where the new revision is worse."""

from __future__ import annotations

import math
import shlex
import sys
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import compare_revisions as cr  # noqa: E402

finite = st.floats(-1e3, 1e3, allow_nan=False)


@given(finite)
def test_a_quality_is_equal_or_better_than_itself(q):
    assert cr.equal_or_better(q, q)


@given(finite, finite)
def test_a_difference_beyond_the_tolerance_has_one_winner(old, new):
    # the closed form: equal within 1e-9 of the larger magnitude, else the larger wins
    if abs(new - old) > 1e-9 * max(abs(old), abs(new)):
        assert cr.equal_or_better(old, new) == (new > old)
        assert cr.equal_or_better(new, old) == (old > new)
    else:
        assert cr.equal_or_better(old, new) and cr.equal_or_better(new, old)


@given(finite, finite, st.floats(0, 1e3))
def test_raising_the_new_quality_never_turns_better_into_worse(old, new, up):
    if cr.equal_or_better(old, new):
        assert cr.equal_or_better(old, new + up)


def test_the_tolerance_is_relative_at_1e_9():
    assert cr.equal_or_better(0.5, 0.5 * (1 - 0.5e-9))
    assert not cr.equal_or_better(0.5, 0.5 * (1 - 2e-9))
    assert not cr.equal_or_better(-0.2, -0.2 * (1 + 2e-9))  # a more inverted worst tet
    assert not cr.equal_or_better(0.0, -1e-300)


def test_a_failed_run_is_worse_than_any_result_and_equal_to_a_failure():
    assert not cr.equal_or_better(0.1, None)
    assert cr.equal_or_better(None, -5.0)
    assert cr.equal_or_better(None, None)
    assert cr.equal_or_better(math.nan, math.nan) and not cr.equal_or_better(0.3, math.nan)


def test_the_time_limit_is_1_2_times_the_old():
    assert cr.within(10.0, 12.0) and not cr.within(10.0, 12.01)
    assert cr.within(10.0, 1.0)
    assert not cr.within(None, 1.0) and not cr.within(1.0, None)


def test_repeats_keep_the_fastest_time_and_the_worst_quality():
    runs = [{"worst": 0.5, "seconds": 3.0, "cpu": 2.5, "measures": {"folds": 0}},
            {"worst": 0.4, "seconds": 2.0, "cpu": 2.9, "measures": {"folds": 1}}]
    s = cr.summarize(runs)
    assert (s["worst"], s["seconds"], s["cpu"], s["varies"]) == (0.4, 2.0, 2.5, True)
    assert s["measures"] == {"folds": 1}
    failed = cr.summarize([{"error": "exit 1: boom"}])
    assert failed["worst"] is None and failed["error"] == "exit 1: boom"


def _side(worst, seconds, **measures):
    return {"worst": worst, "seconds": seconds, "cpu": seconds, "measures": measures,
            "varies": False}


def test_the_report_lists_exactly_the_rows_where_the_new_is_worse():
    cases = [cr.Case("docs/a.md", "t", name, "run_move") for name in "abcd"]
    rows = [cr.row(cases[0], _side(0.5, 1.0, folds=0), _side(0.5, 1.1, folds=0)),
            cr.row(cases[1], _side(0.5, 1.0), _side(0.49, 1.0)),
            cr.row(cases[2], _side(0.5, 1.0), _side(0.6, 1.5)),
            cr.row(cases[3], _side(0.5, 1.0, folds=0), _side(0.5, 1.0, folds=2))]
    assert [(r["good"], r["fast"]) for r in rows] == [(True, True), (False, True),
                                                      (True, False), (True, True)]
    assert rows[0]["other"] == "same" and rows[3]["other"] == "folds 0 → 2"
    text = cr.report(rows, cases, "# header", selected_all=True)
    worse = text.split("## Rows where the new revision is worse")[1]
    assert "t: b: worst quality lower" in worse and "t: c: time ×1.5" in worse
    assert "t: a:" not in worse and "t: d:" not in worse
    assert text.count("| t | ") == 4


def test_options_a_revision_lacks_are_left_out():
    def move(points, *, steps=4):
        return steps

    assert cr._accepted(move, steps=2, contact=False) == {"steps": 2}


def test_every_case_has_a_runner_and_the_left_out_ones_say_why():
    cases = cr.all_cases()
    assert all(c.runner in cr.RUNNERS for c in cases)
    assert all(c.why_not for c in cases if not c.default)
    assert {c.page for c in cases if c.default} == {
        "docs/benchmarks.md", "docs/benchmarks-3d.md", "docs/benchmarks-surface.md"}


def test_the_printed_command_runs_the_same_cases_again():
    argv = ["6b9c044", "--all", "--cases", "0.25) box, ellipsoidal", "hole shifted 0.4",
            "--markdown", "/tmp/out.md", "--repeats", "4"]
    words = shlex.split(cr.printed_command(argv))
    assert words[:2] == ["python", "benchmarks/compare_revisions.py"]
    assert words[2:] == [*argv[:6], "FILE", *argv[7:]]


def test_page_sizes_lists_the_3d_cases_at_their_pages_sizes(capsys):
    cases = cr.all_cases()
    full = [c for c in cases if c.full]
    assert cr.main(["--page-sizes", "--list"]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"{c.page} | {c.table} | {c.name}" for c in full]
    # every 3D case the default set runs at a reduced size is there at the page's size
    reduced = [c for c in cases if "size 0.25" in c.table or "size 0.15" in c.table]
    assert reduced and all(any((f.runner, f.name) == (c.runner, c.name) for f in full)
                           for c in reduced)
    assert not any(c.default for c in full) and not any(c.full for c in reduced)
    assert {c.kwargs.get("size") for c in full if c.runner == "run_tet_sweep"} == {0.11, 0.06}
    assert {c.kwargs["size"] for c in full if c.runner == "run_tet_move"} == {0.12, 0.0595}
