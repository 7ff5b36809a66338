"""The example scripts run (the quick ones; the thesis reproductions take minutes)."""

from __future__ import annotations

import runpy
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_morph_twist_example(tmp_path, capsys):
    module = runpy.run_path(str(EXAMPLES / "morph_twist.py"))
    module["main"](str(tmp_path))
    out = capsys.readouterr().out
    assert "all admissible: True" in out and "inverts" in out
    for name in ("frame_000.msh", "frame_008.msh", "strip.png", "quality.png"):
        assert (tmp_path / name).stat().st_size > 0
    module["main"](str(tmp_path))  # runs again into the same directory
