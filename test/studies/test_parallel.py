"""The one process pool of the studies: same results as in this process, in job order."""
from __future__ import annotations

import os

from ltd_brake_ros.studies.parallel import default_workers, map_jobs, process_pool
from ltd_brake_ros.studies.runs import validate


def _pid_and_square(x):
    return os.getpid(), x * x


_STATE: dict = {}


def _remember(value):
    _STATE["value"] = value


def _recall(_):
    return _STATE.get("value")


def test_map_jobs_keeps_job_order_and_uses_other_processes():
    out = map_jobs(_pid_and_square, range(7), workers=2)
    assert [sq for _, sq in out] == [x * x for x in range(7)]
    assert os.getpid() not in {pid for pid, _ in out}
    # one worker, or a single job: in this process
    assert {pid for pid, _ in map_jobs(_pid_and_square, range(3), workers=1)} == {os.getpid()}
    assert map_jobs(_pid_and_square, [5], workers=4) == [(os.getpid(), 25)]


def test_pool_runs_the_initializer_in_each_worker():
    with process_pool(2, initializer=_remember, initargs=("set",)) as pool:
        assert list(pool.map(_recall, range(4))) == ["set"] * 4
    assert "value" not in _STATE  # only the workers were initialised


def test_default_workers_is_what_this_process_may_use():
    assert 1 <= default_workers() <= (os.cpu_count() or 1)


def test_validation_on_the_pool_is_bit_identical_to_one_process():
    serial = validate(scenarios=[7, 12], workers=1)
    pooled = validate(scenarios=[7, 12], workers=2)
    for a, b in zip(serial, pooled):
        ra, rb = a.result.as_dict(), b.result.as_dict()
        for volatile in ("wall_time_s", "real_time_factor"):
            ra.pop(volatile), rb.pop(volatile)
        assert ra == rb
