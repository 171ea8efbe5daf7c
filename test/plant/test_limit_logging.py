"""Limits exceeded in a run: one line per criterion at WARN or ERROR, the rest at debug."""
from __future__ import annotations

import dataclasses

from plant_helpers import SPEED_KMH, FakeClock, Log, short_train
from ltd_brake_ros.inputs.consist import VehicleLimits
from ltd_brake_ros.plant.runner import PlantRunner
from ltd_brake_ros.plant.settings import PlantSettings
from ltd_brake_ros.simulator import Event, Simulator


def test_each_criterion_is_logged_once_per_run_and_the_rest_at_debug():
    c = short_train()
    # every coupler weaker than any draft the stop makes, every body weaker than any buff
    weak = VehicleLimits(draft_strength_N=1.0, buff_strength_N=1.0)
    c = dataclasses.replace(c, vehicles=tuple(dataclasses.replace(v, limits=weak)
                                              for v in c.vehicles))
    clock, log = FakeClock(), Log()
    runner = PlantRunner(Simulator(c, SPEED_KMH), PlantSettings(
        real_time_factor=0.0, chunk_s=0.1, auto_brake_at_s=0.0, shutdown_after_stop_s=0.5),
        publish_state=lambda snap: None, publish_status=lambda status: None,
        input_handled=lambda *a: None, log=log, recorder=None, labels={}, clock=clock.clock())
    runner.begin()
    while not runner.finished.is_set():
        runner.poll()
    about_limits = [(lvl, text) for lvl, text in log.lines if "beyond its" in text]
    loud = [(lvl, text) for lvl, text in about_limits if lvl != "debug"]
    # forces beyond strength are errors, one per criterion; every other coupler at debug
    assert sorted(lvl for lvl, _ in loud) == ["error", "error"]
    assert {t.split("beyond its ")[1].split(" limit")[0] for _, t in loud} == \
        {"draft strength", "buff strength"}
    # each coupler beyond a limit once per criterion, as the verdicts table names them
    table = runner.sim.verdicts()
    named = len(table["draft_strength"].exceedances) + len(table["buff_strength"].exceedances)
    assert len(about_limits) == named > 2
    assert all("/diagnostics" in t for _, t in loud)


def test_a_demand_just_over_its_limit_does_not_read_as_equal():
    e = Event(1.0, "limit_exceeded", {"criterion": "adhesion_at_speed", "vehicle": 3,
                                      "demand": 0.150004, "limit": 0.15, "speed_kmh": 60.0})
    assert "demand 0.15000, limit 0.150" in e.describe() or "0.150004" in e.describe()
    assert "demand 0.150," not in e.describe()
