"""Campaign execution: executors, the Parquet results folder, its manifest, resuming.

A results folder holds ``manifest.json``, a copy of the campaign file and ``batches/``, one
Parquet file per batch of runs, each written under a temporary name and renamed when complete:
a batch file is there entirely or not at all, so re-running the same command after an
interruption runs only the batches that are missing.

Executors share one small interface (:class:`Executor`): ``map_batches(campaign, batches)``
yields ``(batch, table)`` as batches complete, in any order. The process pool is the studies'
one (:mod:`.parallel`); Dask distributed spreads batches over a cluster.
"""
from __future__ import annotations

import json
import os
import shutil
from concurrent.futures import FIRST_COMPLETED, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Callable, Iterable, Iterator

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from ..inputs import InputError
from ..inputs.campaign import Campaign
from ..simulator import SimulationError
from .campaign import run_batch, schema_of, warm_up
from .parallel import default_workers, process_pool

__all__ = ["DaskExecutor", "Executor", "PoolExecutor", "SerialExecutor", "make_executor",
           "missing_batches", "read_results", "run_campaign"]

#: Times a batch is resubmitted after its worker process died.
MAX_RETRIES = 3
#: Dask settings of a cluster started here (``local:N``): without a dashboard nothing reads the
#: workers' statistical profiler (a stack sample of the running batch every 10 ms), and the
#: event loops' health checks (every 20 ms) and system monitors (every 0.5 s) may run
#: seldom; on few cores each of them takes turns from the batches.
LOCAL_CLUSTER_CONFIG = {"distributed.worker.profile.enabled": False,
                        "distributed.admin.tick.interval": "1s",
                        "distributed.admin.system-monitor.interval": "2s"}


