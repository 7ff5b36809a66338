"""Running a pipeline (or a conversion) over many files: worker processes with per-file
isolation, resume after a crash, a Dask cluster.

- :func:`run_batch` (:mod:`.run`): the library entry (``mt.run_batch``); ``meshopt run``
  and ``meshopt convert`` go through :func:`~.run.execute`.
- :mod:`.tasks`: what a batch does to one file (:class:`~.tasks.RunTask`,
  :class:`~.tasks.ConvertTask`); :mod:`.file_job`: one file, errors reported per file
  (:func:`run_file`, :class:`RunOptions`).
- :mod:`.workers` (``-j N``), :mod:`.cluster` (``--scheduler``), :mod:`.journal`
  (``--resume``), :mod:`.progress` (the progress bar and summary).

This package sits above :mod:`meshopt_toolkit.pipeline`: it runs pipelines.
"""

from __future__ import annotations

from .file_job import RunOptions, run_file
from .run import BatchResult, execute, run_batch

__all__ = ["run_batch", "execute", "BatchResult", "RunOptions", "run_file"]
