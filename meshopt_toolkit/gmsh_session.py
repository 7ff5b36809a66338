"""Run gmsh inside a Python process without changing that process's signal handlers.

``gmsh.initialize()`` resets the process-wide signal dispositions: SIGPIPE is no longer
ignored (so a program whose output is piped into ``head``/``tail``, or that writes to a
worker that died, is killed by SIGPIPE instead of getting ``BrokenPipeError``) and, unless
``interruptible=False``, Ctrl-C no longer raises ``KeyboardInterrupt``.
:func:`gmsh_session` restores every handler Python knows about right after initializing.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator
from types import ModuleType


def _python_handlers() -> dict[signal.Signals, object]:
    handlers = {}
    for sig in signal.valid_signals():
        try:
            handler = signal.getsignal(sig)
        except (OSError, ValueError):  # pragma: no cover - platform specific
            continue
        if handler is not None:  # None: installed outside Python, nothing to restore
            handlers[sig] = handler
    return handlers


def _restore(handlers: dict[signal.Signals, object]) -> None:
    for sig, handler in handlers.items():
        with contextlib.suppress(OSError, ValueError, RuntimeError):  # SIGKILL/SIGSTOP, threads
            signal.signal(sig, handler)


@contextlib.contextmanager
def gmsh_session(*, terminal: bool = False, deterministic: bool = False) -> Iterator[ModuleType]:
    """Initialize gmsh, yield the module, finalize; signal handlers stay as they were.

    Parameters
    ----------
    terminal : bool
        Let gmsh print its messages (``General.Terminal``).
    deterministic : bool
        Mesh in one thread with a fixed random seed: the same mesh on every run.

    Examples
    --------
    >>> with gmsh_session() as gmsh:                      # doctest: +SKIP
    ...     gmsh.model.occ.addDisk(0, 0, 0, 1, 1)
    """
    import gmsh

    handlers = _python_handlers()
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    _restore(handlers)
    try:
        gmsh.option.setNumber("General.Terminal", int(terminal))
        if deterministic:
            gmsh.option.setNumber("General.NumThreads", 1)
            gmsh.option.setNumber("Mesh.RandomSeed", 1)
        yield gmsh
    finally:
        gmsh.finalize()
        _restore(handlers)
