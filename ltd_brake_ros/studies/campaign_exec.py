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
from concurrent.futures import FIRST_COMPLETED, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Callable, Iterable, Iterator

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from ..inputs import InputError
from ..inputs.campaign import Campaign
from ..outputs import write_replacing
from ..simulator import SimulationError
from .campaign import run_batch, schema_of, warm_up
from .parallel import default_workers, process_pool, terminate_pool

__all__ = ["DaskExecutor", "Executor", "PoolExecutor", "SerialExecutor", "check_batches",
           "make_executor", "missing_batches", "prepare_folder", "probe_dask", "read_manifest",
           "read_results", "run_campaign"]

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
                    # interrupted (Ctrl-C, SIGTERM) or a worker died: stop every worker now
                    terminate_pool(pool)
                    if not isinstance(exc, BrokenProcessPool):
                        raise
                    tries += 1
                    if tries > MAX_RETRIES:
                        raise SimulationError(f"worker processes died {tries} times; "
                                              f"{len(pending)} batches not run") from None


#: How long a Dask address has to connect and send its handshake [s].
PROBE_TIMEOUT_S = 10.0
#: Largest handshake a Dask scheduler sends (a few hundred bytes in practice) [bytes].
_MAX_HANDSHAKE = 1 << 16


def probe_dask(address: str, timeout_s: float = PROBE_TIMEOUT_S,
               connect_timeout_s: float = 0.0) -> None:
    """Check that ``tcp://host:port`` is a Dask scheduler, within ``timeout_s``.

    A Dask listener sends its handshake (a length-prefixed message holding its compression
    and pickle settings) as soon as it accepts a connection; anything else at the address (a
    web server, a silent port) is told apart without waiting on the Dask client, which can
    wait forever for a peer that never answers. Addresses of other schemes are not probed.

    Parameters
    ----------
    address : str
    timeout_s : float, optional
        Bound of the handshake, once connected [s].
    connect_timeout_s : float, optional
        How long a refused connection is tried again (a scheduler starting up) [s].

    Raises
    ------
    InputError
        One line: no connection, no answer in time, or not the Dask protocol.
    """
    import socket
    import struct
    import time

    rest = address[len("tcp://"):] if address.startswith("tcp://") else (
        address if "://" not in address else None)
    if rest is None:
        return
    host, _, port = rest.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    try:
        port_n = int(port)
    except ValueError:
        raise InputError("--dask", "", f"{address!r}: write tcp://host:port or local:N") from None

    def read(sock, n: int) -> bytes:
        data = b""
        while len(data) < n:
            left = end - time.monotonic()
            if left <= 0:
                raise TimeoutError
            sock.settimeout(left)
            chunk = sock.recv(n - len(data))
            if not chunk:
                raise ConnectionError("it closed the connection")
            data += chunk
        return data

    what = f"{host}:{port_n}"
    connect_end = time.monotonic() + connect_timeout_s
    while True:  # a scheduler starting up refuses connections for a moment: try again
        try:
            sock = socket.create_connection((host, port_n), timeout=timeout_s)
            break
        except ConnectionRefusedError as exc:
            if time.monotonic() >= connect_end:
                raise InputError("--dask", "", f"cannot connect to {what} within "
                                 f"{connect_timeout_s:g} s: {exc.strerror or exc}") from None
            time.sleep(0.1)
        except OSError as exc:
            raise InputError("--dask", "", f"cannot connect to {what}: "
                             f"{exc.strerror or exc}") from None
    end = time.monotonic() + timeout_s
    try:
        with sock:
            (size,) = struct.unpack("<Q", read(sock, 8))
            if not 0 < size <= _MAX_HANDSHAKE:
                raise ValueError(f"a first message of {size} bytes")
            body = read(sock, size)
    except TimeoutError:
        raise InputError("--dask", "", f"{what} sent no Dask handshake within {timeout_s:g} s: "
                         "not a Dask scheduler (or one too busy to answer)") from None
    except (ConnectionError, ValueError) as exc:
        raise InputError("--dask", "", f"{what} does not speak the Dask protocol ({exc}): "
                         "is it the scheduler's address (default port 8786)?") from None
    except OSError as exc:
        raise InputError("--dask", "", f"cannot connect to {what}: "
                         f"{exc.strerror or exc}") from None
    try:
        from distributed.protocol import loads
        from distributed.protocol.utils import unpack_frames

        msg = loads(unpack_frames(body))
    except Exception:  # noqa: BLE001 - any undecodable answer is a protocol mismatch
        msg = None
    if not isinstance(msg, dict) or "compression" not in msg:
        raise InputError("--dask", "", f"{what} answered, but not with a Dask handshake: is it "
                         "the scheduler's address (default port 8786)?")


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
            probe_dask(address, min(timeout_s, PROBE_TIMEOUT_S), connect_timeout_s=timeout_s)
            try:
                self.client = Client(address, timeout=timeout_s)
            except Exception as exc:  # noqa: BLE001 - any failure to connect is one line
                raise InputError("--dask", "", f"cannot reach the Dask scheduler at {address}: "
                                 f"{type(exc).__name__}: {exc}") from None
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


