"""Executors for a batch: in this process, or in worker processes with per-file isolation.

An executor runs a *task* (a picklable callable, see :mod:`.tasks`) on payloads. The
driver (:mod:`.run`) gives each payload an id with :meth:`submit` while
:attr:`free` is positive and collects ``(id, result)`` pairs with :meth:`wait`.

:class:`ProcessPool` starts N worker processes (``spawn``: no state inherited from the
parent, nothing forked from a threaded process). Each worker gets the task once, then one
payload at a time over its own pipe, so a worker that dies — a native abort in pymeshlab,
a segmentation fault, the kernel's out-of-memory killer — is known to have died on
exactly one payload: that one gets a :class:`WorkerCrash` result, a fresh worker replaces
it and the others go on. A ``MemoryError`` that the task reports retires its worker too.

Workers die with the batch process, even when it is killed with SIGKILL: on Linux the
kernel sends them SIGKILL (``PR_SET_PDEATHSIG``), and everywhere a thread of each worker
waits on its parent's sentinel and ends the worker when the parent is gone. No worker
outlives its batch to write into the folders of the next run.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import multiprocessing
import os
import signal
import sys
import threading
from dataclasses import dataclass
from multiprocessing.connection import wait as _wait_any
from typing import Any, Callable

from ..cores import available_cores

__all__ = ["WorkerCrash", "InlineExecutor", "ProcessPool", "cpu_count", "RESTART_KEY"]

#: a task's result dict with this key true asks for a fresh worker (after a MemoryError)
RESTART_KEY = "_restart_worker"
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
_env_lock = threading.Lock()


def cpu_count() -> int:
    """The cores this process may use (``-j 0``): :func:`meshopt_toolkit.cores.available_cores`."""
    return available_cores()


@dataclass
class WorkerCrash:
    """The result of a payload whose worker process died while running it."""

    exitcode: int | None

    def describe(self) -> str:
        """``the worker process crashed (killed by SIGABRT: ...)``."""
        code = self.exitcode
        if code is None:
            return "the worker process crashed (it disappeared)"
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            hint = {"SIGKILL": ": out of memory?", "SIGABRT": ": a native MeshLab filter "
                    "aborted?", "SIGSEGV": ": a native MeshLab filter crashed?"}.get(name, "")
            return f"the worker process crashed (killed by {name}{hint})"
        return f"the worker process crashed (exit status {code})"


class InlineExecutor:
    """Run each payload at once, in this process (``-j 1`` without isolation)."""

    slots = 1  # the most payloads at once

    def __init__(self, task: Callable[[Any], Any]) -> None:
        self.task = task
        self._done: list = []

    @property
    def free(self) -> int:
        return 0 if self._done else 1

    def submit(self, ident, payload) -> None:
        result = self.task(payload)
        if isinstance(result, dict):
            result.pop(RESTART_KEY, None)
        self._done.append((ident, result))

    def wait(self) -> list:
        done, self._done = self._done, []
        return done

    def close(self, *, kill: bool = False) -> None:
        pass


_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _exit_when_gone(sentinel) -> None:  # pragma: no cover - runs in the worker
    _wait_any([sentinel])
    os._exit(1)  # at once and silently: the batch that wanted the result is gone


def _die_with_parent(parent_pid: int) -> None:  # pragma: no cover - runs in the worker
    """End this process as soon as the batch process ``parent_pid`` ends, however it ends."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent_pid:  # gone before the request was in place
        os._exit(1)
    parent = multiprocessing.parent_process()
    if parent is not None:  # the portable watch, where the kernel has no death signal
        threading.Thread(target=_exit_when_gone, args=(parent.sentinel,), daemon=True,
                         name="meshopt-parent-watch").start()


def _received(conn):  # pragma: no cover - runs in the worker
    """The parent's next message; None when the pipe is closed."""
    try:
        return conn.recv()
    except (EOFError, OSError):
        return None


