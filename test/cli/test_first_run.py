"""The first run after an install says that it compiles the kernels, and how long it took."""
from __future__ import annotations

import math

import pytest

from ltd_brake_ros.cli.main import main


def test_kernels_are_known_to_be_cached_after_a_run():
    from ltd_brake_ros import compiled, simulator
    from ltd_brake_ros.inputs import get_scenario

    sc = get_scenario(1)
    simulator.Simulator(sc.consist(), sc.speed_kmh).warm_up()
    assert compiled.kernels_cached() is True


@pytest.mark.parametrize("cached, says", [(False, True), (True, False), (None, False)])
def test_simulate_says_when_it_compiles(monkeypatch, capsys, cached, says):
    from ltd_brake_ros import compiled

    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: cached)
    assert main(["simulate", "--scenario", "1"]) == 0
    err = capsys.readouterr().err
    assert ("compiling the simulation kernels (first run only" in err) is says
    assert ("compiled the simulation kernels in" in err) is says


def test_the_python_api_says_when_it_compiles(monkeypatch, capsys):
    import ltd_brake_ros as ltd
    from ltd_brake_ros import compiled

    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: False)
    ltd.emergency_stop(ltd.load_consist("scenario_1"), 40.0)
    out = capsys.readouterr()
    assert "compiling the simulation kernels (first run only" in out.out + out.err


def test_an_empty_kernel_cache_is_known_as_such(tmp_path):
    """A fresh install's state: the import's stale-cache check leaves empty index files, which
    must not count as compiled kernels (no compiling here: only the check runs)."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    out = subprocess.run([sys.executable, "-c", "from ltd_brake_ros import compiled; "
                          "print(compiled.kernels_cached())"], env=env, capture_output=True,
                         text=True, timeout=120, check=True)
    assert out.stdout.strip() == "False", out.stderr


# ------------------------------------------------------------ plain Python while compiling

BRAKES = [None, "brake_params/uic.yaml", "brake_params/uic_brake_pipe.yaml"]


def _stop(params, plain_until_s=None, until_s=3.0, adhesion=None):
    """Scenario 6 under the emergency brake, in chunks of 0.5 s; with ``plain_until_s``, calls
    from Python run the kernels as plain Python until the run has reached that time [s]."""
    from ltd_brake_ros.inputs import get_scenario, load_brake_params
    from ltd_brake_ros.physics import equations
    from ltd_brake_ros.simulator import Commands, Simulator

    made = []
    if plain_until_s is not None:
        equations.run_plain_while(lambda: not made or made[0].time_s < plain_until_s)
    try:
        sim = Simulator(get_scenario(6).consist(), 100.0,
                        load_brake_params(params) if params else None, adhesion=adhesion)
        made.append(sim)
        snaps = [sim.advance(0.5, Commands(emergency=True))]
        while sim.time_s < until_s - 1e-9:
            snaps.append(sim.advance(0.5))
        return sim, snaps
    finally:
        equations.run_plain_while(None)


def _same(a, b):
    """Two runs' chunk ends and counters, to the last bit."""
    import numpy as np

    sim_a, snaps_a = a
    sim_b, snaps_b = b
    assert sim_a.stats == sim_b.stats
    assert len(snaps_a) == len(snaps_b)
    for x, y in zip(snaps_a, snaps_b):
        for field in ("speed_m_s", "coupler_force_N", "brake_force_N"):
            assert np.array_equal(getattr(x, field), getattr(y, field)), field
        assert [(e.time_s, e.kind) for e in x.events] == [(e.time_s, e.kind) for e in y.events]


@pytest.mark.parametrize("params", BRAKES, ids=["paper", "uic_empirical", "uic_brake_pipe"])
def test_plain_python_kernels_give_the_compiled_results_bit_for_bit(params):
    """A first run starts with the kernels as Python source while they compile elsewhere: the
    same IEEE arithmetic, so the same floats (an emergency stop's first 3 s, every brake
    model, wheel slide on a wet rail with the paper's)."""
    compiled = _stop(params)
    plain = _stop(params, plain_until_s=math.inf)
    assert compiled[0].plain_python_s == 0.0
    assert plain[0].plain_python_s == pytest.approx(3.0)
    _same(compiled, plain)
    if params is None:
        _same(_stop(None, adhesion="wet"), _stop(None, plain_until_s=math.inf, adhesion="wet"))


def test_a_run_goes_on_compiled_from_the_chunk_after_the_kernels_are_ready():
    """The predicate turns false part-way (the background compile ended): the chunks after
    run compiled, and the run is the one a compiled run gives."""
    compiled = _stop(None)
    mixed = _stop(None, plain_until_s=1.2)
    assert mixed[0].plain_python_s == pytest.approx(1.5)  # the chunks that began before 1.2 s
    _same(compiled, mixed)