def _checksum_path(path: Path) -> Path:
    """The file beside a batch that holds its SHA-256 and row count."""
    return path.with_name(path.name + ".sha256")


def _package_version() -> str:
    from .._version import __version__

    return __version__


#: Keys of the manifest a resumed campaign must match, and what each means to a user.
_PINNED = {"digest": "campaign file", "seed": "seed", "runs": "runs",
           "batch_size": "batch_size", "package_version": "ltd_brake_ros version"}


def _manifest(c: Campaign) -> dict:
    return {"name": c.name, "campaign_file": str(Path(c.source).resolve()),
            "digest": c.digest, "seed": c.seed, "runs": c.runs, "batch_size": c.batch_size,
            "batches": c.batches, "sampling": c.sampling,
            "manoeuvres": [m.name for m in c.manoeuvres],
            "package_version": _package_version(), "inputs": dict(c.inputs),
            "columns": schema_of(c).names}


def read_manifest(out: str | os.PathLike) -> dict:
    """The manifest of a results folder, checked to be one.

    Parameters
    ----------
    out : path-like

    Returns
    -------
    dict

    Raises
    ------
    InputError
        No manifest, or one that cannot be read or lacks a field.
    """
    manifest = Path(out) / "manifest.json"
    if not manifest.is_file():
        raise InputError(out, "", "is not a campaign results folder (no manifest.json)")
    try:
        meta = json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(manifest, "", f"cannot read: {exc}") from None
    if not isinstance(meta, dict):
        raise InputError(manifest, "", "is not a campaign manifest (not a JSON object)")
    for key, kind in (("digest", str), ("runs", int), ("batch_size", int),
                      ("manoeuvres", list)):
        if not isinstance(meta.get(key), kind) or isinstance(meta.get(key), bool):
            raise InputError(manifest, key, "missing or damaged; the folder cannot be trusted, "
                             "run the campaign into a new --out")
    if meta["runs"] < 1 or meta["batch_size"] < 1 or not meta["manoeuvres"]:
        raise InputError(manifest, "runs", "damaged (no run, batch or manoeuvre); run the "
                         "campaign into a new --out")
    return meta


def _short(text) -> str:
    text = str(text)
    return text[:12] if len(text) == 64 else text


