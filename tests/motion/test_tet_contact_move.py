"""Contact on the free parts of a tet mesh's boundary (motion/tets/contact.py and its use in
motion/tets/move.py): a slot closed by a motion past contact."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_tet_move import cube_tets

import meshopt_toolkit as mt
from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.errors import SelfIntersectionError
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.kernels.tetrahedra import signed_volumes
from meshopt_toolkit.mesh import TetMesh
from meshopt_toolkit.motion.engine.contact import ContactTerm, ContactWarning, NoContact
from meshopt_toolkit.motion.engine.similarity_3d import tet_boundary_faces
from meshopt_toolkit.motion.tets.contact import tet_contact_term
from meshopt_toolkit.motion.tets.move import move_tets

pytest.importorskip("ipctk")


def slotted_block(h: float = 1.0):
    """[0, 5] × [0, 1] × [0, 3] in cubes of side ``h`` (six Kuhn tets each) less the slot
    2 < x < 3, z > 1 and the corner x > 3, z > 2: a left arm 3 high and a right arm 2
    high, a slot of width 1 between them."""
    P, T = cube_tets(round(5 / h))
    P = 5.0 * P
    x, y, z = P[T].mean(axis=1).T  # each tet's centroid is inside its cube
    keep = (y < 1) & (z < 3) & ~((x > 2) & (x < 3) & (z > 1)) & ~((x > 3) & (z > 2))
    used, local = np.unique(T[keep], return_inverse=True)
    return P[used], local.reshape(-1, 4)


def closing(P, shift: float, drift=(0.0, 0.0)):
    """Handles: the left arm's outer face and top (moved by ``shift`` along x, ``drift``
    along y, z) and the right arm's outer face and top (fixed); the slot's faces free."""
    left = np.isclose(P[:, 0], 0) | (np.isclose(P[:, 2], 3) & (P[:, 0] < 2.01))
    right = np.isclose(P[:, 0], 5) | (np.isclose(P[:, 2], 2) & (P[:, 0] > 2.99))
    h = np.flatnonzero(left | right)
    tg = P[h].copy()
    tg[left[h]] += [shift, *drift]
    return h, tg


def _clean(P, T, res, h, tg):
    F = tet_boundary_faces(T)
    for Q in res.frames:
        assert len(self_intersections(Q, F)) == 0
        assert (signed_volumes(Q, T) > 0).all()
    assert np.array_equal(res.points[h], tg)


@pytest.fixture(scope="module")
def case():
    P, T = slotted_block()
    h, tg = closing(P, 1.5)
    return P, T, h, tg


def test_without_contact_the_closed_slot_intersects_itself(case):
    P, T, h, tg = case
    res = move_tets(P, T, h, tg, frames=3, contact=False)
    assert (signed_volumes(res.points, T) > 0).all()  # every tet positive, yet
    assert len(self_intersections(res.points, tet_boundary_faces(T))) > 0
    assert res.details["contact"] is False


@pytest.mark.slow
def test_with_contact_every_frame_is_clean(case):
    P, T, h, tg = case
    res = move_tets(P, T, h, tg, frames=3)
    _clean(P, T, res, h, tg)
    assert res.details["contact"] is True


def test_far_from_contact_the_motion_is_bitwise_unchanged():
    P, T = slotted_block()
    h, tg = closing(P, 0.3)
    on, off = (move_tets(P, T, h, tg, frames=3, contact=c) for c in (True, False))
    assert on.details["contact"] is False
    for a, b in zip(on.frames, off.frames):
        assert np.array_equal(a, b)


def test_boundary_barrier_derivatives_pass_taylor_tests():
    P, T = slotted_block()
    Q = P.copy()
    arm = (Q[:, 0] <= 2.01) & (Q[:, 2] > 1.01)
    rng = np.random.default_rng(1)
    Q[arm, 0] += 0.95  # the left arm's inner face 0.05 from the right arm's,
    Q[arm] += rng.uniform(-0.01, 0.01, (arm.sum(), 3))  # off the distances' kinks
    free = np.ones(P.size, bool)
    term = tet_contact_term(P, T, free, np.ones(len(P)))
    assert isinstance(term, ContactTerm) and 0.05 < term.contact.dhat
    assert term.active(Q)
    term.kappa = 1.0
    v = rng.normal(size=P.size) * 1e-2
    v.reshape(-1, 3)[~arm] = 0.0  # the barrier on the moving side (interior entries zero)

    def f(x):
        return term.energy(x.reshape(-1, 3))

    def g(x):
        return term.gradient(x.reshape(-1, 3))

    def hvp(x, d):  # the Hessian unprojected: the exact second derivative
        return term.contact.hessian(x.reshape(-1, 3), project=False) @ d

    interior = np.setdiff1d(np.arange(len(P)), np.unique(tet_boundary_faces(T)))
    assert not g(Q.ravel()).reshape(-1, 3)[interior].any()
    r = check_gradient(f, g, Q.ravel(), v, eps0=1e-3)
    assert r.passed, str(r)
    r = check_hvp(f, g, hvp, Q.ravel(), v, eps0=1e-3)
    assert r.passed, str(r)


def test_no_contact_where_the_boundary_is_prescribed_or_intersects_itself():
    P, T = slotted_block()
    free = np.ones(P.size, bool)
    assert isinstance(tet_contact_term(P, T, free, np.ones(len(P)), on=False), NoContact)
    boundary = np.unique(tet_boundary_faces(T))
    fixed = free.reshape(-1, 3).copy()
    fixed[boundary] = False
    assert isinstance(tet_contact_term(P, T, fixed.ravel(), np.ones(len(P))), NoContact)
    # two blocks overlapping: one warning line with the count, moved without contact
    Q = np.concatenate([P, P + [0.5, 0.0, 0.0]])
    TT = np.concatenate([T, T + len(P)])
    pairs = len(self_intersections(Q, tet_boundary_faces(TT)))
    assert pairs > 0
    with pytest.warns(ContactWarning, match=f"{pairs} pairs"):
        term = tet_contact_term(Q, TT, np.ones(Q.size, bool), np.ones(len(Q)))
    assert isinstance(term, NoContact)


@pytest.mark.slow
def test_mt_move_contact_on_and_off(case):
    P, T, h, tg = case
    mesh = TetMesh(P, T)
    with pytest.raises(SelfIntersectionError):  # the final guard of every frame
        mt.move(mesh, h, tg, contact=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ContactWarning)
        res = mt.move(mesh, h, tg, frames=3)
    F = tet_boundary_faces(T)
    assert all(len(self_intersections(m.points, F)) == 0 for m in res.frames)


@pytest.mark.slow
@settings(max_examples=3, deadline=None, derandomize=True)
@given(shift=st.floats(1.1, 1.6), dy=st.floats(-0.2, 0.2), dz=st.floats(-0.2, 0.2))
def test_random_closing_motions_stay_clean(shift, dy, dz):
    P, T = slotted_block()
    h, tg = closing(P, shift, (dy, dz))
    res = move_tets(P, T, h, tg, frames=4)
    _clean(P, T, res, h, tg)
