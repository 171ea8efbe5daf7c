"""Dask distributed: a LocalCluster of worker processes and a scheduler with two workers started
with the ``dask`` commands give the process pool's table; a worker killed mid-campaign loses
nothing and duplicates nothing."""
from __future__ import annotations

import signal

import pytest
from campaign_helpers import free_port, write_campaign
from conftest import executable

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import InputError
from ltd_brake_ros.inputs.campaign import load_campaign
from ltd_brake_ros.studies.campaign_exec import (DaskExecutor, PoolExecutor, read_results,
                                                 run_campaign)

@pytest.fixture(scope="module")
def pool_table(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pool")
    path = write_campaign(folder, runs=24, batch=2)
    with PoolExecutor(2) as pool:
        run_campaign(load_campaign(path), folder / "out", pool)
    return path, read_results(folder / "out")[1]

def test_local_cluster_gives_the_pool_table(pool_table, tmp_path, capsys):
    path, table = pool_table
    assert main(["campaign", "run", str(path), "--out", str(tmp_path / "out"), "--dask",
                 "local:2", "--quiet"]) == 0
    assert "24 runs in 12 batches (0 failed)" in capsys.readouterr().out
    assert read_results(tmp_path / "out")[1].equals(table)

@pytest.fixture
def dask_cluster(processes):
    """``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1, killed at the end."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = executable("dask")
    processes.start(dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                    "--no-dashboard", name="scheduler")
    workers = [processes.start(dask, "worker", address, "--nthreads", "1", "--nworkers", "1",
                               "--host", "127.0.0.1", "--no-dashboard", name=f"worker{i}")
               for i in range(2)]
    return address, workers

def _connected(address: str):
    executor = DaskExecutor(address)
    executor.client.wait_for_workers(2, timeout=60)
    executor.workers = 2
    return executor

def test_scheduler_and_two_workers_give_the_pool_table(pool_table, dask_cluster, tmp_path):
    path, table = pool_table
    address, _ = dask_cluster
    with _connected(address) as executor:
        run_campaign(load_campaign(path), tmp_path / "out", executor)
        assert len(executor.client.scheduler_info()["workers"]) == 2
    assert read_results(tmp_path / "out")[1].equals(table)

def test_a_killed_worker_loses_and_duplicates_nothing(pool_table, dask_cluster, tmp_path):
    path, table = pool_table
    address, workers = dask_cluster
    killed = []

    def kill_after_first_batch(runs: int, failed: int) -> None:
        if not killed:
            workers[0].kill()  # SIGKILL of the worker and its nanny
            killed.append(True)

    with _connected(address) as executor:
        summary = run_campaign(load_campaign(path), tmp_path / "out", executor,
                               progress=kill_after_first_batch)
        assert len(executor.client.scheduler_info()["workers"]) == 1
    assert killed and summary["runs"] == 24
    done = read_results(tmp_path / "out")[1]
    assert done["run_id"].to_pylist() == list(range(24))
    assert done.equals(table)

def _worker_setup() -> tuple:
    """What a worker holds before any batch: its profiler setting, the kernel's loaded
    specialisations."""
    import dask

    from ltd_brake_ros.physics import kernel

    return (dask.config.get("distributed.worker.profile.enabled"),
            sum(len(loop.overloads) for loop in kernel._LOOPS.values()))


def test_local_cluster_workers_load_the_kernel_before_the_first_batch():
    with DaskExecutor("local:1") as executor:
        # no dashboard reads the profiler; the kernel loaded as the worker joined
        assert list(executor.client.run(_worker_setup).values()) == [(False, 1)]


def test_unreachable_scheduler_names_the_option():
    port = free_port()
    with pytest.raises(InputError, match=rf"^--dask: cannot connect to 127.0.0.1:{port} "
                                         r"within 1 s: Connection refused"):
        DaskExecutor(f"tcp://127.0.0.1:{port}", timeout_s=1.0)


@pytest.mark.parametrize("peer, words", [
    ("silent", "sent no Dask handshake within 1 s"),
    ("http", "does not speak the Dask protocol"),
    ("garbage", "answered, but not with a Dask handshake")])
def test_an_address_that_is_not_dask_is_one_line_within_its_bound(peer, words):
    import socket
    import threading
    import time

    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    kept = []

    def serve():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            kept.append(conn)
            if peer == "http":  # a web server's refusal, read as a length prefix
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n")
            elif peer == "garbage":  # a plausible length, then bytes that are not msgpack
                conn.sendall((16).to_bytes(8, "little") + b"\xc1" * 16)

    threading.Thread(target=serve, daemon=True).start()
    start = time.monotonic()
    try:
        with pytest.raises(InputError, match=rf"^--dask: 127.0.0.1:{port} {words}"):
            DaskExecutor(f"tcp://127.0.0.1:{port}", timeout_s=1.0)
    finally:
        server.close()
        for conn in kept:
            conn.close()
    assert time.monotonic() - start < 5.0


def test_bad_local_cluster_size_is_one_line(tmp_path, capsys):
    path = write_campaign(tmp_path)
    assert main(["campaign", "run", str(path), "--out", str(tmp_path / "out"), "--dask",
                 "local:zero"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "ltd-brake campaign: error: --dask: local:N needs a worker count >= 1, " \
                  "got 'local:zero'"