def prepare_folder(c: Campaign, out: str | os.PathLike, create: bool = True) -> None:
    """Create the results folder, or check that it holds this campaign made the same way.

    A folder is pinned to the campaign file, seed, size, the package version and the digest
    of every input file; a folder without a manifest is never adopted.

    Parameters
    ----------
    c : Campaign
    out : path-like
    create : bool, optional
        False: only check (nothing is created, so a command can check its folder before it
        starts workers).

    Raises
    ------
    InputError
        One line naming what differs.
    """
    out = Path(out)
    if (out / "manifest.json").exists():
        old, now = read_manifest(out), _manifest(c)
        for key, what in _PINNED.items():
            if old.get(key) != now[key]:
                raise InputError(out, "", f"holds results made with another {what} "
                                 f"({_short(old.get(key))!r}, now {_short(now[key])!r}); its "
                                 "runs would mix with these: choose a new --out")
        before = old.get("inputs")
        if not isinstance(before, dict):
            raise InputError(out, "", "its manifest lists no input files, so what made its "
                             "results cannot be checked: choose a new --out")
        for path in sorted(set(before) | set(c.inputs)):
            if before.get(path) != c.inputs.get(path):
                change = ("is no longer read" if path not in c.inputs else
                          "was not read before" if path not in before else
                          f"changed (sha256 {_short(before[path])}, now "
                          f"{_short(c.inputs[path])})")
                raise InputError(out, "", f"input file {path} {change} since its results were "
                                 "made; they would mix two models: choose a new --out (or "
                                 "restore the file)")
        return
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(out, "", "exists and is not a campaign results folder (no "
                         "manifest.json); it is never adopted: choose a new or empty --out")
    if not create:
        return
    (out / "batches").mkdir(parents=True, exist_ok=True)
    if c.document is not None:  # built from a mapping: the folder keeps the document
        import yaml

        _atomic_write(out / "campaign.yaml",
                      yaml.safe_dump(c.document, sort_keys=False).encode())
    else:
        write_replacing(out / "campaign.yaml", Path(c.source).read_bytes())
    _atomic_write(out / "manifest.json", (json.dumps(_manifest(c), indent=2) + "\n").encode())


