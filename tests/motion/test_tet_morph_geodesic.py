"""The tet morph's geodesic is the Riemannian layer's one discrete geodesic
(riemannian.discrete_geodesic on TetGraphMetric.path_model): the same frames as
Levenberg–Marquardt on the tet path model itself, the boundary's self-intersection test
given as its faces, other free sets and anchors refused, and morph_tets through it."""

from __future__ import annotations

import numpy as np
import pytest
from test_tet_morph import twisted_cube

import meshopt_toolkit.motion.tets.morph as tm
from meshopt_toolkit.errors import OptionError
from meshopt_toolkit.kernels.intersections3d import self_intersections
from meshopt_toolkit.motion.engine.similarity_3d import tet_boundary_faces
from meshopt_toolkit.motion.tets.metric import TetGraphMetric
from meshopt_toolkit.motion.tets.path import TetPath
from meshopt_toolkit.riemannian.discrete_geodesic import discrete_geodesic
from meshopt_toolkit.riemannian.levenberg_marquardt import levenberg_marquardt
from meshopt_toolkit.riemannian.path_options import LevenbergMarquardtOptions


def _pair(K=3):
    src, tgt = twisted_cube(3, degrees=50.0)
    metric = TetGraphMetric(src.points, src.tets, 0.8)
    t = np.linspace(0.0, 1.0, K + 1)[:, None, None]
    return metric, src.points, tgt.points, (1.0 - t) * src.points + t * tgt.points


@pytest.mark.parametrize("newton", [False, True])
def test_discrete_geodesic_is_levenberg_marquardt_on_the_tet_path(newton):
    metric, P0, P1, init = _pair()
    faces = tet_boundary_faces(metric.tets)
    options = LevenbergMarquardtOptions(max_iterations=40, gtol=1e-10, newton=newton)
    geo = discrete_geodesic(metric, P0, P1, 3, path=init, boundary_edges=faces,
                            options=options)
    ref = levenberg_marquardt(TetPath(metric, init, lambda Q: bool(len(self_intersections(
        Q, faces)))), init, options)
    assert geo.converged and geo.nit == ref.nit and geo.status == ref.status
    np.testing.assert_array_equal(geo.points, ref.points)
    assert geo.energy == ref.energy and geo.points.shape == init.shape


def test_the_tet_path_model_refuses_a_free_set_or_anchor_it_cannot_take():
    metric, P0, P1, init = _pair()
    free = np.zeros(init.shape[:2], bool)
    free[1] = True
    with pytest.raises(OptionError, match="every vertex of the interior frames"):
        discrete_geodesic(metric, P0, P1, 3, path=init, free=free)
    with pytest.raises(OptionError, match="anchor"):
        discrete_geodesic(metric, P0, P1, 3, path=init, anchor=np.zeros((len(metric.tets), 7)))


def test_morph_tets_takes_the_one_discrete_geodesic(monkeypatch):
    src, tgt = twisted_cube(3, degrees=50.0)
    calls = []

    def spy(metric, *args, **kwargs):
        calls.append(type(metric))
        return discrete_geodesic(metric, *args, **kwargs)

    monkeypatch.setattr(tm, "discrete_geodesic", spy)
    res = tm.morph_tets(src, tgt, 4)
    assert calls == [TetGraphMetric] and res.converged
