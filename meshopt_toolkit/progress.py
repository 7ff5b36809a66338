"""A dependency-free progress bar for long work, shown only on a terminal."""

from __future__ import annotations

import sys
import time
from typing import IO


class ProgressBar:
    """Minimal progress bar on stderr.

    Parameters
    ----------
    total : int
        Number of steps.
    label : str
        Shown before the bar.
    stream : file, optional
        Defaults to ``sys.stderr``.
    enabled : bool, optional
        Defaults to whether ``stream`` is a terminal; a bar never pollutes logs or pipes.

    Examples
    --------
    >>> with ProgressBar(3, "convert", enabled=False) as bar:
    ...     for _ in range(3):
    ...         bar.update(status="ok")
    """

    def __init__(self, total: int, label: str = "", stream: IO[str] | None = None,
                 enabled: bool | None = None) -> None:
        self.total = max(int(total), 1)
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.count = 0
        self._start = time.perf_counter()
        self._last = 0.0

    def update(self, n: int = 1, status: str = "") -> None:
        """Advance by ``n`` steps and redraw (at most 10 times a second, always at the end)."""
        self.count = min(self.count + n, self.total)
        now = time.perf_counter()
        if not self.enabled or (now - self._last < 0.1 and self.count < self.total):
            return
        self._last = now
        width = 30
        filled = int(width * self.count / self.total)
        elapsed = now - self._start
        line = (f"\r{self.label} [{'#' * filled}{'.' * (width - filled)}] "
                f"{self.count}/{self.total} {elapsed:5.1f}s {status}")
        self.stream.write(line[:120].ljust(120))
        self.stream.flush()

    def to_fraction(self, fraction: float) -> None:
        """Advance to ``fraction`` (in [0, 1]) of ``total`` and redraw: a ``progress``
        callback of the operations that report the part of their work done."""
        self.update(int(self.total * fraction) - self.count)

    def close(self) -> None:
        """Finish the line."""
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self) -> "ProgressBar":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
