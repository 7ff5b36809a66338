"""distortion_morph (motion/planar/morph.py): similar ends give similar frames, frames as
healthy as the ends, the proven bound on every frame.
"""

from __future__ import annotations

import numpy as np
from conftest import grid_mesh
from hypothesis import given
from hypothesis import strategies as st
from motion_helpers import FAST, _similar

from meshopt_toolkit.kernels.triangles import aspect_ratios, inverse_shape_quality
from meshopt_toolkit.motion.planar.morph import distortion_morph
from meshopt_toolkit.motion.planar.distortion import shape_quality_bound


@FAST
@given(angle=st.floats(-3.1, 3.1), scale=st.floats(0.2, 5), shift=st.tuples(
    st.floats(-5, 5), st.floats(-5, 5)))
def test_morph_between_similar_meshes_is_similar_in_every_frame(angle, scale, shift):
    mesh = grid_mesh(3, jitter=0.3)
    target = mesh.with_points(_similar(mesh.points, angle, scale, shift))
    result = distortion_morph(mesh, target, frames=4)
    ar0 = aspect_ratios(mesh.points, mesh.triangles)
    for Q in result.points:
        np.testing.assert_allclose(aspect_ratios(Q, mesh.triangles), ar0, rtol=1e-9)
    assert np.array_equal(result.points[-1], target.points)


def test_morph_frames_stay_as_healthy_as_the_ends(annulus):
    """Every frame's min aspect ratio ≥ 0.9 × the worse end's, and never
    below linear or as-rigid-as-possible interpolation where those stay valid."""
    from meshopt_toolkit.generate import log_twist

    target = log_twist(annulus, 90)
    result = distortion_morph(annulus, target, frames=9)
    worse_end = min(aspect_ratios(annulus.points, annulus.triangles).min(),
                    aspect_ratios(target.points, target.triangles).min())
    assert result.converged
    assert (result.stats.inverted == 0).all()
    assert result.stats.min_aspect_ratio.min() >= 0.9 * worse_end
    for other in (result.linear, result.rigid):
        if (other.inverted == 0).all():
            assert result.stats.min_aspect_ratio.min() >= other.min_aspect_ratio.min() * (1 - 1e-9)
    q0 = inverse_shape_quality(annulus.points, annulus.triangles)
    for Q, ell in zip(result.points, result.strain_bound):  # the proven bound, every frame
        assert (inverse_shape_quality(Q, annulus.triangles)
                <= shape_quality_bound(q0, np.full(len(q0), ell)) * (1 + 1e-9)).all()
