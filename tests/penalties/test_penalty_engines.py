"""The three evaluation engines of the per-triangle terms agree (penalties/engines.py).

The blocked engine (any block size), the complex-arithmetic engine (f1) and the Fourier
engine (f2) compute the same value, gradient and curvature on random meshes; the
blocked engine's Hessian-vector product is checked against the curvature.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh

from meshopt_toolkit.penalties import HeightPenalty, QualityPenalty
from meshopt_toolkit.penalties.engines import (
    BlockedEngine,
    ComplexEngine,
    Engine,
    FourierEngine,
)
from meshopt_toolkit.penalties.terms import _Accumulator, _Want

WANT = _Want(gradient=True, curvature=True)


def _evaluate(pen, engine, Q, V):
    acc = _Accumulator(pen.n_vertices, WANT)
    assert engine.run(Q, V, acc)
    if pen._area_term is not None:  # the blocked engine leaves it to the term itself
        pen._area_term.evaluate(Q, V, acc)
    return acc


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("kind", ["height", "quality"])
def test_engines_agree_on_random_meshes(kind, seed):
    rng = np.random.default_rng(seed)
    mesh = grid_mesh(int(rng.integers(2, 7)), jitter=0.3, seed=seed)
    pen = (HeightPenalty(mesh, alpha=(1.3, 0.0, 0.0)) if kind == "height"
           else QualityPenalty(mesh, beta=(1.3, 0.7, 0.0, 0.0)))
    Q = mesh.points + 0.01 * rng.standard_normal(mesh.points.shape)
    V = rng.standard_normal(Q.shape)
    small = pen._small_engine
    assert isinstance(small, FourierEngine if kind == "quality" else ComplexEngine)
    tt = pen._tri_t
    engines = [small] + [BlockedEngine(tt, pen.n_vertices, pen._triangle_term, b)
                         for b in (1, 3, mesh.n_triangles)]
    results = [_evaluate(pen, e, Q, V) for e in engines]
    ref = results[0]
    for acc in results[1:]:
        assert acc.values.keys() == ref.values.keys()
        for name in ref.values:
            assert acc.values[name] == pytest.approx(ref.values[name], rel=1e-12)
        np.testing.assert_allclose(acc.grad, ref.grad, rtol=1e-10, atol=1e-12)
        assert acc.curvature == pytest.approx(ref.curvature, rel=1e-10)
    # the hvp (blocked engine only) is consistent with the curvature: V·(∇²f V) = V·∇²f·V
    acc = _Accumulator(pen.n_vertices, _Want(hvp=True))
    assert engines[1].run(Q, V, acc)
    tri_curv = ref.curvature
    if pen._area_term is not None:
        area_only = _Accumulator(pen.n_vertices, _Want(curvature=True))
        pen._area_term.evaluate(Q, V, area_only)
        tri_curv -= area_only.curvature
    assert float(np.sum(acc.hvp * V)) == pytest.approx(tri_curv, rel=1e-9)


def test_engines_refuse_an_inverted_triangle():
    mesh = grid_mesh(3)
    pen = QualityPenalty(mesh)
    Q = mesh.points.copy()
    Q[[0, 1]] = Q[[1, 0]]
    for engine in (pen._small_engine, pen._blocked_engine):
        with np.errstate(all="ignore"):
            assert engine.run(Q, None, _Accumulator(pen.n_vertices, WANT)) is False


def test_every_engine_declares_the_interface():
    for cls in (BlockedEngine, ComplexEngine, FourierEngine):
        assert callable(cls.run) and isinstance(cls.supports_hvp, bool)
    assert BlockedEngine.supports_hvp and not ComplexEngine.supports_hvp
    assert Engine.__name__ == "Engine"
