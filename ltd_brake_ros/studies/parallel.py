"""The one process pool of the offline studies: many independent runs spread over the cores.

Each emergency stop is single-threaded compiled code that holds the GIL between kernel calls,
so independent runs scale with processes, not threads. The numba on-disk cache makes a worker's
first run as cheap as the parent's.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Iterable, Sequence

__all__ = ["default_workers", "process_pool", "map_jobs", "terminate_pool"]

#: How often a worker checks that the process that started it is alive [s].
PARENT_POLL_S = 0.5


def default_workers() -> int:
    """Cores this process may use.

    Returns
    -------
    int
        The CPU affinity of this process where the platform reports it (a container or
        ``taskset`` may allow fewer cores than the machine has), else the machine's count.
    """
    from ..user_files import usable_cores

    return usable_cores()


def _orphan_guard(parent: int) -> None:
    """Make this worker exit when ``parent`` does, even if it was killed (SIGKILL)."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG: the kernel tells us at once
        except (OSError, AttributeError):
            pass

    def watch() -> None:  # everywhere, and for parents that were threads
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _worker_start(parent: int, initializer: Callable | None, initargs: tuple) -> None:
    _orphan_guard(parent)
    if initializer is not None:
        initializer(*initargs)


def terminate_pool(pool: ProcessPoolExecutor) -> None:
    """Stop a pool now: queued tasks are dropped and running workers are terminated.

    Parameters
    ----------
    pool : concurrent.futures.ProcessPoolExecutor
    """
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        try:
            p.terminate()
        except (OSError, ValueError, AttributeError):
            pass
    for p in procs:
        try:
            p.join(timeout=5.0)
        except (OSError, ValueError, AttributeError, AssertionError):
            pass


def process_pool(workers: int, *, initializer: Callable | None = None,
                 initargs: tuple = ()) -> ProcessPoolExecutor:
    """A pool of ``workers`` processes; the caller shuts it down (use it as a context manager).

    Each worker exits when this process ends, however it ends (on Linux at once, elsewhere
    within :data:`PARENT_POLL_S`).

    Parameters
    ----------
    workers : int
        Processes, at least 1.
    initializer : callable, optional
        Run once in each worker with ``initargs``: state that every task needs (trains,
        coupler table) is sent once per worker instead of once per task.
    initargs : tuple, optional

    Returns
    -------
    concurrent.futures.ProcessPoolExecutor
    """
    return ProcessPoolExecutor(max_workers=max(1, int(workers)), initializer=_worker_start,
                               initargs=(os.getpid(), initializer, initargs))


def map_jobs(fn: Callable, jobs: Iterable, workers: int = 1) -> list:
    """``[fn(job) for job in jobs]``, on a process pool when that can help.

    Parameters
    ----------
    fn : callable
        A module-level function (it is pickled by name).
    jobs : iterable
        Picklable arguments, one call each.
    workers : int, optional
        Processes; 1, or a single job, runs in this process.

    Returns
    -------
    list
        The results in the order of ``jobs``.
    """
    jobs: Sequence = list(jobs)
    if workers > 1 and len(jobs) > 1:
        with process_pool(workers) as pool:
            try:
                return list(pool.map(fn, jobs))
            except BaseException:
                terminate_pool(pool)
                raise
    return [fn(job) for job in jobs]
