"""The pipeline filters hand the mesh to the verb at its own scale: the filter's result is
the library call's on the same mesh, bit for bit, at any scale (the verbs alone work at
unit size, :mod:`meshopt_toolkit.scaling`)."""

from __future__ import annotations

import numpy as np
import pytest
from cli_helpers import timeless

import meshopt_toolkit as mt
from meshopt_toolkit import data_path
from meshopt_toolkit.io import load
from meshopt_toolkit.pipeline import Document, registry

DISC = load(data_path("disc_25.msh")).as_planar()
RIM = DISC.boundary_vertices
#: scales that are not powers of two, and past the range where areas fit in floating point
FACTORS = [3.7, 1e12, 1e-12, 1e300, 1e-300]


def _apply(name: str, meshes, **params) -> tuple[Document, dict]:
    doc = Document(meshes)
    return doc, registry.get(name)()(doc, **params)


def _points(mesh) -> np.ndarray:
    return np.asarray(mesh.points)[:, :2]


@pytest.mark.parametrize("factor", FACTORS)
def test_the_move_filter_is_mt_move(tmp_path, factor):
    mesh = DISC.with_points(DISC.points * factor)
    targets = mesh.points[RIM] * [1.2, 0.9]
    np.save(tmp_path / "h.npy", np.column_stack([RIM, targets]))
    doc, summary = _apply("apply_coord_prescribed_motion", [mesh],
                          targets=str(tmp_path / "h.npy"))
    ref = mt.move(mesh, RIM, targets)  # the filter's defaults are the verb's
    assert np.array_equal(_points(doc.mesh), ref.mesh.points)
    assert timeless(summary) == timeless(ref.summary())


@pytest.mark.parametrize("factor", FACTORS)
def test_the_deformation_filter_is_mt_deform(tmp_path, factor):
    mesh = DISC.with_points(DISC.points * factor)
    V = np.zeros_like(mesh.points)
    V[RIM] = mesh.points[RIM] * [0.3, -0.2]
    np.save(tmp_path / "v.npy", V)
    doc, summary = _apply("apply_coord_quality_preserving_deformation", [mesh],
                          displacement=str(tmp_path / "v.npy"), time=0.5)
    ref = mt.deform(mesh, V, time=0.5)
    assert np.array_equal(_points(doc.mesh), ref.mesh.points)
    assert summary["min_aspect_ratio"] == np.min(ref.aspect_ratio)
    assert summary["penalty_end"] == ref.geodesic.penalty[-1]


@pytest.mark.parametrize("metric", ["distortion", "scalar"])
@pytest.mark.parametrize("factor", FACTORS)
def test_the_morph_filter_is_mt_morph(factor, metric):
    from meshopt_toolkit.kernels.triangles import aspect_ratios

    source = DISC.with_points(DISC.points * factor)
    target = source.with_points(source.points * [1.3, 0.8])
    doc, summary = _apply("generate_geodesic_morph", [source, target], frames=3,
                          metric=metric)
    ref = mt.morph(source, target, 3, metric=metric)
    assert len(doc) == 5
    for k in range(3):
        entry = doc.entries[2 + k]
        assert np.array_equal(_points(entry.mesh), ref.frames[k].points), k
        # the face quality is 2r/R, free of scale
        unit = ref.frames[k].points / factor
        assert np.allclose(entry.face_attributes["quality"],
                           aspect_ratios(unit, DISC.triangles), rtol=1e-12, atol=0)
    assert summary["admissible"]
    assert timeless(summary) == timeless(ref.summary())
