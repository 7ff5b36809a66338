"""ProgressBar: the count a fraction of the work gives, and what it draws."""

import io

from hypothesis import given, strategies as st

from meshopt_toolkit.progress import ProgressBar


@given(total=st.integers(1, 10**6),
       fractions=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20))
def test_to_fraction_counts_that_part_of_the_total(total, fractions):
    bar = ProgressBar(total, enabled=False)
    for s in sorted(fractions):
        bar.to_fraction(s)
        assert bar.count == int(total * s)


def test_to_fraction_draws_the_count_and_ends_at_the_total():
    stream = io.StringIO()
    with ProgressBar(1000, "move", stream=stream, enabled=True) as bar:
        bar.to_fraction(0.25)
        assert "250/1000" in stream.getvalue()
        bar.to_fraction(1.0)
    assert "1000/1000" in stream.getvalue() and stream.getvalue().endswith("\n")
