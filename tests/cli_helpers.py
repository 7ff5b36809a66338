"""Shared by the tests of the command line (tests/cli/): the one stderr line a refused
command prints."""

from __future__ import annotations


def one_line(capsys) -> str:
    """The command's stderr: exactly one line, no traceback, no "internal error"."""
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "internal error" not in err[0] and "Traceback" not in err[0]
    return err[0]