def test_a_first_run_starts_at_once_and_leaves_the_kernels_compiled(tmp_path):
    """The user's first ``ltd-brake simulate``: an empty numba cache, the run in plain Python
    at once while a background process compiles, the same results; the next run loads the
    compiled kernels."""
    import json
    import os
    import subprocess

    from conftest import executable

    from ltd_brake_ros.first_run import wait_for_compile

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"),
               LTD_BRAKE_FIRST_RUN="background")
    argv = [executable("ltd-brake"), "simulate", "--scenario", "1", "--json"]
    first = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
    try:
        assert first.returncode == 0, first.stderr
        assert "compiling the simulation kernels in the background" in first.stderr
        assert "compiled the simulation kernels in" not in first.stderr
    finally:
        assert wait_for_compile(env["NUMBA_CACHE_DIR"], timeout_s=600.0), "still compiling"
    second = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
    assert second.returncode == 0, second.stderr
    assert "compiling" not in second.stderr, second.stderr
    a, b = json.loads(first.stdout), json.loads(second.stdout)
    assert a["plain_python_s"] > 0.0 and b["plain_python_s"] == 0.0
    for key in ("stopping_distance_m", "stop_time_s", "peak_draft_kN", "peak_buff_kN",
                "steps", "newton_iterations", "verdicts"):
        assert a[key] == b[key], key


@pytest.fixture
def background(monkeypatch, tmp_path):
    """Background compiles allowed, with a lock of the test's own; plain mode off after."""
    from ltd_brake_ros.physics import equations

    monkeypatch.setenv("LTD_BRAKE_FIRST_RUN", "background")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # only the lock's name: numba has read it
    yield
    equations.run_plain_while(None)


def _until_compiled(deadline_s=60.0):
    import time

    from ltd_brake_ros.physics.equations import plain_now

    deadline = time.monotonic() + deadline_s
    while plain_now():
        assert time.monotonic() < deadline, "still plain Python"
        time.sleep(0.05)


def test_a_failed_background_compile_is_said_and_the_run_compiles_here(background, monkeypatch):
    import shutil

    from ltd_brake_ros import first_run
    from ltd_brake_ros.inputs import get_scenario
    from ltd_brake_ros.physics.equations import plain_now

    monkeypatch.setattr(first_run.sys, "executable", shutil.which("false"))
    said = []
    started = first_run.start({"consist": get_scenario(1).consist(), "speed_kmh": 40.0},
                              said.append)
    assert started is not None and started.process is not None
    _until_compiled()
    assert not plain_now()
    assert len(said) == 1 and "the background compile failed (exit status 1" in said[0]
    assert said[0].endswith("compiling here")


def test_a_run_that_finds_a_compile_under_way_waits_for_it_in_plain_python(background):
    """A second first run while the first one's compile holds the lock starts no compile of
    its own: plain Python until the lock is free."""
    import fcntl
    import os

    from ltd_brake_ros import first_run
    from ltd_brake_ros.inputs import get_scenario
    from ltd_brake_ros.physics.equations import plain_now

    fd = os.open(first_run.lock_path(), os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        started = first_run.start({"consist": get_scenario(1).consist(), "speed_kmh": 40.0},
                                  print)
        assert started is not None and started.process is None
        assert plain_now()
    finally:
        os.close(fd)
    _until_compiled(deadline_s=10 * first_run.POLL_S + 5.0)


def test_waiting_for_the_compile_is_a_choice(monkeypatch):
    from ltd_brake_ros import first_run
    from ltd_brake_ros.inputs import get_scenario
    from ltd_brake_ros.physics.equations import plain_now

    monkeypatch.setenv("LTD_BRAKE_FIRST_RUN", "wait")
    assert first_run.start({"consist": get_scenario(1).consist(), "speed_kmh": 40.0},
                           print) is None
    assert not plain_now()


def test_plain_python_kernels_never_call_compiled_code():
    """Inside a plain-Python chunk every kernel function calls the plain version of the next
    (directly or through its module): none goes through a compiled function's entry, which
    would compile it here when the background compile ends mid-chunk. Only the simulator's
    own calls from Python ask whether plain Python still holds."""
    from ltd_brake_ros.inputs import get_scenario, load_brake_params
    from ltd_brake_ros.physics import equations
    from ltd_brake_ros.simulator import Commands, Simulator

    for params in BRAKES:
        asked = []
        equations.run_plain_while(lambda: asked.append(1) or True)
        try:
            sim = Simulator(get_scenario(6).consist(), 100.0,
                            load_brake_params(params) if params else None, adhesion="wet")
            sim.advance(0.5, Commands(emergency=True))
            before = len(asked)
            sim.advance(2.0)  # 200 steps, thousands of kernel calls
        finally:
            equations.run_plain_while(None)
        assert sim.plain_python_s == pytest.approx(2.5)
        assert len(asked) - before <= 5, params
