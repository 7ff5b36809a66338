"""Threads over a path's frames: one pool for the process (frames are independent; the
results never depend on whether they ran in threads)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor

from ...cores import thread_budget

_LOCK = threading.Lock()  # guards the frame pool

_POOL: list[ThreadPoolExecutor] = []  # one pool for the process, made on first use


def frame_pool() -> ThreadPoolExecutor | None:
    """Threads for the frames (:class:`.FrameBlocks`' factors and solves, the path's
    assembly and products), one per core this process may use (None on one). Its tasks
    never submit tasks to it (no deadlock)."""
    with _LOCK:
        if not _POOL:
            cores = thread_budget()
            _POOL.append(ThreadPoolExecutor(cores) if cores > 1 else None)
        return _POOL[0]


#: paths with at least this many triangles assemble their frames in threads (numpy's
#: per-triangle kernels release the GIL; below this the threads' overhead outweighs the
#: work)
PARALLEL_ASSEMBLY_FROM = 5_000


def _pool_for(n_triangles: int, n_frames: int) -> ThreadPoolExecutor | None:
    """The frame pool for a path of several frames and ``PARALLEL_ASSEMBLY_FROM``
    triangles or more, else None."""
    return frame_pool() if n_triangles >= PARALLEL_ASSEMBLY_FROM and n_frames > 1 else None


def frame_map(n_triangles: int, n_frames: int) -> Callable:
    """``map`` over frames: in the frame pool's threads for large paths (the results do
    not depend on it: each frame's terms are computed alone and combined in order)."""
    pool = _pool_for(n_triangles, n_frames)
    return map if pool is None else pool.map


def frame_submit(n_triangles: int, n_frames: int) -> Callable[..., Future]:
    """``submit(fn, *args)`` for one frame's work: to the frame pool under the rule of
    :func:`frame_map`, else run at once (a completed future)."""
    pool = _pool_for(n_triangles, n_frames)
    if pool is not None:
        return pool.submit

    def run_now(fn: Callable, *args) -> Future:
        future: Future = Future()
        future.set_result(fn(*args))
        return future

    return run_now
