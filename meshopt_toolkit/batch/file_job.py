"""Running a pipeline on one file of a batch, with errors reported per file.

:func:`run_file` runs one input (load → pipeline → save) and returns a JSON-able record;
errors become ``status="failed"`` records instead of exceptions. Running it over many
files — in worker processes, on a Dask cluster, resumable — is :mod:`.run`
(:func:`~.run.run_batch`).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import MeshoptError
from ..pipeline.document import Document
from ..pipeline.limits import DEFAULT_MAX_TRIANGLES
from ..pipeline.runner import Pipeline
from .workers import RESTART_KEY

logger = logging.getLogger(__name__)

__all__ = ["output_path", "run_file", "RunOptions", "kept_warnings"]

#: the logger whose warnings a file's record keeps (the library's)
LIBRARY_LOGGER = "meshopt_toolkit"
_quiet_lock = threading.Lock()
_quiet_count = 0


class _Lines(logging.Handler):
    """The warnings this thread logs, as plain one-line messages."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.lines: list[str] = []
        self._thread = threading.get_ident()

    def emit(self, record: logging.LogRecord) -> None:
        if record.thread == self._thread:
            self.lines.append(" ".join(record.getMessage().split()))


@contextlib.contextmanager
def kept_warnings() -> Iterator[list[str]]:
    """The library's log warnings while the block runs (in this thread), as the plain
    lines of a list instead of log lines on stderr: a batch puts them in the file's
    record, whose paths in the scratch folder the driver turns into the outputs'."""
    global _quiet_count
    handler = _Lines()
    log = logging.getLogger(LIBRARY_LOGGER)
    with _quiet_lock:
        _quiet_count += 1
        log.propagate = False  # not also printed "WARNING:...:" by the root logger
        log.addHandler(handler)
    try:
        yield handler.lines
    finally:
        with _quiet_lock:
            log.removeHandler(handler)
            _quiet_count -= 1
            if not _quiet_count:
                log.propagate = True


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
        "seconds"}``; ``"warnings"``: one plain line each, the pipeline's and those the
        library logs meanwhile (:func:`kept_warnings`).
    """
    if options is None:
        options = RunOptions(ext=ext, force=force, dry_run=dry_run)
    t0 = time.perf_counter()
    src = Path(src)
    record = new_record(src)
    with kept_warnings() as logged:  # the library's warnings, in the record
        _run_into(record, pipeline, src, outdir, options, index, source)
    record["warnings"] += logged
    record["seconds"] = time.perf_counter() - t0
    return record


def new_record(src: Path) -> dict:
    """The record of one input before its work: ``status`` ok, nothing written yet."""
    return {"input": str(src), "status": "ok", "outputs": [], "results": [], "warnings": [],
            "error": None}


@contextlib.contextmanager
def failures_recorded(record: dict, src: Path) -> Iterator[None]:
    """Turn an error of the work on ``src`` into ``status="failed"`` and one ``error`` line
    naming the file in ``record``, so the batch goes on with the next file."""
    try:
        yield
    except MeshoptError as exc:
        record.update(status="failed", error=str(exc))
    except OSError as exc:  # a file system refusal the layers below did not name
        record.update(status="failed", error=f"{exc.filename or src}: {exc.strerror or exc}")
    except MemoryError:  # this file only; the worker process is then replaced
        record.update(status="failed", error=f"{src}: out of memory (MemoryError)")
        record[RESTART_KEY] = True
    except Exception as exc:  # a bug or a library failure: still per file
        logger.debug("unexpected error on %s", src, exc_info=True)
        record.update(status="failed", error=f"{src}: internal error: {type(exc).__name__}: {exc}")


def _run_into(record: dict, pipeline, src: Path, outdir, options: RunOptions, index: int,
              source: str | None) -> None:
    """:func:`run_file`'s work: ``record`` filled in, errors included."""
    from ..pipeline.document import load_entry, save_entry

    doc = None
    with failures_recorded(record, src):
        if isinstance(pipeline, dict):
            pipeline = Pipeline.from_dict(pipeline, source)
        pipeline.validate()
        doc = _document(src, outdir, options, index)
        doc.add(load_entry(src))  # with every block, tag and datum of the file
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
                save_entry(doc.current_entry, dst, overwrite=options.force)
                record["outputs"].append(str(dst))
    if doc is not None:
        record["warnings"] = list(doc.warnings)
