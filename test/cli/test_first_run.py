"""The first run after an install says that it compiles the kernels, and how long it took."""
from __future__ import annotations

import pytest

from ltd_brake_ros.cli.main import main


def test_kernels_are_known_to_be_cached_after_a_run():
    from ltd_brake_ros import simulator
    from ltd_brake_ros.inputs import get_scenario

    sc = get_scenario(1)
    simulator.Simulator(sc.consist(), sc.speed_kmh).warm_up()
    assert simulator.kernels_cached() is True


@pytest.mark.parametrize("cached, says", [(False, True), (True, False), (None, False)])
def test_simulate_says_when_it_compiles(monkeypatch, capsys, cached, says):
    from ltd_brake_ros import simulator

    monkeypatch.setattr(simulator, "kernels_cached", lambda *a: cached)
    assert main(["simulate", "--scenario", "1"]) == 0
    err = capsys.readouterr().err
    assert ("compiling the simulation kernels (first run only" in err) is says
    assert ("compiled the simulation kernels in" in err) is says


def test_the_python_api_says_when_it_compiles(monkeypatch, capsys):
    import ltd_brake_ros as ltd
    from ltd_brake_ros import simulator

    monkeypatch.setattr(simulator, "kernels_cached", lambda *a: False)
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
    out = subprocess.run([sys.executable, "-c", "from ltd_brake_ros import simulator; "
                          "print(simulator.kernels_cached())"], env=env, capture_output=True,
                         text=True, timeout=120, check=True)
    assert out.stdout.strip() == "False", out.stderr
