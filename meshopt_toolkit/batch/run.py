"""Batches at scale: worker processes, resume after a crash, a Dask cluster.

:func:`run_batch` is the library API (``mt.run_batch``); ``meshopt run`` and
``meshopt convert`` go through :func:`execute`, which runs any task of :mod:`.tasks`.

How a batch runs
----------------
- Inputs are consumed lazily and at most a window of them (a few per worker) is in flight
  or waiting to be reported: memory stays flat in the number of files, whether 10 or
  100,000. Records are reported in input order.
- Executors (:mod:`.workers`, :mod:`.cluster`): this process (``jobs=1``), N worker
  processes (``jobs=N``; a crash, a native abort or a ``MemoryError`` fails that file
  only), or a Dask cluster (``client=``).
- Tasks write into a scratch folder ``OUTDIR/.meshopt-staging/<run>-<n>`` (``<run>`` new
  in each run); this process moves each output into place (hard link or rename: atomic;
  an existing file is replaced only with ``force``) and records it in the journal
  (:mod:`.journal`). A killed run leaves no partial output: at worst a scratch folder.
- ``resume=True`` skips files the journal knows as done with the same input content and
  configuration and with all their outputs intact (``"status": "skipped"``). Temporaries
  are removed only by the exact names the journal recorded before making them.
- Inputs are opened by :func:`~meshopt_toolkit.io._files.open_input`: a FIFO, a device or
  a socket (symlinks resolved) fails that file with one line, and is never read.
"""

from __future__ import annotations

import dataclasses
import os
import secrets
import shutil
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .._options import options_of
from ..errors import MeshoptError, OptionError, WriteError
from ..io._atomic import place
from ..pipeline.runner import Pipeline
from .file_job import RunOptions
from .journal import Journal, config_sha256, file_sha256
from .progress import BatchProgress, count_outcome, format_summary
from .tasks import RunTask, failed_record
from .workers import RESTART_KEY, InlineExecutor, ProcessPool, WorkerCrash, cpu_count

__all__ = ["run_batch", "execute", "BatchResult", "Job", "resolve_jobs"]


@dataclass
class Job:
    """One input of a batch: its position (from 1), path and, optionally, output name."""

    index: int
    src: Path
    name: str | None = None


@dataclass
class BatchResult:
    """What a batch did.

    Attributes
    ----------
    done, skipped, failed : int
        Files processed (checked, in a dry run), skipped by ``resume``, failed.
    dry_run : bool
        Nothing was run or written: :meth:`report` says so instead of "done".
    seconds : float
        Wall time.
    records : list of dict or None
        One record per file in input order (None when an ``on_record`` callback took them).
    """

    done: int = 0
    skipped: int = 0
    failed: int = 0
    seconds: float = 0.0
    records: list[dict] | None = field(default_factory=list)
    dry_run: bool = False

    @property
    def ok(self) -> bool:
        return self.failed == 0

    @property
    def status(self) -> str:
        return "ok" if self.ok else "failed"

    def summary(self) -> dict:
        """The counts, ``dry_run``, ``seconds`` and ``status`` as a JSON-ready dict."""
        return {"done": self.done, "skipped": self.skipped, "failed": self.failed,
                "dry_run": self.dry_run, "seconds": float(self.seconds), "status": self.status}

    def report(self) -> str:
        """``N done, K skipped, F failed in T s``; in a dry run ``dry run: N checked, F
        failed, nothing written in T s``."""
        if self.dry_run:
            return (f"dry run: {self.done} checked, {self.failed} failed, nothing written "
                    f"in {self.seconds:.1f} s")
        return format_summary(self.done, self.skipped, self.failed, self.seconds)


def resolve_jobs(jobs: int) -> int:
    """``jobs`` workers, 0 meaning all the cores this process may use."""
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 0:
        raise MeshoptError(f"jobs={jobs!r}: expected 0 (all cores) or a positive integer")
    return cpu_count() if jobs == 0 else jobs


def _replace_text(obj, pairs: list[tuple[str, str]]):
    if isinstance(obj, str):
        for old, new in pairs:
            obj = obj.replace(old, new)
        return obj
    if isinstance(obj, list):
        return [_replace_text(v, pairs) for v in obj]
    if isinstance(obj, dict):
        return {k: _replace_text(v, pairs) for k, v in obj.items()}
    return obj


def _move(staged: Path, final: Path, overwrite: bool) -> None:
    """Move a complete file into place atomically; never replace without ``overwrite``."""
    final.parent.mkdir(parents=True, exist_ok=True)
    if final.is_dir():
        raise WriteError(f"{final}: is a directory")
    place(staged, final, overwrite, "use --force to overwrite")


@dataclass
class _Pending:
    job: Job
    key: str | None = None
    input_sha: str | None = None
    stage: Path | None = None


