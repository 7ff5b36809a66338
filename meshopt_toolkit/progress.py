"""A dependency-free progress bar for long work, shown only on a terminal."""

from __future__ import annotations

import contextlib
import logging
import sys
import threading
import time
from typing import IO, Iterator


class ProgressBar:
    """Minimal progress bar on stderr.

    While it is shown, its clock is redrawn every ``tick`` seconds, so work that does not
    advance the count (a search before the first iteration) is still seen to run; the
    status stays until the next one is given (:meth:`update`, :meth:`showing_log`).

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
    tick : float
        Seconds between two redraws of the clock (0: redrawn only by :meth:`update`).

    Examples
    --------
    >>> with ProgressBar(3, "convert", enabled=False) as bar:
    ...     for _ in range(3):
    ...         bar.update(status="ok")
    """

    def __init__(self, total: int, label: str = "", stream: IO[str] | None = None,
                 enabled: bool | None = None, tick: float = 1.0) -> None:
        self.total = max(int(total), 1)
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.count = 0
        self.status = ""
        self._start = time.perf_counter()
        self._last = 0.0
        self._lock = threading.RLock()
        self._closed = threading.Event()
        self._ticker = None
        if self.enabled and tick > 0:
            self._ticker = threading.Thread(target=self._tick, args=(float(tick),),
                                            daemon=True)
            self._ticker.start()

    def update(self, n: int = 1, status: str | None = None) -> None:
        """Advance by ``n`` steps, with ``status`` where given, and redraw (at most 10
        times a second, always at the end)."""
        with self._lock:
            self.count = min(self.count + n, self.total)
            if status is not None:
                self.status = status
            now = time.perf_counter()
            if self.enabled and (now - self._last >= 0.1 or self.count >= self.total):
                self._draw(now)

    def to_fraction(self, fraction: float) -> None:
        """Advance to ``fraction`` (in [0, 1]) of ``total`` and redraw: a ``progress``
        callback of the operations that report the part of their work done."""
        self.update(int(self.total * fraction) - self.count)

    @contextlib.contextmanager
    def showing_log(self, name: str, level: int = logging.DEBUG) -> Iterator[None]:
        """Inside, the messages of the logger ``name`` at ``level`` and above are the
        bar's status (where it is shown): the stages of work that has no count. The
        logger passes them on as before; a handler that shows less (the command line's
        stderr at its verbosity) still shows less."""
        if not self.enabled:
            yield
            return
        logger = logging.getLogger(name)
        handler = _StatusHandler(self, level)
        kept = logger.level
        if not logger.isEnabledFor(level):
            logger.setLevel(level)
        logger.addHandler(handler)
        try:
            yield
        finally:
            logger.removeHandler(handler)
            logger.setLevel(kept)

    def close(self) -> None:
        """Stop the clock and finish the line."""
        self._closed.set()
        if self._ticker is not None:
            self._ticker.join()
        if self.enabled:
            with self._lock:
                self.stream.write("\n")
                self.stream.flush()

    def line(self) -> str:
        """The bar's text, e.g. ``morph [#####.....] 3/20  12.5s E=0.0421``."""
        width = 30
        filled = int(width * self.count / self.total)
        return (f"{self.label} [{'#' * filled}{'.' * (width - filled)}] "
                f"{self.count}/{self.total} {time.perf_counter() - self._start:5.1f}s "
                f"{self.status}")

    def _draw(self, now: float) -> None:
        self._last = now
        self.stream.write("\r" + self.line()[:119].ljust(119))
        self.stream.flush()

    def _tick(self, period: float) -> None:
        while not self._closed.wait(period):
            with self._lock:
                self._draw(time.perf_counter())

    def __enter__(self) -> "ProgressBar":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _StatusHandler(logging.Handler):
    """A log record's message as a :class:`ProgressBar`'s status."""

    def __init__(self, bar: ProgressBar, level: int) -> None:
        super().__init__(level)
        self.bar = bar

    def emit(self, record: logging.LogRecord) -> None:
        self.bar.update(0, status=" ".join(record.getMessage().split()))
