"""Running a batch on an existing Dask distributed cluster (``--scheduler``, ``client=``).

Needs ``dask[distributed]`` (the ``meshopt-toolkit[dask]`` extra) here and on the workers,
with the same meshopt-toolkit (and plugins) installed there.

Inputs travel in one of two ways:

- ``"bytes"`` (the default): the client reads each input and sends its content; the
  worker writes it into a private temporary folder under the same file name. Works with
  no shared file system. A pipeline then reads only its own input (no ``--allow-read``).
- ``"path"`` (``--shared-inputs``): the client sends the absolute path and the worker
  reads it; the inputs must be visible to the workers at the same path (NFS, a cluster
  file system). Reads of other inputs and ``--allow-read`` paths work as locally.

Either way the worker writes its outputs into a temporary folder and sends their bytes
back; the client moves them into the output directory atomically and keeps the journal
(:mod:`.journal`), so results and outputs are the same as a local run's.

A worker that dies on a file (a native abort) is restarted by its nanny and Dask retries
the file on another worker up to ``distributed.scheduler.allowed-failures`` times; then
the file ends in ``KilledWorker``. Files queued on the dying workers can end so too: each
such file is retried once alone on the cluster, so only the file that crashes fails, and
the others go on.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ..errors import MeshoptError

__all__ = ["connect", "DaskExecutor", "SEND_MODES"]

SEND_MODES = ("bytes", "path")
#: seconds to reach the scheduler and to wait for a first worker
CONNECT_TIMEOUT = 10.0
_SCATTER_ABOVE = 1 << 20  # inputs larger than this go by scatter, not inside the task


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise MeshoptError("a Dask cluster needs dask.distributed: "
                           "pip install 'meshopt-toolkit[dask]'") from None
    return distributed


def _probe() -> str:  # pragma: no cover - runs on the workers
    import meshopt_toolkit

    return meshopt_toolkit.__version__


def connect(address: str, timeout: float | None = None):
    """A ``distributed.Client`` for the scheduler at ``address``, with at least one worker.

    Raises
    ------
    MeshoptError
        Dask is not installed, the scheduler cannot be reached in ``timeout`` seconds,
        it has no worker, or its workers cannot import meshopt_toolkit.
    """
    distributed = _import_distributed()
    timeout = CONNECT_TIMEOUT if timeout is None else timeout
    try:
        client = distributed.Client(address, timeout=f"{timeout}s", set_as_default=False)
    except Exception as exc:  # OSError, TimeoutError, ValueError (bad address)...
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise MeshoptError(f"cannot reach the Dask scheduler at {address}: {msg}") from None
    try:
        check_workers(client, timeout)
    except BaseException:
        client.close()
        raise
    return client


def check_workers(client, timeout: float = 10.0) -> None:
    """Wait for a worker and check that the workers import meshopt_toolkit."""
    from .. import __version__

    try:
        client.wait_for_workers(1, timeout=timeout)
    except Exception:
        raise MeshoptError(f"the Dask scheduler at {client.scheduler.address} has no "
                           f"worker (waited {timeout:g} s)") from None
    try:
        versions = client.run(_probe)
    except Exception as exc:
        raise MeshoptError(f"the Dask workers cannot run meshopt-toolkit ({type(exc).__name__}:"
                           f" {exc}); install it on every worker") from None
    other = sorted({v for v in versions.values() if v != __version__})
    if other:
        raise MeshoptError(f"the Dask workers have meshopt-toolkit {', '.join(other)}, this "
                           f"client {__version__}; install the same version everywhere")


def _identity(value):  # pragma: no cover - runs on the workers
    return value


def remote_run(task, src: str, data, index: int, name) -> dict:
    """Run ``task`` on one input on a worker; return the record and the outputs' bytes.

    ``data`` is the input's content (bytes mode) or None (path mode: ``src`` is read).
    """
    with tempfile.TemporaryDirectory(prefix="meshopt-batch-") as tmp:
        tmp = Path(tmp)
        if data is not None:
            (tmp / "in").mkdir()
            local = tmp / "in" / Path(src).name
            local.write_bytes(data)
        else:
            local = Path(src)
        out = tmp / "out"
        out.mkdir()
        record = task((str(local), index, name, str(out)))
        files = {}
        if record.get("status") == "ok":
            root = os.path.realpath(out)
            for p in record.get("outputs", ()):
                rel = os.path.relpath(os.path.realpath(p), root)
                if not rel.startswith("..") and os.path.isfile(p):
                    files[rel] = Path(p).read_bytes()
        return {"record": record, "files": files, "local": str(local), "outdir": str(out)}


class DaskExecutor:
    """Submit payloads to a Dask cluster (see the module docstring).

    Parameters
    ----------
    client : distributed.Client
    task : callable
        Sent once (a future the workers share).
    send : {"bytes", "path"}
    slots : int, optional
        Payloads in flight at once (default: twice the cluster's threads).
    """

    def __init__(self, client, task, *, send: str = "bytes", slots: int | None = None) -> None:
        distributed = _import_distributed()
        if send not in SEND_MODES:
            raise MeshoptError(f"send_inputs={send!r}: choose from {', '.join(SEND_MODES)}")
        self.client = client
        self.send = send
        # a computed (not scattered) value: if the workers holding it die, Dask recomputes it
        self._task = client.submit(_identity, task, pure=False)
        self._max_bytes = getattr(task, "max_bytes", None)
        threads = sum(client.nthreads().values()) or 1
        self.slots = slots or 2 * threads  # the most payloads in flight
        self._wait = distributed.wait
        self._ids: dict = {}  # future key -> (id, future, payload)
        self._suspects: list = []  # (id, payload) that ended in KilledWorker once
        self._retried: set = set()

    @property
    def free(self) -> int:
        if self._suspects:  # drain, then retry the suspects one at a time
            return 0
        return self.slots - len(self._ids)

    def submit(self, ident, payload) -> None:
        """Send one input (read here in bytes mode: an unreadable file raises OSError,
        one that is not a regular file :class:`~meshopt_toolkit.errors.ReadError`)."""
        from ..io._files import read_input

        src, index, name, _ = payload
        if self.send == "bytes":
            data = read_input(src, self._max_bytes)  # a FIFO or a device: ReadError
            if len(data) > _SCATTER_ABOVE:
                [data] = self.client.scatter([data], hash=False)
            where = str(src)
        else:
            data, where = None, os.path.abspath(src)
        future = self.client.submit(remote_run, self._task, where, data, index, name,
                                    pure=False)
        self._ids[future.key] = (ident, future, payload)

    def wait(self) -> list:
        """Block until at least one input is finished; ``[(id, result), ...]`` where a
        result is :func:`remote_run`'s dict or the exception the task ended with.

        A worker that dies takes down the tasks queued with it, not only the one that
        crashed it: a file that ends in ``KilledWorker`` is retried once, alone on the
        cluster, so that only the file that really crashes fails.
        """
        while self._ids or self._suspects:
            if self._suspects and not self._ids:
                ident, payload = self._suspects.pop(0)
                self._retried.add(ident)
                try:
                    self.submit(ident, payload)
                except OSError as exc:
                    return [(ident, exc)]
            out = self._collect()
            if out:
                return out
        return []

    def _collect(self) -> list:
        futures = [entry[1] for entry in self._ids.values()]
        try:
            with self.client.as_current():  # the client need not be the default one
                done, _ = self._wait(futures, return_when="FIRST_COMPLETED")
        except Exception:  # some were cancelled (their dependencies lost): report them
            done = [f for f in futures if f.done() or f.cancelled()]
            if not done:
                raise
        out = []
        for future in sorted(done, key=lambda f: self._ids[f.key][0]):
            ident, _, payload = self._ids.pop(future.key)
            try:
                result = future.result()
            except Exception as exc:  # KilledWorker, a lost connection, ...
                result = exc
            future.release()
            if type(result).__name__ == "KilledWorker" and ident not in self._retried:
                self._suspects.append((ident, payload))
                continue
            self._retried.discard(ident)
            out.append((ident, result))
        return out

    def close(self, *, kill: bool = False) -> None:
        futures = [entry[1] for entry in self._ids.values()] + [self._task]
        self._ids.clear()
        self._suspects.clear()
        self.client.cancel(futures)
