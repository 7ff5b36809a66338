"""ProgressBar: the count a fraction of the work gives, what it draws, its clock and the
log messages it shows."""

import io
import logging
import time

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


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def _draws(stream) -> list[str]:
    return [d for d in stream.getvalue().split("\r") if d.strip()]


def test_the_clock_is_redrawn_without_updates_and_stops_when_closed():
    stream = _Terminal()
    bar = ProgressBar(10, "morph", stream=stream, tick=0.02)
    assert bar.enabled
    deadline = time.monotonic() + 30.0
    while len(_draws(stream)) < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert len(_draws(stream)) >= 3
    assert all("0/10" in d for d in _draws(stream))
    bar.close()
    written = stream.getvalue()
    time.sleep(0.1)
    assert stream.getvalue() == written and written.endswith("\n")


def test_a_pipe_gets_no_clock():
    stream = io.StringIO()
    with ProgressBar(10, "morph", stream=stream, tick=0.01) as bar:
        assert bar._ticker is None
        time.sleep(0.05)
    assert stream.getvalue() == ""


def test_the_log_s_messages_are_the_status_and_the_logger_is_left_as_it_was():
    stream = _Terminal()
    logger = logging.getLogger("meshopt_toolkit.motion.test_progress")
    before = logger.level
    with ProgressBar(10, "morph", stream=stream, tick=0) as bar:
        logger.debug("not shown: before")
        with bar.showing_log("meshopt_toolkit.motion"):
            logger.debug("start path: the homotopy,\n increment %d of %d", 3, 32)
            assert bar.status == "start path: the homotopy, increment 3 of 32"
            bar.update(status="E=1.5")
        logger.debug("not shown: after")
        assert bar.status == "E=1.5"
    assert logger.level == before and logging.getLogger("meshopt_toolkit.motion").level == 0
    assert "start path: the homotopy, increment 3 of 32" in stream.getvalue()
    assert "not shown" not in stream.getvalue()
