"""The example scripts run (the thesis reproductions in their quick modes)."""

from __future__ import annotations

import runpy
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.slow
def test_morph_twist_example(tmp_path, capsys, monkeypatch):
    main = runpy.run_path(str(EXAMPLES / "morph_twist.py"))["main"]
    computed, morph = [], main.__globals__["morph"]

    def kept(*args, **kwargs):  # the same morph again: its first result
        if not computed:
            computed.append(morph(*args, **kwargs))
        return computed[0]

    monkeypatch.setitem(main.__globals__, "morph", kept)
    main(str(tmp_path))
    out = capsys.readouterr().out
    assert "all admissible: True" in out and "inverts" in out
    for name in ("frame_000.msh", "frame_008.msh", "strip.png", "quality.png"):
        assert (tmp_path / name).stat().st_size > 0
    main(str(tmp_path))  # runs again into the same directory (writes over its files)
    assert "all admissible: True" in capsys.readouterr().out


def _run(script: str, *args: str) -> str:
    done = subprocess.run([sys.executable, str(EXAMPLES / script), *args], capture_output=True,
                          text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.mark.slow
def test_geodesics_thesis_5_5_example(tmp_path):
    out = _run("geodesics_thesis_5_5.py", "--out", str(tmp_path))
    assert "squeeze:" in out and "disc alpha=1.00" in out
    for name in ("squeeze_complete_vs_euclidean.png", "disc_aspect_ratio.png", "summary.txt"):
        assert (tmp_path / name).stat().st_size > 0


@pytest.mark.slow
def test_shape_optimization_thesis_6_quick_example(tmp_path):
    _run("shape_optimization_thesis_6.py", str(tmp_path), "--quick")
    assert "6.4" in (tmp_path / "tables.md").read_text(encoding="utf-8")


def test_example_pipelines_run_and_agree(tmp_path):
    # the README's pipeline examples: the same steps as JSON and as MeshLab .mlx
    import meshio
    import numpy as np

    from meshopt_toolkit.cli import main

    data = Path(__file__).resolve().parents[1] / "meshopt_toolkit" / "data" / "disc_541.msh"
    written = []
    for name in ("remesh_refine.json", "remesh_refine.mlx"):
        out = tmp_path / name
        assert main(["run", str(EXAMPLES / "pipelines" / name), str(data), "-o", str(out)]) == 0
        written.append(meshio.read(out / "disc_541.msh"))
    a, b = written
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.cells_dict["triangle"], b.cells_dict["triangle"])
    assert len(a.cells_dict["triangle"]) > 4 * 500  # remeshed, then each triangle split in 4