class _Batch:
    """One run of :func:`execute` (state shared by prepare / finish)."""

    def __init__(self, task, outdir, *, force: bool, resume: bool, dry_run: bool,
                 remote: bool) -> None:
        self.task = task
        self.outdir = None if outdir is None else Path(outdir)
        self.force, self.resume, self.dry_run, self.remote = force, resume, dry_run, remote
        self.config_sha = config_sha256(task.config())
        self.journal: Journal | None = None
        self.staging: Path | None = None
        self._run = secrets.token_hex(4)  # this run's scratch folders: <run>-<n>
        self._seq = 0

    def open(self) -> None:
        if self.dry_run or self.outdir is None:
            return
        try:
            self.outdir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise MeshoptError(f"{self.outdir}: cannot create the output directory: "
                               f"{exc.strerror or exc}") from None
        self.journal = Journal(self.outdir)  # locked: no other batch writes here now
        try:
            self.staging = self.journal.reset_staging()  # only what the journal recorded
        except MeshoptError:
            self.journal.close()  # the lock goes with the refusal
            self.journal = None
            raise

    def close(self) -> None:
        if self.journal is not None:
            try:
                self.journal.remove_temporaries()  # the staging folder
            except (OSError, MeshoptError):
                pass  # recorded: the next run removes it
            self.journal.close()

    def prepare(self, job: Job) -> tuple[_Pending, Any] | dict:
        """A payload for the executor, or at once a record (skipped, or failed early)."""
        src = Path(job.src)
        pending = _Pending(job)
        if self.journal is None:  # a dry run: nothing written, nothing journaled
            out = None if self.outdir is None else str(self.outdir)
            return pending, (str(src), job.index, job.name, out)
        try:  # a FIFO or a device is refused here, before it is read
            pending.input_sha = file_sha256(src, max_bytes=getattr(self.task, "max_bytes", None))
        except MeshoptError as exc:
            return failed_record(src, str(exc))
        except OSError as exc:
            return failed_record(src, f"{src}: cannot read: {exc.strerror or exc}")
        pending.key = Journal.key(src, pending.input_sha, self.config_sha, job.name)
        if self.resume:
            outputs = self.journal.completed(pending.key)
            if outputs is not None:
                rec = failed_record(src, None)
                rec.update(status="skipped", outputs=[str(self.outdir / o["path"])
                                                      for o in outputs])
                return rec
        name = job.name or self.task.output_name(src)
        if name:
            dst = self.outdir / name
            if (dst.exists() and not self.force
                    and not self.journal.is_own(pending.key, name)):
                why = "is the input file" if dst.resolve() == src.resolve() else "already exists"
                return failed_record(src, f"{dst}: {why} (use --force to overwrite)")
        self._seq += 1
        pending.stage = self.staging / f"{self._run}-{self._seq}"
        if not self.remote:
            pending.stage.mkdir()
        return pending, (str(src), job.index, job.name, str(pending.stage))

    def finish(self, pending: _Pending, raw) -> dict:
        """The record of a finished payload; its outputs moved into place and journaled."""
        src = pending.job.src
        stage = pending.stage
        try:
            rec = self._record(pending, raw)
            if stage is not None:
                if rec["status"] == "ok":
                    self._publish(pending, rec)
                else:
                    rec["outputs"] = []
                out = str(self.outdir) + os.sep
                pairs = [(str(stage) + os.sep, out), (os.path.realpath(stage) + os.sep, out)]
                rec.update(_replace_text({k: rec.get(k) for k in ("results", "warnings", "error")},
                                         pairs))
        finally:
            if pending.stage is not None:
                shutil.rmtree(pending.stage, ignore_errors=True)
        rec["input"] = str(src)
        return rec

    def _record(self, pending: _Pending, raw) -> dict:
        src = pending.job.src
        if isinstance(raw, WorkerCrash):
            return failed_record(src, f"{src}: {raw.describe()}; other files go on")
        if isinstance(raw, MemoryError):
            return failed_record(src, f"{src}: out of memory (MemoryError)")
        if isinstance(raw, BaseException):
            name = type(raw).__name__
            if name == "KilledWorker":
                return failed_record(src, f"{src}: each Dask worker that ran it died "
                                          "(KilledWorker: a native crash?); other files go on")
            return failed_record(src, f"{src}: {name}: {raw}")
        if isinstance(raw, dict) and "files" in raw:  # from a Dask worker
            rec = dict(raw["record"])
            rec.pop(RESTART_KEY, None)  # Dask's nanny restarts a worker, not we
            pairs = [(raw["outdir"], str(pending.stage)), (raw["local"], str(src))]
            rec = _replace_text(rec, pairs)
            if rec["status"] == "ok":
                for rel, data in raw["files"].items():
                    path = pending.stage / rel
                    path.parent.mkdir(parents=True, exist_ok=True)
                    path.write_bytes(data)
            return rec
        rec = dict(raw)
        rec.pop(RESTART_KEY, None)
        return rec

    def _publish(self, pending: _Pending, rec: dict) -> None:
        stage, outdir = pending.stage, self.outdir
        root = os.path.realpath(stage)
        rels: list[str] = []
        for p in rec["outputs"]:
            rel = os.path.relpath(os.path.realpath(p), root)
            if rel.startswith("..") or os.path.isabs(rel):
                raise MeshoptError(f"{p}: an output outside the scratch folder")  # a bug
            if rel not in rels:
                rels.append(rel)
        own = {rel: self.journal.is_own(pending.key, rel) for rel in rels}
        self.journal.will_publish(pending.key, rels)
        published = []
        try:
            for rel in rels:
                staged = stage / rel
                item = {"path": rel, "size": staged.stat().st_size,
                        "sha256": file_sha256(staged)}
                _move(staged, outdir / rel, self.force or own[rel])
                published.append(item)
        except (WriteError, OSError) as exc:
            msg = str(exc) if isinstance(exc, WriteError) else \
                f"{exc.filename or outdir}: {exc.strerror or exc}"
            rec.update(status="failed", error=msg)
        if rec["status"] == "ok":
            self.journal.mark_done(pending.key, pending.job.src, pending.input_sha,
                                   self.config_sha, published)
        rec["outputs"] = [str(outdir / item["path"]) for item in published]


