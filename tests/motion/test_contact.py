"""The contact barrier and CCD of a surface (:mod:`meshopt_toolkit.motion.engine.contact`):
derivatives by Taylor tests, the projected Hessian's sign, the barrier's support, and the
CCD bound against the closed-form time of impact of a flap dropped onto a sheet."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_morph_self_intersection import flap_through_sheet

from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.motion.engine.contact import (DHAT_FRACTION, IPCTK_FLOOR, SEGMENT_FLOOR,
                                                   SurfaceContact)

ipctk = pytest.importorskip("ipctk")


def _near(drop: float) -> np.ndarray:
    return flap_through_sheet(drop)[1].points


@pytest.fixture(scope="module")
def contact() -> SurfaceContact:
    src, _ = flap_through_sheet()
    return SurfaceContact(src.points, src.triangles)


def test_dhat_is_the_fraction_of_the_mean_edge(contact):
    src, _ = flap_through_sheet()
    P, F = src.points, src.triangles
    e = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    mean = np.linalg.norm(P[e[:, 1]] - P[e[:, 0]], axis=1).mean()
    assert contact.usable
    assert contact.dhat == pytest.approx(DHAT_FRACTION * mean)
    assert contact.value(P) == 0.0  # nothing within d̂ at rest


def test_dhat_below_half_the_rests_closest_pair():
    src, _ = flap_through_sheet()
    close = _near(0.49)  # the flap's lower edge 0.01 above the sheet
    c = SurfaceContact(close, src.triangles)
    assert c.usable and c.dhat == pytest.approx(0.005, rel=1e-6)
    assert c.value(close) == 0.0


def test_a_rest_through_itself_has_no_barrier():
    src, _ = flap_through_sheet()
    assert not SurfaceContact(_near(1.0), src.triangles).usable


@pytest.mark.parametrize("drop", [0.48, 0.485, 0.495])
def test_barrier_derivatives_taylor(contact, drop):
    """The flap's lower edge within d̂ of the sheet; random directions of size ~1e-3 of
    the gap keep every pair apart."""
    Q = _near(drop)
    assert contact.value(Q) > 0.0
    shape = Q.shape
    f = lambda x: contact.value(x.reshape(shape))  # noqa: E731
    g = lambda x: contact.gradient(x.reshape(shape)).ravel()  # noqa: E731
    hvp = lambda x, v: contact.hessian(x.reshape(shape), project=False) @ v  # noqa: E731
    rng = np.random.default_rng(1)
    for _ in range(3):
        v = rng.standard_normal(Q.size)
        r = check_gradient(f, g, Q.ravel(), v, eps0=1e-4)
        assert r.passed, str(r)
        r = check_hvp(f, g, hvp, Q.ravel(), v, eps0=1e-4)
        assert r.passed, str(r)


def test_projected_hessian_is_positive_semidefinite(contact):
    Q = _near(0.49)
    H = contact.hessian(Q).toarray()
    assert np.abs(H - H.T).max() <= 1e-9 * np.abs(H).max()
    assert np.linalg.eigvalsh(H).min() >= -1e-9 * np.abs(H).max()
    assert np.abs(H).max() > 0.0


def test_barrier_is_infinite_where_a_pair_touches(contact):
    assert contact.value(_near(0.5)) == np.inf  # the flap's lower edge in the sheet


@pytest.mark.parametrize("drop", [2.0, 1.0, 0.6])
def test_ccd_stops_short_of_the_closed_form_impact(contact, drop):
    """The flap's lower edge (z = 0.5) falls by ``drop`` along a straight path: it meets
    the sheet at the fraction 0.5/drop; CCD stops before it, not far before."""
    src, _ = flap_through_sheet()
    end = _near(drop)
    s = contact.stepsize(src.points, end)
    impact = 0.5 / drop
    assert 0.5 * impact <= s < impact
    stop = src.points + s * (end - src.points)
    assert not len(self_intersections(stop, src.triangles))
    assert contact.stepsize(src.points, _near(0.4)) == 1.0  # a path that stays clear


def test_cap_skips_the_ccd_only_where_no_pair_can_close(contact, monkeypatch):
    """Far from contact a step shorter than d̂/2 needs no CCD; a longer one, or one from
    a configuration with a pair within d̂, is CCD's."""
    from meshopt_toolkit.motion.engine.contact import ContactTerm

    src, _ = flap_through_sheet()
    term = ContactTerm(contact, np.ones(src.points.size, bool), 1.0)
    calls = []
    monkeypatch.setattr(contact, "stepsize", lambda *a: calls.append(1) or 0.5)
    small = src.points + [0.0, 0.0, -0.45 * contact.dhat]
    assert term.cap(src.points, small) == 1.0 and not calls
    far = src.points + [0.0, 0.0, -0.55 * contact.dhat]
    assert term.cap(src.points, far) == 0.5 and len(calls) == 1
    near = _near(0.49)  # a pair within d̂
    assert term.cap(near, near + [0.0, 0.0, 1e-9]) == 0.5 and len(calls) == 2


