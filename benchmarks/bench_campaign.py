"""Throughput of statistical campaigns: serial loop, process pool and Dask on the same runs.

The shipped example campaign (emergency stops of randomised E402B + 20-40 Shimmns trains from
80-100 km/h) is run three times over the same runs, each into its own Parquet folder: in this
process, on the process pool and on a Dask ``LocalCluster`` with as many single-threaded worker
processes. Printed: runs/s of each, the pool's parallel efficiency against the serial loop
(serial time / (workers x pool time)), Dask against the pool (with and without the time of
starting and stopping the cluster, said separately), that the three tables are
identical, and the driver's resident memory before and during the pool's run (streamed to
Parquet batch by batch, it does not grow with the number of runs).

Usage::

    python benchmarks/bench_campaign.py                 # 2000 runs, every core
    python benchmarks/bench_campaign.py --runs 10000    # the full-size figure
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import re  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import threading  # noqa: E402
from pathlib import Path  # noqa: E402

from ltd_brake_ros.inputs import config_dir  # noqa: E402
from ltd_brake_ros.inputs.campaign import load_campaign  # noqa: E402
from ltd_brake_ros.studies.campaign_exec import (DaskExecutor, PoolExecutor,  # noqa: E402
                                                 SerialExecutor, read_results, run_campaign)
from ltd_brake_ros.studies.parallel import default_workers  # noqa: E402


def _rss_mib() -> float:
    """Resident size of this process [MiB]."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def _timed(c, out: Path, make) -> tuple[float, float, float]:
    """Wall time of starting the executor (``make()``), of the campaign with it and of
    stopping it [s]; their sum is the command's wall time."""
    start = time.perf_counter()
    executor = make()
    started = time.perf_counter()
    with executor:
        summary = run_campaign(c, out, executor)
        ran = time.perf_counter()
    stopped = time.perf_counter()
    assert summary["runs"] == c.runs, summary
    return started - start, ran - started, stopped - ran


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=2000)
    parser.add_argument("--workers", type=int, default=default_workers())
    parser.add_argument("--batch-size", type=int, default=50)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        text = (config_dir() / "campaigns" / "example.yaml").read_text()
        text = re.sub(r"(?m)^runs: .*$", f"runs: {args.runs}", text)
        text = re.sub(r"(?m)^batch_size: .*$", f"batch_size: {args.batch_size}", text)
        (tmp / "bench.yaml").write_text(text)
        c = load_campaign(tmp / "bench.yaml")
        SerialExecutor().map_batches(c, [0]).__next__()  # compile / load the kernel cache
        cpu = time.process_time()
        serial = sum(_timed(c, tmp / "serial", SerialExecutor))
        cpu = time.process_time() - cpu
        rss0, peak = _rss_mib(), [0.0]
        done = threading.Event()

        def sample() -> None:  # the driver's resident size while the pool runs
            while not done.wait(0.05):
                peak[0] = max(peak[0], _rss_mib())

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        pool_start, pool_run, pool_stop = _timed(c, tmp / "pool",
                                                 lambda: PoolExecutor(args.workers))
        pool = pool_start + pool_run + pool_stop
        done.set()
        sampler.join()
        dask_start, dask_run, dask_stop = _timed(c, tmp / "dask",
                                                 lambda: DaskExecutor(f"local:{args.workers}"))
        dask = dask_start + dask_run + dask_stop
        tables = [read_results(tmp / k)[1] for k in ("serial", "pool", "dask")]
        identical = tables[0].equals(tables[1]) and tables[0].equals(tables[2])
        failed = sum(s != "ok" for s in tables[0]["status"].to_pylist())
    n, w = args.runs, args.workers
    print(f"| {n} emergency stops, E402B + 20-40 Shimmns, 80-100 km/h, batches of "
          f"{args.batch_size} | wall s | runs/s |")
    print("|---|---|---|")
    print(f"| serial loop (1 process) | {serial:.1f} | {n / serial:.1f} |")
    print(f"| process pool ({w} workers) | {pool:.1f} | {n / pool:.1f} |")
    print(f"| Dask LocalCluster ({w} workers, incl. its start and stop) | {dask:.1f} | "
          f"{n / dask:.1f} |")
    print()
    print(f"parallel efficiency of the pool: {100 * serial / (w * pool):.0f} % "
          f"(serial {serial / n * 1e3:.1f} ms/run wall, {cpu / n * 1e3:.1f} ms/run CPU: a busy "
          f"machine shows as wall above CPU)")
    print(f"Dask against the pool: {100 * (dask / pool - 1):+.0f} % wall time; "
          f"{100 * (dask_run / pool - 1):+.0f} % without the {dask_start:.1f} s of starting "
          f"and the {dask_stop:.1f} s of stopping the cluster (the pool's figure includes its "
          f"{pool_start + pool_stop:.1f} s of start and stop; Parquet writing is in every "
          "figure)")
    print(f"tables identical (serial, pool, Dask): {identical}; failed runs: {failed}")
    print(f"driver resident memory: {rss0:.0f} MiB before the pool, at most {peak[0]:.0f} MiB "
          f"while it ran")


if __name__ == "__main__":
    main()
