"""Handles pulled along a path that runs into the surface
(:mod:`meshopt_toolkit.motion.surface.handle_pull`): the augmented-Lagrangian penalty's
derivatives by Taylor tests, and a paddle swung about a hinge above a sheet whose border is
fixed: the paddle's prescribed arc passes below the sheet, its end is clear of it. The
handles cannot stay on their path; pulled, every frame is free of self-intersections by the
exact kernel and the handles are bitwise at their targets at the end."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from test_morph_self_intersection import _grid

from meshopt_toolkit.diagnostics import check_gradient, check_hvp
from meshopt_toolkit.errors import NotAdmissibleError
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.motion.engine.contact import SurfaceContact, contact_term
from meshopt_toolkit.motion.engine.similarity import HandlePath, handle_groups
from meshopt_toolkit.motion.surface.handle_pull import (HandlePenalty, HandlePull,
                                                        PulledContact,
                                                        placed_targets_problem)
from meshopt_toolkit.motion.surface.move import lumped_mass, move_surface

pytest.importorskip("ipctk")


def paddle_over_sheet(n: int = 6, height: float = 0.15, turn: float = -165.0,
                      shift: float = 0.0):
    """A sheet z = 0 over [0, 1]² (its border the first handles, its inside free) and a
    paddle (every vertex a handle) in the plane z = ``height``, x in [0.35, 0.65], at 0.05
    to 0.45 from the hinge line y = 0.5, z = ``height``, turned by ``turn`` degrees about
    it (and moved by ``shift`` along y) at the targets. Points, triangles, handles,
    targets."""
    uv, F = _grid(n)
    sheet = np.c_[uv, np.zeros(len(uv))]
    border = np.flatnonzero((uv == 0.0).any(axis=1) | (uv == 1.0).any(axis=1))
    pu, pF = _grid(2)
    rho = 0.05 + 0.4 * pu[:, 1]
    paddle = np.c_[0.35 + 0.3 * pu[:, 0], 0.5 + rho, np.full(len(pu), height)]
    a = np.radians(turn)
    moved = np.c_[paddle[:, 0], 0.5 + shift + rho * np.cos(a), height + rho * np.sin(a)]
    handles = np.r_[border, len(uv) + np.arange(len(pu))]
    return (np.vstack([sheet, paddle]), np.vstack([F, pF + len(uv)]), handles,
            np.vstack([sheet[border], moved]))


def paddle_onto_sphere(depth: float, subdivisions: int = 1):
    """trimesh's icosphere of radius 0.5 (its vertices z < −0.4 the first handles, the rest
    free) and a square paddle 0.3 wide 0.1 above its top (every vertex a handle), lowered
    at the targets to ``depth`` below its top: through the sphere's free top as it rests.
    Points, triangles, handles, targets, and the sphere's vertex count."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.5)
    V, F = np.asarray(s.vertices, float), np.asarray(s.faces, np.int64)
    bottom = np.flatnonzero(V[:, 2] < -0.4)
    pu, pF = _grid(2)
    paddle = np.c_[0.3 * (pu - 0.5), np.full(len(pu), V[:, 2].max() + 0.1)]
    lowered = paddle - [0.0, 0.0, 0.1 + depth]
    return (np.vstack([V, paddle]), np.vstack([F, pF + len(V)]),
            np.r_[bottom, len(V) + np.arange(len(pu))], np.vstack([V[bottom], lowered]), len(V))


def test_the_penalty_derivatives_pass_taylor_tests(rng):
    mass = rng.uniform(0.5, 2.0, 7)
    pen = HandlePenalty(np.array([1, 4, 6]), mass, kappa=3.0)
    pen.targets = rng.normal(size=(3, 3))
    pen.multipliers = rng.normal(size=(3, 3))
    x = rng.normal(size=21)
    assert check_gradient(pen.value, pen.gradient, x, rng=rng).order > 1.8
    r = check_hvp(pen.value, pen.gradient, lambda q, v: pen.hessian() @ v, x, rng=rng)
    assert r.order > 2.7


def test_the_pulled_contact_adds_the_penalty_to_the_barrier(rng):
    """Near contact (pairs within d̂, κ set): energy, gradient and Hessian of the sum."""
    V, F, h, _ = paddle_over_sheet(n=2, height=0.15)
    contact = SurfaceContact(V, F)
    Q = V.copy()
    Q[h[-9:], 2] = 0.6 * contact.dhat  # the paddle lowered to within d̂ of the sheet
    Q[h[-9:], 0] += 0.01
    free = np.ones(V.size, bool)
    term = contact_term(V, F, free, lumped_mass(V, F), contact=contact)
    pen = HandlePenalty(h, lumped_mass(V, F), kappa=2.0)
    pen.targets = V[h] + rng.normal(scale=0.1, size=(len(h), 3))
    pen.multipliers = rng.normal(size=(len(h), 3))
    both = PulledContact(term, pen)
    assert both.set_stiffness(Q, rng.normal(size=V.size)) and term.active(Q)

    def flat(f):
        return lambda x: f(x.reshape(-1, 3))

    x = Q.ravel()
    v = rng.normal(size=x.size)  # the pairs stay within d̂ along the sweep
    e = flat(both.energy)
    assert check_gradient(e, flat(both.gradient), x, v, eps0=1e-6).order > 1.8
    np.testing.assert_allclose((both.hessian(Q) - pen.hessian()).toarray(),
                               term.hessian(Q).toarray())