@pytest.mark.parametrize("seed", range(3))
def test_short_steps_from_one_start_share_candidates_and_agree_with_the_broad_phase(
        contact, seed):
    """A line search's trials from one start: the second and later CCDs of steps moving no
    coordinate by more than REACH d̂ run on candidates kept around the start, with the
    fractions of each path's own broad phase, impacts included; longer steps use their
    own."""
    from meshopt_toolkit.motion.engine.contact import ContactTerm

    rng = np.random.default_rng(seed)
    Q0 = _near(0.505)  # the flap's lowest corner just above the sheet
    term = ContactTerm(contact, np.ones(Q0.size, bool), 1.0)
    dhat = contact.dhat
    down = np.zeros_like(Q0)  # the flap's points down, the sheet's still
    down[np.any(_near(0.6) != Q0, axis=1), 2] = -1.0
    trials = [Q0 + dhat * (s * down + rng.uniform(-1, 1, Q0.shape))
              for s in rng.uniform(0.0, 3.0, 8)]
    kept = []
    for Q1 in trials:
        assert term.cap(Q0, Q1) == contact.stepsize(Q0, Q1)
        kept.append(term._reach is not None)
    assert not kept[0] and all(kept[1:])
    assert min(term.cap(Q0, Q1) for Q1 in trials) < 1.0
    far = _near(2.0)  # further than REACH d̂
    assert term._candidates(Q0, far) is None
    assert term.cap(Q0, far) == contact.stepsize(Q0, far) < 1.0


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.3, 0.7), st.floats(0.0, 1.0), st.integers(0, 2**31 - 1))
def test_a_steps_trials_take_their_pairs_from_its_swept_candidates(contact, drop, alpha,
                                                                   seed):
    """After a step is capped, the pairs within d̂ at a point of its path (a line
    search's trial) come from the step's own swept candidates, and are exactly those of a
    broad phase of the whole surface; off the path the whole surface's broad phase runs."""
    from meshopt_toolkit.motion.engine.contact import ContactTerm

    import meshopt_toolkit.motion.engine.contact as module

    rng = np.random.default_rng(seed)
    Q0 = _near(0.45)
    Q1 = _near(drop) + contact.dhat * rng.uniform(-1, 1, Q0.shape)
    term = ContactTerm(contact, np.ones(Q0.size, bool), 1.0)
    pairs = len(contact.swept(Q0, Q1)) / len(contact.triangles)
    with pytest.MonkeyPatch.context() as patch:  # more pairs than kept: none kept
        patch.setattr(module, "SWEPT_PAIRS", 0.99 * pairs)
        term.cap(Q0, Q1)
        assert term._path is None
        patch.setattr(module, "SWEPT_PAIRS", pairs)
        term = ContactTerm(contact, np.ones(Q0.size, bool), 1.0)
        cap = term.cap(Q0, Q1)
    trial = Q0 + alpha * cap * (Q1 - Q0)
    assert term._on_path(trial) is not None
    assert (contact.signature(term.collisions(trial))
            == contact.signature(contact.collisions(trial)))
    assert contact.value(trial, term.collisions(trial)) == pytest.approx(
        contact.value(trial), rel=1e-12)
    off = trial + [0.0, 0.0, 10.0 * contact.dhat]
    assert term._on_path(off) is None


def test_triangles_of_one_fan_through_each_other_are_found():
    """Two triangles sharing the vertex 0: ``B`` turned into ``A``'s interior. No pair of
    IPC's comes near (the nearest is 0.5 apart); the exact fan test finds them."""
    rest = np.array([[0, 0, 0], [1, -1, 0], [1, 1, 0], [-0.5, 0, -1], [-0.5, 0, 1.0]])
    F = np.array([[0, 1, 2], [0, 3, 4]])
    c = SurfaceContact(rest, F)
    assert c.usable and not c.neighbours_meet(rest)
    through = rest.copy()
    through[3:, 0] = 0.5  # B = (0, (½, 0, ∓1)) cuts A along (0, 0, 0)–(½, 0, 0)
    assert len(self_intersections(through, F)) == 1
    assert len(c.collisions(through)) == 0 and c.neighbours_meet(through)