def execute(task, jobs: Iterable[Job], outdir, *, workers: int = 1, isolate: bool = False,
            client=None, send_inputs: str = "bytes", resume: bool = False, force: bool = False,
            dry_run: bool = False, on_record: Callable[[dict], None] | None = None,
            progress: BatchProgress | None = None) -> BatchResult:
    """Run ``task`` over ``jobs``; see the module docstring.

    Parameters
    ----------
    task : RunTask or ConvertTask
    jobs : iterable of Job
        Consumed lazily.
    outdir : path or None
        Where outputs go (None only in a dry run).
    workers : int
        Worker processes (1 with ``isolate=False``: this process).
    isolate : bool
        Use a worker process even for ``workers=1``.
    client : distributed.Client, optional
        Run on this Dask cluster instead (``workers`` is then ignored); a dry run, which
        runs no filter, is checked here all the same.
    send_inputs : {"bytes", "path"}
        How a Dask cluster gets the inputs (see :mod:`.cluster`).
    resume, force, dry_run : bool
    on_record : callable, optional
        Called with each record in input order (then :attr:`BatchResult.records` is None).
    progress : BatchProgress, optional

    Returns
    -------
    BatchResult
    """
    t0 = time.perf_counter()
    if dry_run:  # runs no filter and needs the real output directory: checked here
        client = None
    batch = _Batch(task, outdir, force=force, resume=resume, dry_run=dry_run,
                   remote=client is not None)
    if client is not None:
        from .cluster import DaskExecutor

        if isinstance(task, RunTask):
            if send_inputs == "bytes" and task.options.allow_read:
                raise MeshoptError("reading other files (--allow-read) on a Dask cluster needs "
                                   "the inputs on a shared file system: add --shared-inputs")
            if send_inputs == "bytes":  # the worker has only its own input
                task = task.with_options(inputs=[])
        executor = DaskExecutor(client, task, send=send_inputs)
    elif workers > 1 or isolate:
        executor = ProcessPool(task, workers, single_thread=workers > 1)
    else:
        executor = InlineExecutor(task)
    result = BatchResult(records=None if on_record is not None else [], dry_run=dry_run)
    window = 4 * executor.slots + 8
    pending: dict[int, _Pending] = {}
    ready: dict[int, dict] = {}
    seq = emitted = 0

    def emit() -> None:
        nonlocal emitted
        while emitted in ready:
            rec = ready.pop(emitted)
            emitted += 1
            count_outcome(result, rec["status"])
            if on_record is not None:
                on_record(rec)
            else:
                result.records.append(rec)
            if progress is not None:
                progress.record(rec["status"])

    batch.open()
    clean = False
    try:
        it = iter(jobs)
        exhausted = False
        while True:
            while not exhausted and executor.free > 0 and seq - emitted < window:
                job = next(it, None)
                if job is None:
                    exhausted = True
                    break
                prepared = batch.prepare(job)
                if isinstance(prepared, dict):
                    ready[seq] = prepared
                else:
                    try:
                        executor.submit(seq, prepared[1])
                        pending[seq] = prepared[0]
                    except MeshoptError as exc:  # bytes mode: refused by open_input
                        ready[seq] = failed_record(job.src, str(exc))
                    except OSError as exc:  # bytes mode: the client could not read it
                        ready[seq] = failed_record(job.src, f"{job.src}: cannot read: "
                                                            f"{exc.strerror or exc}")
                seq += 1
                emit()
            emit()
            if not pending:
                if exhausted:
                    break
                continue
            for ident, raw in executor.wait():
                ready[ident] = batch.finish(pending.pop(ident), raw)
            emit()
        clean = True
    finally:
        executor.close(kill=not clean)
        batch.close()
    result.seconds = time.perf_counter() - t0
    return result


