"""Running a pipeline (or a conversion) over many files: worker processes with per-file
isolation, resume after a crash, a Dask cluster.

- :func:`run_batch` (:mod:`.run`): the library entry (``mt.run_batch``); ``meshopt run``
  and ``meshopt convert`` go through :func:`~.run.execute`.
- :mod:`.tasks`: what a batch does to one file (:class:`~.tasks.RunTask`,
  :class:`~.tasks.ConvertTask`); :mod:`.file_job`: one file, errors reported per file
  (:func:`run_file`, :class:`RunOptions`).
- :mod:`.workers` (``-j N``), :mod:`.cluster` (``--scheduler``), :mod:`.journal`
  (``--resume``), :mod:`.progress` (the progress bar and summary).

This package sits above :mod:`meshopt_toolkit.pipeline`: it runs pipelines. Its names
are imported on first use, so that a worker process starts with :mod:`.workers` alone.
"""

from __future__ import annotations

import importlib

_WHERE = {"run_batch": "run", "execute": "run", "BatchResult": "run",
          "RunOptions": "file_job", "run_file": "file_job"}

__all__ = list(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