@pytest.mark.parametrize("gap", [1e-6, 1e-9, 5e-11])
def test_ccd_from_a_near_touch_stops_before_the_impact(contact, gap):
    """The flap's lower edge ``gap`` above the sheet (tight-inclusion CCD below 10⁻³ d̂),
    moved down by 0.01 and sideways: CCD stops before the closed-form impact."""
    Q0, Q1 = _near(0.5 - gap), _near(0.51).copy()
    Q1[16:, 0] += 0.003
    impact = gap / (0.01 + gap)
    assert 0.0 < contact.stepsize(Q0, Q1) < impact


def test_stiffness_doubles_as_the_closest_pair_nears(contact):
    from meshopt_toolkit.motion.engine.contact import ContactTerm

    term = ContactTerm(contact, np.ones(_near(0.4).size, bool), 1.0)
    g = np.ones(_near(0.4).size)
    assert not term.set_stiffness(_near(0.4), g) and term.kappa is None  # no pair near
    assert term.set_stiffness(_near(0.49), g)  # a pair within d̂: IPC's initial κ
    k0 = term.kappa
    assert k0 > 0 and term.max_kappa >= k0
    assert not term.set_stiffness(_near(0.495), g) and term.kappa == k0  # not 10⁻² d̂
    close = 0.5 - 1e-3 * contact.dhat
    assert term.set_stiffness(_near(close), g) and term.kappa == min(2 * k0, term.max_kappa)
    assert not term.set_stiffness(_near(close), g)  # no nearer than at the last update


def _point_over_slope(scale: float = 1.0):
    """A triangle on the slope z = y and a small one above it whose lowest point lies
    ``h`` over the slope's point (0.25, 0.5, 0.5) (distance ``h/√2``, the closest pair):
    the points at ``h`` (a callable) and the triangles, all times ``scale``."""
    slope = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    top = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.4], [0.0, 0.2, 0.4]])
    base = np.array([0.25, 0.5, 0.5])

    def at(h):
        return scale * np.vstack([slope, top + base + [0.0, 0.0, h]])

    return at, np.array([[0, 1, 2], [3, 4, 5]])


@settings(max_examples=30, deadline=None, derandomize=True, database=None)
@given(k=st.sampled_from([-40, -20, 0, 20, 40]),
       decimal=st.sampled_from([1e-12, 1e-6, 1.0, 1e6, 1e12]),
       far=st.floats(0.05, 0.5), ratio=st.floats(1.3, 4.0))
def test_a_segment_is_free_down_to_a_fifth_of_a_pairs_distance_or_the_floor(
        k, decimal, far, ratio):
    """The closed-form pair dropped straight down: from any distance a segment may close it
    down to the floor (``SEGMENT_FLOOR`` of the rest's diagonal), not below; from below
    the floor by fivefold at most (the CCD's tolerance, conservative, makes both up to
    twice as strict: the band between is not asserted); the same verdicts at every
    scale. At the user's scale, wherever the diagonal is at least 1, ipctk's own check
    passes every segment ours does."""
    scale = np.ldexp(decimal, k)
    at, F = _point_over_slope(scale)

    def free(d0, end):
        """The verdict on the drop from distance ``d0`` to ``end(floor)``."""
        Q0 = at(np.sqrt(2.0) * d0)
        contact = SurfaceContact(Q0, F)
        Q1 = at(np.sqrt(2.0) * end(SEGMENT_FLOOR * contact.bbox_diagonal / scale))
        verdict = contact.segment_free(Q0, Q1)
        if verdict and contact.bbox_diagonal >= IPCTK_FLOOR / SEGMENT_FLOOR:
            assert ipctk.is_step_collision_free(contact.mesh, np.asfortranarray(Q0),
                                                np.asfortranarray(Q1))
        return verdict

    assert free(far, lambda floor: 2.0 * ratio * floor)
    assert not free(far, lambda floor: floor / ratio)
    near = 0.5 * SEGMENT_FLOOR * SurfaceContact(at(1e-3), F).bbox_diagonal / scale
    assert free(near, lambda floor: near / 2.0)
    assert not free(near, lambda floor: near / (5.0 * ratio))
