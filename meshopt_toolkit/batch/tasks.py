"""What a batch does to one file: run a pipeline (:class:`RunTask`) or convert one.

A task is a picklable callable, sent once to each worker process or Dask worker. It is
called with a payload ``(src, index, name, outdir)``: the input, its position in the
batch (from 1), the output's file name when the batch fixes it (None: the task's own
rule), and the folder to write into (the batch's scratch folder; the driver moves the
outputs into place). It returns a JSON-able record ``{"input", "status", "outputs",
"results", "warnings", "error", "seconds"}`` and never raises for a bad file.

:meth:`config` is what the journal hashes: every setting that changes an output.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Callable

from ..pipeline.runner import Pipeline
from .file_job import RunOptions, failures_recorded, new_record, output_path, run_file

__all__ = ["RunTask", "ConvertTask", "failed_record"]


def failed_record(src, error: str, seconds: float = 0.0) -> dict:
    """A record for a file that failed before or outside its task."""
    return {**new_record(src), "status": "failed", "error": error, "seconds": seconds}


class RunTask:
    """Run a pipeline on one file (:func:`~.file_job.run_file`).

    Parameters
    ----------
    pipeline : Pipeline
    options : RunOptions
    """

    def __init__(self, pipeline: Pipeline, options: RunOptions) -> None:
        self.pipeline = pipeline
        self.options = options
        self._data = pipeline.to_dict()

    def __getstate__(self) -> dict:  # workers rebuild the pipeline from its dict once
        return {"data": self._data, "source": self.pipeline.source, "options": self.options}

    def __setstate__(self, state: dict) -> None:
        self._data = state["data"]
        self.options = state["options"]
        self.pipeline = Pipeline.from_dict(state["data"], state["source"])

    #: size cap of an input (None: the default of mesh files)
    max_bytes = None

    @property
    def own_save(self) -> bool:
        return any(s.name == "save_mesh" for s in self.pipeline.steps)

    def config(self) -> dict:
        o = self.options
        return {"task": "run", "pipeline": self._data, "ext": o.ext,
                "max_triangles": o.max_triangles, "allow_inverted": o.allow_inverted}

    def output_name(self, src: Path) -> str | None:
        """The automatic save's file name (None when the pipeline saves by itself)."""
        return None if self.own_save else output_path(Path(src), Path("."), self.options.ext).name

    def with_options(self, **changes) -> "RunTask":
        """A copy with some :class:`RunOptions` fields changed."""
        fields = dict(vars(self.options), **changes)
        return RunTask(self.pipeline, RunOptions(**fields))

    def __call__(self, payload) -> dict:
        src, index, _name, outdir = payload
        return run_file(self.pipeline, src, outdir, options=self.options, index=index)


class ConvertTask:
    """Convert one file with ``func(src, dst, args)`` (``meshopt convert``'s per-file step).

    Parameters
    ----------
    func : callable
        A module-level function (picklable by reference); it writes ``dst`` and raises
        :class:`~meshopt_toolkit.errors.MeshoptError` for a bad file. A dict it returns
        becomes the record's ``results`` (its ``"warnings"`` list the record's warnings).
    args : argparse.Namespace
        Passed to ``func``; only its plain values are kept.
    ext : str
        The output extension (``.vtu``) when a payload names no file.
    """

    #: options that change how a batch runs, not what it writes
    RUN_CONTROL = frozenset({"inputs", "output", "force", "jobs", "resume", "scheduler",
                             "shared_inputs", "json", "debug", "verbose", "command",
                             "recursive", "max_file_size"})

    def __init__(self, func: Callable, args, ext: str | None = None) -> None:
        self.func = func
        plain = {k: v for k, v in vars(args).items()
                 if not k.startswith("_") and isinstance(v, (str, int, float, bool, type(None),
                                                               list, tuple))}
        self.args = argparse.Namespace(**plain)
        self.ext = ext

    @property
    def max_bytes(self) -> int | None:
        """Size cap of an input (``--max-file-size``; None: the default)."""
        return getattr(self.args, "max_file_size", None)

    def config(self) -> dict:
        opts = {k: v for k, v in vars(self.args).items() if k not in self.RUN_CONTROL}
        return {"task": "convert", "func": f"{self.func.__module__}.{self.func.__qualname__}",
                "ext": self.ext, "options": opts}

    def output_name(self, src: Path) -> str:
        return Path(src).stem + (self.ext or Path(src).suffix.lower())

    def __call__(self, payload) -> dict:
        src, _index, name, outdir = payload
        t0 = time.perf_counter()
        src = Path(src)
        dst = Path(outdir) / (name or self.output_name(src))
        record = new_record(src)
        with failures_recorded(record, src):
            dst.parent.mkdir(parents=True, exist_ok=True)
            info = self.func(src, dst, self.args)
            record["outputs"] = [str(dst)]
            if isinstance(info, dict):
                info = dict(info)
                record["warnings"] = list(info.pop("warnings", ()))
                record["results"] = [info]
        record["seconds"] = time.perf_counter() - t0
        return record
