"""``meshopt morph``'s progress bar on a terminal: the stages of a surface morph's search
for a start are its status, and stderr keeps to the verbosity asked."""

from __future__ import annotations

import io
import logging
import sys

import pytest
from test_morph_self_intersection import _surface_file
from test_surface_morph_homotopy import hinge_band

from meshopt_toolkit.cli import main
from meshopt_toolkit.mesh import SurfaceMesh


class _Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.mark.parametrize("verbose, lines", [([], set()), (["-v"], {"info"})])
def test_the_bar_shows_the_start_search_and_stderr_its_verbosity(tmp_path, monkeypatch,
                                                                 verbose, lines):
    V0, V1, F = hinge_band(40.0)  # swung through flat: the interpolation is a clean start
    a = _surface_file(tmp_path / "a.vtu", SurfaceMesh(V0, F))
    b = _surface_file(tmp_path / "b.vtu", SurfaceMesh(V1, F))
    monkeypatch.setattr(sys, "stderr", _Terminal())
    monkeypatch.setattr(logging.root, "handlers", [])  # the command's own stderr handler
    assert main([*verbose, "morph", str(a), str(b), "-o", str(tmp_path / "out"),
                 "--frames", "5"]) == 0
    shown = sys.stderr.getvalue()
    assert "start path: the as-rigid-as-possible interpolation" in shown.split("\r")[1]
    levels = {line.split(": ")[1] for line in shown.replace("\r", "\n").splitlines()
              if line.startswith("meshopt morph: ")}
    assert levels == lines
