"""Running a pipeline over many files with per-file isolation of errors and crashes.

:func:`run_file` runs one input (load → pipeline → save) and returns a JSON-able record;
errors become ``status="failed"`` records instead of exceptions. :class:`BatchRunner`
calls it for each file, either in this process or — for pipelines with MeshLab or plugin
steps, whose native code can abort the process (GPU filters without a display, some
attribute/PLY combinations) — in a child process: a crash then fails only that file and
a fresh worker takes the next one.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Callable

from ..errors import MeshoptError
from .document import Document
from .limits import DEFAULT_MAX_TRIANGLES
from .runner import Pipeline

logger = logging.getLogger(__name__)

__all__ = ["output_path", "run_file", "RunOptions", "BatchRunner"]


def output_path(src: Path, outdir: Path, ext: str | None) -> Path:
    """``OUTDIR/<stem><ext>`` (ext defaults to the input's extension)."""
    ext = ext or src.suffix
    if not ext.startswith("."):
        ext = "." + ext
    return Path(outdir) / (src.stem + ext.lower())


@dataclass
class RunOptions:
    """How a pipeline runs on each file (picklable, passed to worker processes).

    Attributes
    ----------
    ext : str or None
        Output format of the automatic save (default: the input's).
    force : bool
        Replace existing files (``--force``; nothing else can grant it).
    dry_run : bool
        Check everything (:meth:`Pipeline.check`), write nothing.
    inputs : list of str
        All inputs of the batch (a pipeline may read these).
    allow_read : list of str
        Further files or folders a pipeline may read (``--allow-read``).
    max_triangles : int
        Size budget (``--max-triangles``).
    allow_inverted : bool
        Write meshes a MeshLab step left with inverted triangles (warning only).
    """

    ext: str | None = None
    force: bool = False
    dry_run: bool = False
    inputs: list[str] = field(default_factory=list)
    allow_read: list[str] = field(default_factory=list)
    max_triangles: int = DEFAULT_MAX_TRIANGLES
    allow_inverted: bool = False


def _document(src: Path, outdir, options: RunOptions, index: int) -> Document:
    doc = Document()
    doc.output_dir = None if outdir is None else Path(outdir)
    doc.overwrite = options.force
    doc.dry_run = options.dry_run
    doc.variables = {"stem": src.stem, "input_dir": str(src.parent), "suffix": src.suffix,
                     "ext": src.suffix.lstrip("."), "index": str(index)}
    doc.inputs = [Path(p) for p in options.inputs] or [src]
    doc.allow_read = [Path(p) for p in options.allow_read]
    doc.max_triangles = options.max_triangles
    doc.allow_inverted = options.allow_inverted
    return doc


def run_file(pipeline: Pipeline | dict, src, outdir, *, ext: str | None = None,
             force: bool = False, dry_run: bool = False, options: RunOptions | None = None,
             index: int = 1, source: str | None = None) -> dict:
    """Load ``src``, run ``pipeline``, save the current mesh into ``outdir``.

    The automatic save is skipped when the pipeline has its own ``save_mesh`` step. In a
    dry run nothing is written and no filter runs: the input is loaded and
    :meth:`Pipeline.check` checks parameters, paths, existing outputs and the size budget
    (``outdir`` may then be None: existing outputs are not looked for).

    Parameters
    ----------
    options : RunOptions, optional
        Everything else; ``ext``, ``force`` and ``dry_run`` are shortcuts for it.
    index : int
        Position of ``src`` in the batch, from 1 (the ``{index}`` template field).
    source : str, optional
        The pipeline's file name for messages when ``pipeline`` is a dict.

    Returns
    -------
    dict
        ``{"input", "status": "ok"|"failed", "outputs", "results", "warnings", "error",
        "seconds"}``.
    """
    from ..io import load, save

    if options is None:
        options = RunOptions(ext=ext, force=force, dry_run=dry_run)
    t0 = time.perf_counter()
    src = Path(src)
    record: dict = {"input": str(src), "status": "ok", "outputs": [], "results": [],
                    "warnings": [], "error": None}
    doc = None
    try:
        if isinstance(pipeline, dict):
            pipeline = Pipeline.from_dict(pipeline, source)
        pipeline.validate()
        doc = _document(src, outdir, options, index)
        doc.add(load(src), name=src.stem)
        own_save = any(s.name == "save_mesh" for s in pipeline.steps)
        dst = None if own_save or outdir is None else output_path(src, outdir, options.ext)
        if options.dry_run:
            pipeline.check(doc)
            if dst is not None and dst.exists() and not options.force:
                raise MeshoptError(f"{dst}: already exists (use --force to overwrite)")
            record["outputs"] = [] if dst is None else [str(dst)]
        else:
            pipeline.run(doc)
            record["results"] = doc.results
            record["outputs"] = list(doc.written)
            if dst is not None:
                save(doc.mesh, dst, overwrite=options.force)
                record["outputs"].append(str(dst))
    except MeshoptError as exc:
        record.update(status="failed", error=str(exc))
    except OSError as exc:  # a file system refusal the layers below did not name
        name = exc.filename or src
        record.update(status="failed", error=f"{name}: {exc.strerror or exc}")
    except Exception as exc:  # a bug or a library failure: still per file
        logger.debug("unexpected error on %s", src, exc_info=True)
        record.update(status="failed", error=f"{src}: internal error: {type(exc).__name__}: {exc}")
    if doc is not None:
        record["warnings"] = list(doc.warnings)
    record["seconds"] = time.perf_counter() - t0
    return record


def _child_init() -> None:  # pragma: no cover - runs in the worker
    logging.basicConfig(level=logging.WARNING)


class BatchRunner:
    """Run a pipeline over files, optionally each in a worker process.

    Parameters
    ----------
    pipeline : Pipeline
    outdir : path or None
        None only in a dry run.
    isolate : bool
        Run files in a child process (one reused worker; recreated after a crash).
    ext, force, dry_run :
        As in :func:`run_file`.
    options : RunOptions, optional
        Everything at once (then ``ext``, ``force``, ``dry_run`` are ignored).
    """

    def __init__(self, pipeline: Pipeline, outdir, *, isolate: bool = False,
                 ext: str | None = None, force: bool = False, dry_run: bool = False,
                 options: RunOptions | None = None) -> None:
        self.pipeline = pipeline
        self.outdir = None if outdir is None else Path(outdir)
        self.isolate = isolate
        self.options = options or RunOptions(ext=ext, force=force, dry_run=dry_run)
        self._pool: ProcessPoolExecutor | None = None

    def _executor(self) -> ProcessPoolExecutor:
        if self._pool is None:
            import multiprocessing

            self._pool = ProcessPoolExecutor(max_workers=1, initializer=_child_init,
                                             mp_context=multiprocessing.get_context("spawn"))
        return self._pool

    def run_one(self, src, index: int = 1) -> dict:
        if not self.isolate:
            return run_file(self.pipeline, src, self.outdir, options=self.options, index=index)
        t0 = time.perf_counter()
        data = self.pipeline.to_dict()
        outdir = None if self.outdir is None else str(self.outdir)
        try:
            return self._executor().submit(run_file, data, str(src), outdir,
                                           options=self.options, index=index,
                                           source=self.pipeline.source).result()
        except BrokenProcessPool:
            self.close()
            return {"input": str(src), "status": "failed", "outputs": [], "results": [],
                    "warnings": [],
                    "error": f"{src}: the worker process crashed (a native MeshLab filter "
                             "aborted?); other files go on",
                    "seconds": time.perf_counter() - t0}

    def run(self, sources, callback: Callable[[dict], None] | None = None) -> list[dict]:
        records = []
        try:
            for index, src in enumerate(sources, start=1):
                rec = self.run_one(src, index)
                records.append(rec)
                if callback is not None:
                    callback(rec)
        finally:
            self.close()
        return records

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