def _atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` under a temporary name, flush it to disk, rename it into place."""
    write_replacing(path, data)


def _rows_of_batch(runs: int, batch_size: int, manoeuvres: int, b: int) -> int:
    return manoeuvres * max(0, min(batch_size, runs - b * batch_size))


def _check_batch(path: Path, digest: str, b: int, rows: int,
                 schema: pa.Schema | None = None) -> str:
    """Why the batch file at ``path`` cannot count as batch ``b`` ('' when it can)."""
    from ..inputs.campaign import file_digest

    check = _checksum_path(path)
    try:
        recorded = check.read_text(encoding="ascii").split()
    except (OSError, UnicodeDecodeError):
        return "has no checksum (it was not finished)"
    try:
        actual = file_digest(path)
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    if len(recorded) != 2 or recorded[0] != actual:
        return "does not match its checksum (damaged)"
    try:
        pf = pq.ParquetFile(path)
        meta = pf.schema_arrow.metadata or {}
        n = pf.metadata.num_rows
    except (OSError, pa.ArrowException) as exc:
        return f"is not a readable Parquet file ({exc})"
    if meta.get(b"ltd_brake_ros.campaign_digest", b"").decode() != digest:
        return "belongs to another campaign"
    if meta.get(b"ltd_brake_ros.batch", b"").decode() != str(b):
        return f"is not batch {b}"
    if n != rows or recorded[1] != str(rows):
        return f"holds {n} rows, batch {b} has {rows}"
    if schema is not None and not pf.schema_arrow.remove_metadata().equals(
            schema.remove_metadata()):
        return "has columns other than this campaign's"
    return ""


def check_batches(c: Campaign, out: str | os.PathLike) -> tuple[list[int], list[str]]:
    """Batches of ``c`` to run, and a note for each batch file present that does not count.

    A batch counts as done when its file matches its checksum, holds this campaign's rows of
    that batch and its columns; a file that does not is named in a note and run again.

    Parameters
    ----------
    c : Campaign
    out : path-like

    Returns
    -------
    todo : list of int
    notes : list of str
    """
    out = Path(out)
    todo, notes = [], []
    schema = schema_of(c)
    for b in range(c.batches):
        path = _batch_path(out, b)
        if not path.exists():
            todo.append(b)
            continue
        why = _check_batch(path, c.digest, b,
                           _rows_of_batch(c.runs, c.batch_size, len(c.manoeuvres), b), schema)
        if why:
            todo.append(b)
            notes.append(f"{path} {why}; batch {b} is run again")
    return todo, notes


def missing_batches(c: Campaign, out: str | os.PathLike) -> list[int]:
    """Batches of ``c`` without a complete, verified file in ``out``.

    Parameters
    ----------
    c : Campaign
    out : path-like

    Returns
    -------
    list of int
    """
    return check_batches(c, out)[0]


def _write(out: Path, c: Campaign, b: int, table: pa.Table) -> None:
    """Write batch ``b`` durably: data, then its checksum, each atomically."""
    import io

    from ..inputs.campaign import file_digest

    path = _batch_path(out, b)
    meta = dict(table.schema.metadata or {})
    meta.update({b"ltd_brake_ros.campaign_digest": c.digest.encode(),
                 b"ltd_brake_ros.batch": str(b).encode()})
    buf = io.BytesIO()
    pq.write_table(table.replace_schema_metadata(meta), buf)
    _checksum_path(path).unlink(missing_ok=True)
    _atomic_write(path, buf.getvalue())
    _atomic_write(_checksum_path(path), f"{file_digest(path)} {table.num_rows}\n".encode())


def run_campaign(c: Campaign, out: str | os.PathLike, executor: Executor | None = None, *,
                 progress: Callable[[int, int], None] | None = None,
                 note_fn: Callable[[str], None] | None = None) -> dict:
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
    note_fn : callable, optional
        Called with a line for each batch file present that does not count (damaged, foreign,
        unfinished) and is run again.

    Returns
    -------
    dict
        ``batches`` run now, ``runs`` run now, ``failed`` among them, ``skipped`` batches
        already present.
    """
    out = Path(out)
    prepare_folder(c, out)
    for stale in (out / "batches").glob(".batch-*.tmp"):
        stale.unlink(missing_ok=True)
    todo, notes = check_batches(c, out)
    for note in notes:
        if note_fn is not None:
            note_fn(note)
    executor = executor or SerialExecutor()
    runs = failed = 0
    for b, table in executor.map_batches(c, todo):
        _write(out, c, b, table)
        n_failed = int(pc.sum(pc.not_equal(table["status"], "ok")).as_py() or 0)
        runs += table.num_rows
        failed += n_failed
        if progress:
            progress(table.num_rows, n_failed)
    return {"batches": len(todo), "runs": runs, "failed": failed,
            "skipped": c.batches - len(todo), "redone": len(notes)}


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
    meta = read_manifest(out)
    files = sorted((out / "batches").glob("batch-*.parquet"))
    if not files:
        raise InputError(out, "", "holds no results yet: run ltd-brake campaign run first")
    batches = -(-meta["runs"] // meta["batch_size"])
    tables = []
    for f in files:
        try:
            b = int(f.name[len("batch-"):-len(".parquet")])
        except ValueError:
            b = -1
        if not 0 <= b < batches:
            raise InputError(f, "", f"is not a batch of this campaign (it has batches 0-"
                             f"{batches - 1}); remove it")
        why = _check_batch(f, meta["digest"], b, _rows_of_batch(
            meta["runs"], meta["batch_size"], len(meta["manoeuvres"]), b))
        if why:
            raise InputError(f, "", f"{why}: run the same ltd-brake campaign run command "
                             "again to redo it")
        tables.append(pq.read_table(f))
    try:
        table = pa.concat_tables(tables)
    except pa.ArrowException as exc:
        raise InputError(out, "", f"its batches do not share their columns ({exc})") from None
    order = {name: i for i, name in enumerate(meta.get("manoeuvres", []))}
    rank = pa.array([order.get(m, len(order)) for m in table["manoeuvre"].to_pylist()])
    table = table.append_column("_rank", rank)
    return meta, table.sort_by([("run_id", "ascending"), ("_rank", "ascending")]).drop(["_rank"])
