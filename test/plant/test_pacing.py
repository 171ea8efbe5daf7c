"""Pacer: paced time against a fake wall clock (rate, pause, rebase, no pacing)."""
from __future__ import annotations

import math

import pytest

from ltd_brake_ros.plant.pacing import Pacer


@pytest.fixture
def wall():
    return [100.0]


def test_paced_time_runs_at_the_rate_and_due_times_invert_it(wall):
    pacer = Pacer(2.0, monotonic=lambda: wall[0])
    wall[0] = 101.5
    assert pacer.position() == pytest.approx(3.0)
    assert pacer.due_at(3.0) == pytest.approx(101.5)
    assert pacer.seconds_until(4.0) == pytest.approx(0.5)
    assert pacer.seconds_until(1.0) == 0.0  # already passed: due now, not negative
    pacer.rebase(10.0)  # 10 s of paced time at wall 101.5
    assert pacer.due_at(11.0) == pytest.approx(102.0)


def test_pause_freezes_paced_time_and_paused_wall_time_does_not_count(wall):
    pacer = Pacer(1.0, monotonic=lambda: wall[0])
    wall[0] = 101.0
    pacer.pause(True)
    wall[0] = 111.0
    assert pacer.paused and pacer.position() == pytest.approx(1.0)
    assert pacer.due_at(2.0) == math.inf and pacer.seconds_until(2.0) == math.inf
    pacer.pause(True)  # a second pause changes nothing
    pacer.pause(False)
    wall[0] = 111.5
    assert not pacer.paused and pacer.position() == pytest.approx(1.5)


def test_start_paused_and_rebase_while_paused(wall):
    pacer = Pacer(1.0, monotonic=lambda: wall[0], paused=True)
    wall[0] = 105.0
    pacer.rebase(7.0)  # the pause starts again here
    wall[0] = 109.0
    assert pacer.position() == pytest.approx(7.0)
    pacer.pause(False)
    wall[0] = 110.0
    assert pacer.position() == pytest.approx(8.0)


def test_rate_change_keeps_the_position_continuous_even_while_paused(wall):
    pacer = Pacer(2.0, monotonic=lambda: wall[0])
    wall[0] = 101.0
    pacer.set_rate(0.5)
    assert pacer.position() == pytest.approx(2.0)
    wall[0] = 103.0
    assert pacer.position() == pytest.approx(3.0)
    pacer.pause(True)
    wall[0] = 110.0
    pacer.set_rate(4.0)
    assert pacer.position() == pytest.approx(3.0)
    pacer.pause(False)
    wall[0] = 110.5
    assert pacer.position() == pytest.approx(5.0)
    with pytest.raises(ValueError, match="rate"):
        pacer.set_rate(-1.0)
    with pytest.raises(ValueError, match="rate"):
        Pacer(math.nan)


def test_rate_zero_makes_everything_due_at_once(wall):
    pacer = Pacer(0.0, monotonic=lambda: wall[0])
    assert pacer.due_at(1e9) == -math.inf
    assert pacer.seconds_until(1e9) == 0.0