def run_batch(pipeline: Pipeline | dict | str | os.PathLike, inputs, outdir, *, jobs: int = 1,
              client=None, resume: bool = False, shared_inputs: bool = False,
              isolate: bool | None = None, options: RunOptions | Mapping | None = None,
              on_record: Callable[[dict], None] | None = None,
              progress: bool = False) -> BatchResult:
    """Run a pipeline over many mesh files: in parallel, resumable, or on a Dask cluster.

    Each input is loaded, the pipeline runs on it and the current mesh is saved as
    ``outdir/<stem><ext>`` (unless the pipeline saves by itself), as ``meshopt run`` does.
    A bad file, a crash or a ``MemoryError`` fails that file only (its record says why).

    Parameters
    ----------
    pipeline : Pipeline, dict or path
        A pipeline, its JSON dict, or a ``.json``/``.mlx`` file.
    inputs : iterable of path
        Mesh files, consumed lazily (a generator over a directory tree is fine).
    outdir : path
        Output directory (created if missing); it also holds the journal.
    jobs : int
        Worker processes; 0 means all cores; 1 runs in this process (unless the pipeline
        has MeshLab or plugin steps, which get a worker process to contain native crashes).
    client : distributed.Client or str, optional
        A Dask client (or a scheduler address) to run on instead of local processes.
    resume : bool
        Skip files already done by an earlier run with the same pipeline and input.
    shared_inputs : bool
        On a cluster, let workers read inputs from the same path instead of sending their
        bytes (default).
    isolate : bool, optional
        Force a worker process for ``jobs=1`` (True) or not (False).
    options : :class:`~meshopt_toolkit.batch.file_job.RunOptions` or a mapping of its
        fields, optional
        How each file runs: ``ext`` (the output format, ``"vtu"`` or ``".vtu"``; default
        the input's), ``force`` (replace existing outputs), ``dry_run`` (check
        everything, run no filter, write nothing), the size budget, ``allow_read``...
    on_record : callable, optional
        Gets each file's record in input order; then records are not kept (flat memory).
    progress : bool
        Show a progress bar on stderr when it is a terminal.

    Returns
    -------
    BatchResult
        Counts, time and (without ``on_record``) the records.

    Examples
    --------
    >>> import meshopt_toolkit as mt                                    # doctest: +SKIP
    >>> from dask.distributed import Client                             # doctest: +SKIP
    >>> res = mt.run_batch("smooth.json", sorted(Path("runs").rglob("*.msh")), "out",
    ...                    client=Client("tcp://10.0.0.5:8786"), resume=True)  # doctest: +SKIP
    >>> res.report()                                                    # doctest: +SKIP
    '118 done, 0 skipped, 2 failed in 41.3 s'
    """
    from ..pipeline.formats import load_pipeline

    if isinstance(pipeline, (str, os.PathLike)):
        pipeline = load_pipeline(pipeline)
    elif isinstance(pipeline, dict):
        pipeline = Pipeline.from_dict(pipeline)
    pipeline.validate()
    workers = resolve_jobs(jobs)
    opts = options_of(RunOptions, options, {}, error=OptionError, what="run option(s)")
    ext = opts.ext and (opts.ext.lower() if opts.ext.startswith(".") else "." + opts.ext.lower())
    opts = dataclasses.replace(opts, ext=ext)  # a copy: the caller's options stay as given
    force, dry_run = opts.force, opts.dry_run
    if outdir is None and not dry_run:
        raise MeshoptError("run_batch: outdir is required (except with dry_run=True)")
    if isolate is None:
        isolate = not pipeline.only_builtin and not dry_run
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    total = len(inputs) if hasattr(inputs, "__len__") else None
    jobs_iter = (Job(i, Path(p)) for i, p in enumerate(inputs, start=1))
    own_client = None
    if isinstance(client, str):
        from .cluster import connect

        client = own_client = connect(client)
    bar = BatchProgress(total, "run") if progress else None
    try:
        return execute(RunTask(pipeline, opts), jobs_iter, outdir, workers=workers,
                       isolate=isolate, client=client,
                       send_inputs="path" if shared_inputs else "bytes", resume=resume,
                       force=force, dry_run=dry_run, on_record=on_record, progress=bar)
    finally:
        if bar is not None:
            bar.close()
        if own_client is not None:
            own_client.close()