class Executor:
    """Runs batches of a campaign somewhere; subclasses say where."""

    #: Processes that run batches at once.
    workers = 1

    def map_batches(self, c: Campaign, batches: Iterable[int]) -> Iterator[tuple[int, pa.Table]]:
        """Run ``batches`` of ``c``; yield ``(batch, table)`` as each completes."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the workers."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class SerialExecutor(Executor):
    """In this process, one batch after the other."""

    def map_batches(self, c, batches):
        for b in batches:
            yield b, run_batch(c, b)


class PoolExecutor(Executor):
    """The studies' process pool; a batch whose worker died is run again (up to 3 times).

    Parameters
    ----------
    workers : int
        Processes.
    """

    def __init__(self, workers: int):
        self.workers = max(1, int(workers))

    def map_batches(self, c, batches):
        pending = dict.fromkeys(batches)  # in order
        tries = 0
        while pending:
            with process_pool(self.workers) as pool:
                # at most 2 batches per worker in flight: results stream back, none pile up
                queue, running = list(pending), {}
                try:
                    while queue or running:
                        while queue and len(running) < 2 * self.workers:
                            b = queue.pop(0)
                            running[pool.submit(run_batch, c, b)] = b
                        done, _ = wait(running, return_when=FIRST_COMPLETED)
                        for fut in done:
                            b = running.pop(fut)
                            table = fut.result()
                            del pending[b]
                            yield b, table
                except BaseException as exc:
                    # interrupted (Ctrl-C) or a worker died: drop the batches not started
                    pool.shutdown(wait=False, cancel_futures=True)
                    if not isinstance(exc, BrokenProcessPool):
                        raise
                    tries += 1
                    if tries > MAX_RETRIES:
                        raise SimulationError(f"worker processes died {tries} times; "
                                              f"{len(pending)} batches not run") from None


class DaskExecutor(Executor):
    """Dask distributed: an existing scheduler (``tcp://host:port``) or ``local:N``.

    ``local:N`` starts a :class:`distributed.LocalCluster` of N single-threaded worker
    processes with :data:`LOCAL_CLUSTER_CONFIG`. Every worker, present or joining later, loads
    the compiled kernel as it joins (so starting counts that). Dask reschedules the batches of
    a worker that is lost.

    Parameters
    ----------
    address : str
    timeout_s : float, optional
        How long to try to reach a scheduler [s].
    """

    def __init__(self, address: str, timeout_s: float = 30.0):
        import dask
        from distributed import Client, LocalCluster

        self.cluster = None
        if address.startswith("local:"):
            try:
                n = int(address[6:])
            except ValueError:
                n = 0
            if n < 1:
                raise InputError("--dask", "", f"local:N needs a worker count >= 1, got {address!r}")
            with dask.config.set(LOCAL_CLUSTER_CONFIG):  # the workers take it as they start
                self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                            dashboard_address=None)
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(address, timeout=timeout_s)
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError("--dask", "", f"cannot reach the Dask scheduler at {address}: "
                                 f"{exc}") from None
        # every worker, present or joining later, loads the kernel before its first batch
        self.client.register_worker_callbacks(setup=warm_up)
        self.workers = max(1, sum(w.get("nthreads", 1) for w in
                                  self.client.scheduler_info()["workers"].values()))

    def map_batches(self, c, batches):
        from distributed import as_completed

        [shared] = self.client.scatter([c], broadcast=True, hash=False)
        futures = {self.client.submit(run_batch, shared, b, pure=False, retries=MAX_RETRIES): b
                   for b in batches}
        for fut in as_completed(futures):
            b = futures.pop(fut)
            yield b, fut.result()
            fut.release()

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_executor(jobs: int | None = None, dask: str | None = None) -> Executor:
    """The executor a command line asks for.

    Parameters
    ----------
    jobs : int, optional
        Processes of the local pool (default: every core); 1 runs in this process.
    dask : str, optional
        ``tcp://host:port`` of a scheduler or ``local:N``; overrides ``jobs``.

    Returns
    -------
    Executor
    """
    if dask:
        return DaskExecutor(dask)
    jobs = default_workers() if jobs is None else jobs
    return SerialExecutor() if jobs <= 1 else PoolExecutor(jobs)


def _batch_path(out: Path, b: int) -> Path:
    return out / "batches" / f"batch-{b:07d}.parquet"


def _package_version() -> str:
    from .. import __version__

    return __version__


def _prepare(c: Campaign, out: Path) -> None:
    """Create the results folder, or check that it holds this campaign."""
    manifest = out / "manifest.json"
    if manifest.exists():
        try:
            old = json.loads(manifest.read_text())
        except (OSError, ValueError) as exc:
            raise InputError(manifest, "", f"cannot read: {exc}") from None
        for key in ("digest", "seed", "runs", "batch_size"):
            if old.get(key) != getattr(c, key):
                raise InputError(out, "", f"holds results of another campaign ({key} "
                                 f"{old.get(key)!r}, this campaign {getattr(c, key)!r}); "
                                 "choose another --out")
        return
    (out / "batches").mkdir(parents=True, exist_ok=True)
    if c.document is not None:  # built from a mapping: the folder keeps the document
        import yaml

        (out / "campaign.yaml").write_text(yaml.safe_dump(c.document, sort_keys=False))
    else:
        shutil.copyfile(c.source, out / "campaign.yaml")
    data = {"name": c.name, "campaign_file": str(Path(c.source).resolve()),
            "digest": c.digest, "seed": c.seed, "runs": c.runs, "batch_size": c.batch_size,
            "sampling": c.sampling, "manoeuvres": [m.name for m in c.manoeuvres],
            "package_version": _package_version(),
            "columns": schema_of(c).names}
    tmp = manifest.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    os.replace(tmp, manifest)


def missing_batches(c: Campaign, out: str | os.PathLike) -> list[int]:
    """Batches of ``c`` without a complete file in ``out``.

    Parameters
    ----------
    c : Campaign
    out : path-like

    Returns
    -------
    list of int
    """
    out = Path(out)
    return [b for b in range(c.batches) if not _batch_path(out, b).exists()]


def _write(out: Path, b: int, table: pa.Table) -> None:
    path = _batch_path(out, b)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    pq.write_table(table, tmp)
    os.replace(tmp, path)


def run_campaign(c: Campaign, out: str | os.PathLike, executor: Executor | None = None, *,
                 progress: Callable[[int, int], None] | None = None) -> dict:
    """Run every missing batch of a campaign into a results folder.

    Parameters
    ----------
    c : Campaign
    out : path-like
        Results folder (created; if it exists it must hold the same campaign).
    executor : Executor, optional
        Default: in this process.
    progress : callable, optional
        Called with (runs done, of which failed) after each batch written; a run is one
        train under one manoeuvre.

    Returns
    -------
    dict
        ``batches`` run now, ``runs`` run now, ``failed`` among them, ``skipped`` batches
        already present.
    """
    out = Path(out)
    _prepare(c, out)
    for stale in (out / "batches").glob(".batch-*.tmp"):
        stale.unlink(missing_ok=True)
    todo = missing_batches(c, out)
    executor = executor or SerialExecutor()
    runs = failed = 0
    for b, table in executor.map_batches(c, todo):
        _write(out, b, table)
        n_failed = int(pc.sum(pc.not_equal(table["status"], "ok")).as_py() or 0)
        runs += table.num_rows
        failed += n_failed
        if progress:
            progress(table.num_rows, n_failed)
    return {"batches": len(todo), "runs": runs, "failed": failed,
            "skipped": c.batches - len(todo)}


def read_results(out: str | os.PathLike) -> tuple[dict, pa.Table]:
    """The manifest and every row of a results folder, sorted by run id and manoeuvre.

    Parameters
    ----------
    out : path-like

    Returns
    -------
    manifest : dict
    table : pyarrow.Table

    Raises
    ------
    InputError
        ``out`` is not a campaign results folder.
    """
    out = Path(out)
    manifest = out / "manifest.json"
    if not manifest.is_file():
        raise InputError(out, "", "is not a campaign results folder (no manifest.json)")
    try:
        meta = json.loads(manifest.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(manifest, "", f"cannot read: {exc}") from None
    files = sorted((out / "batches").glob("batch-*.parquet"))
    if not files:
        raise InputError(out, "", "holds no results yet: run ltd-brake campaign run first")
    table = pa.concat_tables(pq.read_table(f) for f in files)
    order = {name: i for i, name in enumerate(meta.get("manoeuvres", []))}
    rank = pa.array([order.get(m, len(order)) for m in table["manoeuvre"].to_pylist()])
    table = table.append_column("_rank", rank)
    return meta, table.sort_by([("run_id", "ascending"), ("_rank", "ascending")]).drop(["_rank"])
