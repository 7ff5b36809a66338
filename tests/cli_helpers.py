"""Shared by the tests of the command line and the filters: the one stderr line a refused
command prints, a summary without its wall times."""

from __future__ import annotations


def one_line(capsys) -> str:
    """The command's stderr: exactly one line, no traceback, no "internal error"."""
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "internal error" not in err[0] and "Traceback" not in err[0]
    return err[0]


def timeless(summary):
    """A summary (a JSON-able dict) without its wall times: ``seconds`` at any depth."""
    if isinstance(summary, dict):
        return {k: timeless(v) for k, v in summary.items() if k != "seconds"}
    if isinstance(summary, list):
        return [timeless(v) for v in summary]
    return summary
