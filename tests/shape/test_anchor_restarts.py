"""``scale="auto"`` runs restart from their converged iterate with f2's anchor moved
there and j's weight doubled (:func:`meshopt_toolkit.optimize._follow_anchor`): the
history and the callback count on across restarts, the iteration limit holds, a restart
that cannot converge within it is dropped."""

from __future__ import annotations

import numpy as np
import pytest

from meshopt_toolkit.cli._common import load_workpiece
from meshopt_toolkit.optimize import ANCHOR_GROWTH, optimize
from meshopt_toolkit.shape.cases import ellipse_in_box
from meshopt_toolkit.shape.spec import spec_from_options

SPEC = dict(pde="elasticity", stress="outer=2,1,0", move="hole", keep="area")


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    path = ellipse_in_box(tmp_path_factory.mktemp("anchor") / "plate.msh", (0.5, 0.5), (8, 8),
                          2.0, refine_near=0.25)
    return load_workpiece(path, "optimize").mesh


def _single(mesh, monkeypatch, **kw):
    import sys

    monkeypatch.setattr(sys.modules["meshopt_toolkit.optimize"], "ANCHOR_RESTARTS", 0)
    return optimize(mesh, problem=spec_from_options(**SPEC), **kw)


def test_restarts_count_on_and_lower_j(plate, monkeypatch):
    seen = []
    result = optimize(plate, problem=spec_from_options(**SPEC),
                      callback=lambda r: seen.append(r.iteration))
    with monkeypatch.context() as m:
        single = _single(plate, m)
    assert single.status == "converged" and result.status == "converged"
    assert result.nit > single.nit and result.j < single.j
    # the callback counts on (it also sees the iterations of a dropped last restart)
    assert seen == list(range(1, len(seen) + 1)) and len(seen) >= result.nit
    assert [r.iteration for r in result.history] == list(range(result.nit + 1))
    # the first run's iterations come first, unchanged
    assert [r.j for r in result.history[:single.nit + 1]] == pytest.approx(
        [r.j for r in single.history])
    # the weight doubled at every restart kept
    k = np.log(result.objective_weight / single.objective_weight) / np.log(ANCHOR_GROWTH)
    assert k >= 1 and k == pytest.approx(round(k))


def test_a_restart_without_room_to_converge_is_dropped(plate, monkeypatch):
    with monkeypatch.context() as m:
        single = _single(plate, m)
    capped = optimize(plate, problem=spec_from_options(**SPEC),
                      max_iterations=single.nit + 2)
    assert capped.status == "converged" and capped.nit == single.nit
    assert np.array_equal(capped.x, single.x)
