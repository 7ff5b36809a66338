"""The progress bar of a batch: files done, skipped and failed, rate and time left."""

from __future__ import annotations

import time
from typing import IO

from ..progress import ProgressBar

__all__ = ["BatchProgress", "count_outcome", "format_summary"]


def format_summary(done: int, skipped: int, failed: int, seconds: float) -> str:
    """``N done, K skipped, F failed in T s`` (the last line of a batch)."""
    return f"{done} done, {skipped} skipped, {failed} failed in {seconds:.1f} s"


def count_outcome(counts, status: str) -> None:
    """Add one file with ``status`` (``"ok"``, ``"skipped"``, anything else: failed) to
    the ``done`` / ``skipped`` / ``failed`` counters of ``counts``."""
    name = {"ok": "done", "skipped": "skipped"}.get(status, "failed")
    setattr(counts, name, getattr(counts, name) + 1)


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class BatchProgress(ProgressBar):
    """A :class:`~meshopt_toolkit.progress.ProgressBar` that counts outcomes.

    Shown only when ``stream`` (stderr by default) is a terminal, so nothing reaches pipes
    or logs. The rate counts files actually processed (skipped ones fly by) and the time
    left assumes the rest goes at that rate.

    Parameters
    ----------
    total : int or None
        Number of files (None: unknown, then no bar and no time left).
    label : str
        Shown before the bar.
    stream, enabled :
        As in :class:`~meshopt_toolkit.progress.ProgressBar`.

    Examples
    --------
    >>> bar = BatchProgress(2, "run", enabled=False)
    >>> bar.record("ok"); bar.record("skipped")
    >>> bar.line().split(" | ")[:2]
    ['run [########################] 2/2', '1 done, 1 skipped']
    """

    def __init__(self, total: int | None, label: str = "", stream: IO[str] | None = None,
                 enabled: bool | None = None) -> None:
        self.known = total is not None
        self.done = self.skipped = self.failed = 0
        super().__init__(total or 1, label, stream, enabled)

    def record(self, status: str) -> None:
        """Count one file (``"ok"``, ``"skipped"`` or ``"failed"``) and redraw."""
        count_outcome(self, status)
        self.update()

    def line(self) -> str:
        """The bar's text, e.g. ``run [####......] 40/120 | 38 done, 2 failed | 3.1 files/s
        | 0:26 left``."""
        finished = self.done + self.skipped + self.failed
        elapsed = time.perf_counter() - self._start
        rate = (self.done + self.failed) / elapsed if elapsed > 0 else 0.0
        parts = [f"{self.done} done"]
        if self.skipped:
            parts.append(f"{self.skipped} skipped")
        if self.failed:
            parts.append(f"{self.failed} failed")
        text = f"{self.label} "
        if self.known:
            width = 24
            filled = int(width * finished / self.total)
            text += f"[{'#' * filled}{'.' * (width - filled)}] {finished}/{self.total} | "
        text += ", ".join(parts) + f" | {rate:.1f} files/s"
        if self.known and rate > 0 and finished < self.total:
            text += f" | {_clock((self.total - finished) / rate)} left"
        return text

    def update(self, n: int = 1, status: str | None = None) -> None:
        """Redraw (at most 10 times a second, always at the end)."""
        with self._lock:
            self.count = self.done + self.skipped + self.failed
            now = time.perf_counter()
            last = self.known and self.count >= self.total
            if self.enabled and (now - self._last >= 0.1 or last):
                self._draw(now)

    def clear(self) -> None:
        """Blank the bar's line (before something else is printed on the terminal)."""
        if self.enabled:
            with self._lock:
                self.stream.write("\r" + " " * 119 + "\r")
                self.stream.flush()
                self._last = 0.0

    def message(self, text: str) -> None:
        """Write a line (a warning or an error) without mixing it into the bar."""
        with self._lock:
            self.clear()
            self.stream.write(text + "\n")
            self.stream.flush()
            if self.enabled:
                self._last = 0.0
                self.update()
