"""How many cores this process may use: one owner for the batch runner's ``-j 0`` and for
the threads of the motion package."""

from __future__ import annotations

import os


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity; at least 1)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # pragma: no cover - not Linux
        return max(os.cpu_count() or 1, 1)


def thread_budget() -> int:
    """Threads a computation in this process may start: :func:`available_cores`, capped by
    ``OMP_NUM_THREADS`` when it is set (a batch worker of ``meshopt run -j N`` sets it to 1,
    so N workers do not oversubscribe the cores)."""
    cap = os.environ.get("OMP_NUM_THREADS", "")
    cores = available_cores()
    return min(cores, int(cap)) if cap.isdigit() and int(cap) > 0 else cores