@pytest.mark.slow
def test_a_paddle_whose_arc_runs_through_the_sheet_is_pulled_round_it():
    V, F, h, tg = paddle_over_sheet()
    res = move_surface(V, F, h, tg)
    path = HandlePath(V[h], tg, handle_groups(h, F, len(V)), motion="screw")
    lag = [np.abs(X[h] - path(t)).max() for X, t in zip(res.frames, res.times)]
    assert max(lag) > 1e-3  # the handles left their path: pulled
    assert [len(self_intersections(X, F)) for X in res.frames] == [0] * len(res.frames)
    np.testing.assert_array_equal(res.points[h], tg)
    np.testing.assert_array_equal(res.frames[-1][h], tg)
    assert res.folds == 0 and res.handle_error == 0.0
    # the rigid paddle on its arc crosses the sheet at rest: the path itself runs into it
    Q = V.copy()
    Q[h] = path(0.5)
    assert len(self_intersections(Q, F)) > 0


@pytest.mark.slow
def test_targets_through_the_fixed_border_are_refused():
    """The paddle's end stands through the sheet's fixed border: no pull gets there."""
    V, F, h, tg = paddle_over_sheet(n=4, turn=-90.0, shift=-0.5)
    Q = V.copy()
    Q[h] = tg
    assert len(self_intersections(Q, F)) > 0
    with pytest.raises(NotAdmissibleError, match="their targets"):
        move_surface(V, F, h, tg, steps=1)


def _clean(frames, F) -> list[int]:
    """Each frame's count of intersecting triangle pairs by the exact kernel, and whether
    ipctk finds an intersection (both must be 0/False)."""
    import ipctk

    mesh = ipctk.CollisionMesh(frames[0], ipctk.edges(F.astype(np.int32)), F.astype(np.int32))
    return [len(self_intersections(X, F)) + int(ipctk.has_intersections(mesh, X))
            for X in frames]


@pytest.mark.parametrize("depth", [0.1, pytest.param(0.25, marks=pytest.mark.slow)])
def test_a_paddle_pressed_into_a_free_sphere_dents_it(depth):
    """The targets need the sphere's free top pushed in by ``depth``: the pull stops with
    the handles within the barrier's reach of their targets and pairs far closer, so their
    last step is placed only once it is clear (the pull goes on until then)."""
    V, F, h, tg, n = paddle_onto_sphere(depth)
    res = move_surface(V, F, h, tg)
    assert _clean(res.frames, F) == [0] * len(res.frames)
    np.testing.assert_array_equal(res.points[h], tg)
    assert res.folds == 0 and res.handle_error == 0.0 and res.worst_quality > 0.5
    # the sphere was pushed in below the paddle (which stands through it at rest)
    assert res.points[:n, 2].max() < V[:n, 2].max() - depth
    # the paddle's target centre lies inside the rest sphere's inscribed ball
    P = V[F[F.max(axis=1) < n]]
    normals = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    inscribed = (np.abs(np.einsum("ij,ij->i", normals, P[:, 0]))
                 / np.linalg.norm(normals, axis=1)).min()
    assert np.linalg.norm(tg[-5]) < inscribed


def _paddle_through_fixed_band():
    """The paddle hung down through the sheet at y = 0.1, the sheet's band y ≤ 0.25 fixed
    with its border: the paddle's triangles cross the band's (every vertex a handle)."""
    V, F, h, tg = paddle_over_sheet(n=4, turn=-90.0, shift=-0.4)
    band = np.setdiff1d(np.flatnonzero(V[:25, 1] <= 0.25), h)
    return V, F, np.r_[band, h], np.vstack([V[band], tg])


def test_targets_alone_through_a_fixed_band_are_refused_before_any_increment():
    V, F, h, tg = _paddle_through_fixed_band()
    why = placed_targets_problem(F, h, tg, len(V))
    assert why is not None and "triangle 4 (5, 10, 11)" in why
    # the named pair intersects (exact kernel) with every vertex placed by the targets
    Q = V.copy()
    Q[h] = tg
    assert [4, 32] in self_intersections(Q, F).tolist()
    with pytest.raises(NotAdmissibleError, match="targets alone"):
        move_surface(V, F, h, tg, steps=1, options={"max_iterations": 0})
    move_surface(V, F, h, tg, steps=1, contact=False, options={"max_iterations": 0})  # no contact: moved


def test_placed_elements_sharing_a_vertex_are_not_taken_for_a_crossing():
    """Targets where nothing crosses: the feasible paddles (swung over the sheet, pressed
    into the sphere) and the rest itself."""
    for V, F, h, tg in (paddle_over_sheet(), paddle_onto_sphere(0.25)[:4]):
        assert placed_targets_problem(F, h, tg, len(V)) is None
        assert placed_targets_problem(F, h, V[h], len(V)) is None


