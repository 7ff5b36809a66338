"""The one check of a number's range (``_options.require_positive``/``require_at_least``),
as the library's entry points raise it, and of an array's shape (``require_shape``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from meshopt_toolkit._options import require_at_least, require_positive
from meshopt_toolkit.errors import IntegrationError, OptionError
from meshopt_toolkit.riemannian.geodesic_options import GeodesicOptions


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_require_positive_accepts_exactly_the_positive_numbers(x):
    if x > 0:
        assert require_positive("weight", x) == x
    else:  # zero, negatives and NaN
        with pytest.raises(OptionError, match=r"^weight must be > 0, got "):
            require_positive("weight", x)


@given(st.integers(-5, 5), st.integers(-2, 3))
def test_require_at_least_is_the_inclusive_bound(n, low):
    if n >= low:
        assert require_at_least("frames", n, low) == n
    else:
        with pytest.raises(OptionError, match=rf"^frames must be at least {low}, got {n}$"):
            require_at_least("frames", n, low)


def test_none_is_an_option_left_to_its_default_and_the_error_type_is_the_callers():
    assert require_positive("h0", None) is None
    assert require_at_least("steps", None, 1) is None
    with pytest.raises(ValueError, match="chunk"):
        require_at_least("chunk", 0, 1, error=ValueError)
    with pytest.raises(ValueError):
        require_at_least("steps", math.nan, 1, error=ValueError)


@pytest.mark.parametrize("field", [{"rtol": 0.0}, {"h0": -1.0}, {"max_steps": 0},
                                   {"energy_tol": math.nan}])
def test_geodesic_options_refuse_out_of_range_numbers(field):
    with pytest.raises(IntegrationError, match=next(iter(field))):
        GeodesicOptions(**field)


@pytest.mark.parametrize("entry", ["morph", "move"])
def test_the_entry_points_refuse_one_frame_before_any_work(square, entry):
    import meshopt_toolkit as mt

    with pytest.raises(OptionError, match="frames must be at least 2, got 1"):
        if entry == "morph":
            mt.morph(square, square, frames=1)
        else:
            mt.move(square, [0], square.points[[0]], frames=1)


def test_require_shape_names_both_shapes_with_the_callers_error():
    from meshopt_toolkit._options import require_shape
    from meshopt_toolkit.errors import InvalidMeshError

    a = np.zeros((4, 2))
    assert require_shape("Q", a, (4, 2)) is a
    with pytest.raises(InvalidMeshError, match=r"^Q: shape \(4, 2\), expected \(4, 3\)$"):
        require_shape("Q", a, (4, 3), error=InvalidMeshError)
    with pytest.raises(ValueError, match=r"free mask: shape \(4, 2\), expected \(8,\)"):
        require_shape("free mask", a, [8])
