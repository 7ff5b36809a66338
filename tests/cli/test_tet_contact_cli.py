"""``meshopt move --contact on|off`` on a tet mesh whose motion closes a slot past contact."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from cli_helpers import one_line

from test_tet_contact_move import closing, slotted_block  # (tests/motion: on the path)

from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load_cells
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.motion.engine.similarity_3d import tet_boundary_faces

pytest.importorskip("ipctk")


@pytest.mark.slow
def test_cli_contact_on_and_off(tmp_path, capsys):
    P, T = slotted_block()
    src = tmp_path / "slot.vtu"
    meshio.write(src, meshio.Mesh(P, [("tetra", T)]))
    h, tg = closing(P, 1.5)
    table = tmp_path / "handles.csv"
    table.write_text("index,x,y,z\n" + "".join(
        f"{i},{x!r},{y!r},{z!r}\n" for i, (x, y, z) in zip(h, tg.tolist())))
    base = ["move", str(src), "--targets", str(table), "--free-boundary"]
    off = tmp_path / "off.vtu"
    assert main([*base, "-o", str(off), "--contact", "off"]) == 1  # the final guard
    assert "intersect" in one_line(capsys) and not off.exists()
    on = tmp_path / "on.vtu"
    assert main([*base, "-o", str(on)]) == 0
    Q = load_cells(on).points
    assert len(self_intersections(Q, tet_boundary_faces(T))) == 0
    np.testing.assert_array_equal(Q[h], tg)
