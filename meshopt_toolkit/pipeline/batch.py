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
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Callable

from ..errors import MeshoptError
from .document import Document
from .runner import Pipeline

logger = logging.getLogger(__name__)

__all__ = ["output_path", "run_file", "BatchRunner"]


def output_path(src: Path, outdir: Path, ext: str | None) -> Path:
    """``OUTDIR/<stem><ext>`` (ext defaults to the input's extension)."""
    ext = ext or src.suffix
    if not ext.startswith("."):
        ext = "." + ext
    return Path(outdir) / (src.stem + ext.lower())


def run_file(pipeline: Pipeline | dict, src, outdir, *, ext: str | None = None,
             force: bool = False, dry_run: bool = False) -> dict:
    """Load ``src``, run ``pipeline``, save the current mesh into ``outdir``.

    The automatic save is skipped when the pipeline has its own ``save_mesh`` step. Nothing
    is written in a dry run (the pipeline is validated, the input loaded, the outputs
    checked).

    Returns
    -------
    dict
        ``{"input", "status": "ok"|"failed", "outputs", "results", "error", "seconds"}``.
    """
    from ..io import load, save

    t0 = time.perf_counter()
    src = Path(src)
    record: dict = {"input": str(src), "status": "ok", "outputs": [], "results": [], "error": None}
    try:
        if isinstance(pipeline, dict):
            pipeline = Pipeline.from_dict(pipeline)
        pipeline.validate()
        doc = Document()
        doc.output_dir = Path(outdir)
        doc.overwrite = force
        doc.dry_run = dry_run
        doc.variables = {"stem": src.stem, "input_dir": str(src.parent), "suffix": src.suffix}
        doc.add(load(src), name=src.stem)
        own_save = any(s.name == "save_mesh" for s in pipeline.steps)
        dst = None if own_save else output_path(src, outdir, ext)
        if dry_run:
            if dst is not None and dst.exists() and not force:
                raise MeshoptError(f"{dst}: already exists (use --force to overwrite)")
            record["outputs"] = [] if dst is None else [str(dst)]
        else:
            pipeline.run(doc)
            record["results"] = doc.results
            record["outputs"] = list(doc.written)
            if dst is not None:
                save(doc.mesh, dst, overwrite=force)
                record["outputs"].append(str(dst))
    except MeshoptError as exc:
        record.update(status="failed", error=str(exc))
    except Exception as exc:  # a bug or a library failure: still per file
        logger.debug("unexpected error on %s", src, exc_info=True)
        record.update(status="failed", error=f"{src}: internal error: {type(exc).__name__}: {exc}")
    record["seconds"] = time.perf_counter() - t0
    return record


def _child_init() -> None:  # pragma: no cover - runs in the worker
    logging.basicConfig(level=logging.WARNING)


class BatchRunner:
    """Run a pipeline over files, optionally each in a worker process.

    Parameters
    ----------
    pipeline : Pipeline
    outdir : path
    isolate : bool
        Run files in a child process (one reused worker; recreated after a crash).
    ext, force, dry_run :
        As in :func:`run_file`.
    """

    def __init__(self, pipeline: Pipeline, outdir, *, isolate: bool = False,
                 ext: str | None = None, force: bool = False, dry_run: bool = False) -> None:
        self.pipeline = pipeline
        self.outdir = Path(outdir)
        self.isolate = isolate
        self.kwargs = dict(ext=ext, force=force, dry_run=dry_run)
        self._pool: ProcessPoolExecutor | None = None

    def _executor(self) -> ProcessPoolExecutor:
        if self._pool is None:
            import multiprocessing

            self._pool = ProcessPoolExecutor(max_workers=1, initializer=_child_init,
                                             mp_context=multiprocessing.get_context("spawn"))
        return self._pool

    def run_one(self, src) -> dict:
        if not self.isolate:
            return run_file(self.pipeline, src, self.outdir, **self.kwargs)
        t0 = time.perf_counter()
        data = self.pipeline.to_dict()
        try:
            return self._executor().submit(run_file, data, str(src), str(self.outdir),
                                           **self.kwargs).result()
        except BrokenProcessPool:
            self.close()
            return {"input": str(src), "status": "failed", "outputs": [], "results": [],
                    "error": f"{src}: the worker process crashed (a native MeshLab filter "
                             "aborted?); other files go on",
                    "seconds": time.perf_counter() - t0}

    def run(self, sources, callback: Callable[[dict], None] | None = None) -> list[dict]:
        records = []
        try:
            for src in sources:
                rec = self.run_one(src)
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