def _worker_main(conn, parent_pid: int) -> None:  # pragma: no cover - runs in the worker
    # before the task comes (and its modules load): die with the batch process
    _die_with_parent(parent_pid)
    # Ctrl-C goes to the whole process group: the parent decides, and stops us
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.basicConfig(level=logging.WARNING)
    task = _received(conn)
    if task is None:
        return
    while (msg := _received(conn)) is not None:  # None: stop, or the parent is gone
        ident, payload = msg
        restart = False
        try:
            result = task(payload)
            if isinstance(result, dict):
                restart = bool(result.pop(RESTART_KEY, False))
        except MemoryError:
            result, restart = MemoryError("out of memory"), True
        try:
            conn.send((ident, result, restart))
        except OSError:  # the parent is gone: nobody to answer
            return
        except Exception as exc:  # an unpicklable result: still an answer
            try:
                conn.send((ident, RuntimeError(f"cannot send the result back: {exc}"),
                           restart))
            except OSError:
                return
        if restart:
            return


@contextlib.contextmanager
def _single_threaded_env():
    """Children start with one BLAS/OpenMP thread each, unless the user chose otherwise."""
    with _env_lock:
        added = [v for v in _THREAD_VARS if v not in os.environ]
        for v in added:
            os.environ[v] = "1"
        try:
            yield
        finally:
            for v in added:
                os.environ.pop(v, None)


class _Worker:
    def __init__(self, ctx, task, single_thread: bool) -> None:
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker_main, args=(child, os.getpid()),
                                   daemon=True)
        with _single_threaded_env() if single_thread else contextlib.nullcontext():
            self.process.start()
        child.close()
        with contextlib.suppress(OSError):  # dead already: its first payload says so
            self.conn.send(task)
        self.ident = None

    def stop(self, kill: bool) -> None:
        if kill:
            self.process.kill()
        else:
            with contextlib.suppress(OSError):
                self.conn.send(None)
        self.process.join(timeout=5)
        if self.process.is_alive():  # pragma: no cover
            self.process.kill()
            self.process.join()
        self.conn.close()


class ProcessPool:
    """N worker processes, one payload each at a time (see the module docstring).

    Parameters
    ----------
    task : callable
        Picklable; sent once to each worker.
    workers : int
        How many processes (started when first needed).
    single_thread : bool
        Start them with one BLAS/OpenMP thread each (N workers on N cores).
    """

    def __init__(self, task, workers: int, *, single_thread: bool = True) -> None:
        self.task = task
        self.slots = max(int(workers), 1)  # the most payloads at once: one per process
        self.single_thread = single_thread
        self._ctx = multiprocessing.get_context("spawn")
        self._idle: list[_Worker] = []
        self._busy: list[_Worker] = []

    @property
    def free(self) -> int:
        return self.slots - len(self._busy)

    def submit(self, ident, payload) -> None:
        if self.free <= 0:
            raise RuntimeError("no free worker")
        worker = self._idle.pop() if self._idle else _Worker(self._ctx, self.task,
                                                             self.single_thread)
        try:
            worker.conn.send((ident, payload))
        except OSError:  # it died while idle: a fresh one
            worker.stop(kill=True)
            worker = _Worker(self._ctx, self.task, self.single_thread)
            worker.conn.send((ident, payload))
        worker.ident = ident
        self._busy.append(worker)

    def wait(self) -> list:
        """Block until at least one payload is finished; ``[(id, result), ...]``."""
        if not self._busy:
            return []
        waitables = [w.conn for w in self._busy] + [w.process.sentinel for w in self._busy]
        ready = set(_wait_any(waitables))
        finished = []
        for worker in list(self._busy):
            if worker.conn not in ready and worker.process.sentinel not in ready:
                continue
            try:
                ident, result, restart = worker.conn.recv()
                alive = not restart
            except (EOFError, OSError):
                worker.process.join(timeout=5)
                ident, result, alive = worker.ident, WorkerCrash(worker.process.exitcode), False
            self._busy.remove(worker)
            if alive and worker.process.is_alive():
                worker.ident = None
                self._idle.append(worker)
            else:
                worker.stop(kill=True)
            finished.append((ident, result))
        return finished

    def close(self, *, kill: bool = False) -> None:
        """Stop all workers (``kill``: at once, abandoning running payloads)."""
        for worker in self._idle + self._busy:
            worker.stop(kill=kill or worker in self._busy)
        self._idle, self._busy = [], []
