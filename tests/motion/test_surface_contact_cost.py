"""What a move's CCD costs (:mod:`meshopt_toolkit.motion.engine.contact`): from a start
with a pair nearer than ``10⁻³ d̂`` the CCD is tight inclusion's, its iterations per pair
bounded by ``TIGHT_ITERATIONS``; its fraction stays conservative: below the closed-form
impact, its stop clean. Elsewhere the CCD is additive."""

from __future__ import annotations

import pytest
from test_morph_self_intersection import flap_through_sheet

from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.motion.engine import contact as module
from meshopt_toolkit.motion.engine.contact import SurfaceContact

ipctk = pytest.importorskip("ipctk")


@pytest.fixture(scope="module")
def contact() -> SurfaceContact:
    src, _ = flap_through_sheet()
    return SurfaceContact(src.points, src.triangles)


def _tight_inclusions(monkeypatch) -> list:
    """The arguments of each tight-inclusion CCD made."""
    made, tight = [], ipctk.TightInclusionCCD
    monkeypatch.setattr(ipctk, "TightInclusionCCD", lambda *a: made.append(a) or tight(*a))
    return made


@pytest.mark.parametrize("gap", [1e-6, 1e-9])
def test_bounded_tight_inclusion_stops_short_of_the_impact(contact, gap, monkeypatch):
    """The flap's lower edge ``gap`` above the sheet (below 10⁻³ d̂), moved down by 0.01
    and sideways: tight inclusion with ``TIGHT_ITERATIONS`` per pair gives a positive
    fraction below the impact at gap/(0.01 + gap), its stop clean and the gap not closed."""
    src, _ = flap_through_sheet()
    Q0, Q1 = flap_through_sheet(0.5 - gap)[1].points, flap_through_sheet(0.51)[1].points.copy()
    Q1[16:, 0] += 0.003
    assert gap < 1e-3 * contact.dhat
    made = _tight_inclusions(monkeypatch)
    s = contact.stepsize(Q0, Q1)
    assert made == [(1e-6, module.TIGHT_ITERATIONS)]
    assert 0.0 < s < gap / (0.01 + gap)
    stop = Q0 + s * (Q1 - Q0)
    assert not len(self_intersections(stop, src.triangles))
    assert contact.minimum_distance(stop) > 0.0


def test_a_start_far_from_contact_gets_additive_ccd(contact, monkeypatch):
    src, _ = flap_through_sheet()
    made = _tight_inclusions(monkeypatch)
    assert 0.0 < contact.stepsize(src.points, flap_through_sheet(0.6)[1].points) < 0.5 / 0.6
    assert not made
