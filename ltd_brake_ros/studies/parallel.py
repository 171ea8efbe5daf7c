"""The one process pool of the offline studies: many independent runs spread over the cores.

Each emergency stop is single-threaded compiled code that holds the GIL between kernel calls,
so independent runs scale with processes, not threads. The numba on-disk cache makes a worker's
first run as cheap as the parent's.
"""
from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Iterable, Sequence

__all__ = ["default_workers", "process_pool", "map_jobs"]


def default_workers() -> int:
    """Cores this process may use.

    Returns
    -------
    int
        The CPU affinity of this process where the platform reports it (a container or
        ``taskset`` may allow fewer cores than the machine has), else the machine's count.
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def process_pool(workers: int, *, initializer: Callable | None = None,
                 initargs: tuple = ()) -> ProcessPoolExecutor:
    """A pool of ``workers`` processes; the caller shuts it down (use it as a context manager).

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
    return ProcessPoolExecutor(max_workers=max(1, int(workers)), initializer=initializer,
                               initargs=initargs)


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
            return list(pool.map(fn, jobs))
    return [fn(job) for job in jobs]
