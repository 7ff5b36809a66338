"""The anchor bodies of ``bench_shape3d.py --anchors pironneau`` (benchmarks/_bodies3d.py):
the profile against quadrature and its Bézier form evaluated independently (volume of
the sphere, 60° tips, the asked length over width), and its gmsh mesh in the box
(every tet positive, the body a closed consistently oriented surface on the exact
profile, the tips mesh vertices, the volume below the exact one by a small margin)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from _bodies3d import conical_body_in_box, conical_profile  # noqa: E402

SPHERE = 4 * math.pi * 0.5 ** 3 / 3
aspects = st.floats(1.4, 2.8)
shoulders = st.one_of(st.just(0.0), st.floats(-0.3, 0.6))


def de_casteljau(poles: np.ndarray, t: float) -> np.ndarray:
    p = np.array(poles, float)
    while len(p) > 1:
        p = (1 - t) * p[:-1] + t * p[1:]
    return p[0]


@settings(max_examples=30, deadline=None)
@given(aspects, shoulders)
@example(2.5, 1.4e-45)  # a negligible c2: the roots of r' were wrong, not the bisection
def test_the_profile_has_the_spheres_volume_and_the_asked_aspect(aspect, shoulder):
    p = conical_profile(aspect, shoulder)
    h = p.half_length
    by_quadrature = quad(lambda x: math.pi * p.radius(x) ** 2, -h, h, epsabs=1e-14)[0]
    assert p.volume == pytest.approx(SPHERE, rel=1e-12)
    assert by_quadrature == pytest.approx(SPHERE, rel=1e-10)
    x = np.linspace(-h, h, 20001)
    assert 2 * h / (2 * p.radius(x).max()) == pytest.approx(aspect, rel=1e-7)
    assert (p.radius(x[1:-1]) > 0).all()


@settings(max_examples=30, deadline=None)
@given(aspects, shoulders, st.floats(0.0, 1.0))
def test_the_bezier_form_is_the_profile_with_60_degree_tips(aspect, shoulder, t):
    p = conical_profile(aspect, shoulder)
    poles = p.bezier_poles()
    x, r = de_casteljau(poles, t)
    assert x == pytest.approx(p.half_length * (2 * t - 1), abs=1e-14)
    assert r == pytest.approx(float(p.radius(x)), abs=1e-13)
    assert len(poles) == 2 * len(p.c) + 1
    for tip, inner in ((poles[0], poles[1]), (poles[-1], poles[-2])):
        # a Bézier curve leaves its end along its end leg
        leg = inner - tip
        assert math.degrees(math.atan2(abs(leg[1]), abs(leg[0]))) == pytest.approx(60, abs=1e-9)
    eps = 1e-7 * p.half_length  # the slope at the tips by the profile itself
    slope = (p.radius(-p.half_length + eps) - p.radius(-p.half_length)) / eps
    assert slope == pytest.approx(math.sqrt(3), rel=1e-5)


def test_the_meshed_body_is_closed_positive_and_on_the_profile(tmp_path):
    pytest.importorskip("gmsh")
    from meshopt_toolkit.io import load_cells
    from meshopt_toolkit.kernels.tetrahedra import signed_volumes

    p = conical_profile(2.0, 0.3)
    m = load_cells(conical_body_in_box(tmp_path / "c.msh", p, 2.0, 0.3)).to_tet_mesh("c")
    assert (signed_volumes(m.points, m.tets) > 0).all()
    tris = m.triangles[m.triangle_tags == m.tag_names["body"][0]]
    edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    _, count = np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)
    assert (count == 2).all()  # closed, manifold
    assert len(np.unique(edges, axis=0)) == len(edges)  # consistently oriented
    X = m.points[np.unique(tris)]
    assert np.abs(np.hypot(X[:, 1], X[:, 2]) - p.radius(X[:, 0])).max() < 1e-12
    for tip in (-p.half_length, p.half_length):
        assert np.abs(X - [tip, 0, 0]).max(axis=1).min() < 1e-12
    # this member is convex: the meshed body, inscribed in it, is a little smaller
    body = 8 * 6 * 6 - signed_volumes(m.points, m.tets).sum()
    enclosed = -np.einsum("ij,ij->i", m.points[tris[:, 0]],
                          np.cross(m.points[tris[:, 1]], m.points[tris[:, 2]])).sum() / 6
    assert body == pytest.approx(abs(enclosed), rel=1e-9)
    assert 0 < 1 - body / SPHERE < 0.2