def bunny_ear_crop(reach: float = 0.02):
    """The bunny's ear turned 120° into its back (``bench_surface.bunny_ear_120``) cropped
    to the triangles whose centroid is within ``reach`` of the ear or of the tip's targets
    (the largest piece): the tip the first handles, the crop's border fixed."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import bench_surface as bench

    case = bench.bunny_ear_120()
    V, F = case.V, case.F
    tip = case.handles[case.groups == 1]
    moved = case.path(1.0)[:len(tip)]
    labels = bench.components(V, F, (V[:, 0] > -0.05) & (V[:, 1] > 0.14))
    ids, counts = np.unique(labels[labels >= 0], return_counts=True)
    near = cKDTree(np.vstack([V[labels == ids[np.argmax(counts)]], moved]))
    G = F[near.query(V[F].mean(axis=1))[0] < reach]
    A = sp.coo_matrix((np.ones(G.size), (G.ravel(), G[:, [1, 2, 0]].ravel())),
                      shape=(len(V), len(V)))
    piece = connected_components(A, directed=False)[1]
    G = G[piece[G[:, 0]] == np.bincount(piece[G.ravel()]).argmax()]
    used = np.unique(G)
    index = np.full(len(V), -1)
    index[used] = np.arange(len(used))
    edges, uses = np.unique(np.sort(G[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0,
                            return_counts=True)
    border = np.setdiff1d(edges[uses == 1], tip)
    assert np.isin(tip, used).all()
    return (V[used], index[G], index[np.r_[tip, border]], np.vstack([moved, V[border]]))


@pytest.mark.slow
def test_the_bunny_s_ear_cropped_is_pulled_into_its_back():
    """The ear's free middle rolls onto the back and the tip's path ends 8·10⁻³ inside it:
    every Gauss–Newton step of the pull is cut by CCD to a fraction (~10⁻³–10⁻¹) of itself,
    so a round ends short of a minimizer; the pull goes on at the same κ_a and λ (raising
    them there cuts the steps to 10⁻⁵ of themselves and the pull stalls 0.02 short)."""
    V, F, h, tg = bunny_ear_crop()
    res = move_surface(V, F, h, tg)
    assert _clean(res.frames, F) == [0] * len(res.frames)
    np.testing.assert_array_equal(res.points[h], tg)
    assert res.folds == 0 and res.handle_error == 0.0


def test_the_last_step_carries_the_pairs_along_with_the_handles(monkeypatch):
    """Pressed into the sphere, the paddle stops a few d̂ short with the barrier's pairs far
    closer: its straight last step, the sphere still, is not clear; carried by the barrier's
    Hessian the sphere keeps its distance to the paddle (to first order) and the step is."""
    seen, carried = [], HandlePull._carried

    def recorded(self, Q, H1):
        out = carried(self, Q, H1)
        term = self.problem.contact.contact
        straight = Q.copy()
        straight[self.handles] = H1
        seen.append((term.cap(Q, straight), term.clear(Q, out),
                     term.contact.minimum_distance(Q), term.contact.minimum_distance(out)))
        return out

    monkeypatch.setattr(HandlePull, "_carried", recorded)
    V, F, h, tg, _ = paddle_onto_sphere(0.1)
    res = move_surface(V, F, h, tg)
    np.testing.assert_array_equal(res.points[h], tg)
    assert seen and all(cap < 1.0 for cap, *_ in seen)
    cap, clear, before, after = seen[-1]
    assert clear and abs(after - before) < 1e-2 * before


@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(turn=st.floats(-180.0, 0.0), shift=st.floats(-0.6, 0.2), height=st.floats(-0.2, 0.3))
def test_placed_crossings_agree_with_ipctk(turn, shift, height):
    """Random placements of the paddle by the sheet's fixed band (y ≤ 0.25 and the
    border): refused exactly where ipctk finds an edge through a triangle among the
    elements whose every vertex is a handle, wherever ipctk's floating-point test can tell
    (a paddle lying within 10⁻⁹ of the sheet's plane, e.g. turned by 10⁻¹⁴⁰ just below
    it, is left out: ipctk finds it through the sheet, the exact kernel below)."""
    import ipctk

    V, F, h, _ = _paddle_through_fixed_band()
    a, paddle = np.radians(turn), V[25:]
    rho = paddle[:, 1] - 0.5
    tg = np.vstack([V[h[:-9]], np.c_[paddle[:, 0], 0.5 + shift + rho * np.cos(a),
                                     height + rho * np.sin(a)]])
    P = np.zeros_like(V)
    P[h] = tg
    placed = np.zeros(len(V), bool)
    placed[h] = True
    faces = F[placed[F].all(axis=1)].astype(np.int32)
    E = ipctk.edges(F.astype(np.int32))
    mesh = ipctk.CollisionMesh(P, E[placed[E].all(axis=1)], faces)
    assume(np.abs(tg[-9:, 2]).max() > 1e-9)
    assert (placed_targets_problem(F, h, tg, len(V)) is not None) == ipctk.has_intersections(
        mesh, P)
