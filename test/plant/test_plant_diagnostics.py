"""Diagnostics values: the pace window and the report after a real emergency stop."""
from __future__ import annotations

import pytest

from plant_helpers import make_plant
from ltd_brake_ros.plant.diagnostics import OK, PaceWindow

KEYS = ["state", "sim_time_s", "real_time_factor", "achieved_real_time_factor", "chunks",
        "chunk_overruns", "schedule_dropped_s", "schedule_lag_s", "peak_schedule_lag_s",
        "emergency_command", "brake_command_time_s", "head_speed_kmh",
        "peak_draft_kN", "peak_draft_coupler", "peak_buff_kN", "peak_buff_coupler",
        "couplers_beyond_lut", "brake_demand", "traction_command", "overcharge_command",
        "rejected_inputs",
        "inputs_handled", "resets", "recording", "verdicts", "verdict_draft_strength",
        "verdict_buff_strength", "verdict_endurable_lcf", "verdict_buffer_limit_state",
        "verdict_coupler_travel", "verdict_adhesion", "verdict_adhesion_demand",
        "verdict_standstill_holding", "verdict_runaway", "verdict_wheel_temperature",
        "run_verdicts", "model_validity", "phase", "stops"]


def test_pace_window_measures_simulated_over_wall_time_since_the_last_report():
    window = PaceWindow(10.0)
    assert window.take(12.0, 1.0, 3) == (0.5, 3, 2.0)
    assert window.take(13.0, 4.0, 3) == (3.0, 0, 1.0)
    assert window.take(13.0, 4.0, 5) == (0.0, 2, 0.0)  # an empty window: no pace to speak of
    window.restart(20.0)  # a reset: simulated time is 0 again, the overrun count goes on
    assert window.take(21.0, 0.5, 6) == (0.5, 1, 1.0)


def test_pace_window_keeps_the_largest_lag_until_taken():
    window = PaceWindow(10.0)
    assert window.take_peak_lag() == 0.0
    for lag_s in (0.03, 0.12, 0.01):
        window.lag(lag_s)
    assert window.take_peak_lag() == 0.12
    assert window.take_peak_lag() == 0.0  # the next window starts without lag


def test_report_after_an_emergency_stop_shows_the_stop_and_the_peak_coupler_forces():
    plant = make_plant(real_time_factor=0.0, chunk_s=0.1, auto_brake_at_s=0.0,
                       shutdown_after_stop_s=0.5)
    runner = plant.runner
    while not runner.finished.is_set():
        runner.poll()
    plant.clock.t += 1.0
    runner.poll()
    status = plant.statuses[-1][1]
    values, sim = status.values, runner.sim
    assert list(values) == KEYS + ["stop", "stopping_distance_m", "stop_time_s"]
    # an ordinary stop is within every limit: no warning; the adhesion design check is the
    # wagons' own stop from their maximum speed, whatever the run's
    assert (status.level, status.message, values["state"]) == \
        (OK, "shutdown_after_stop_s reached", "finished")
    assert values["verdicts"] == "PASS" and values["verdict_adhesion"] == "PASS"
    assert values["verdict_draft_strength"] == values["verdict_buff_strength"] == "PASS"
    assert values["stop"].startswith("stop 1: emergency at t = 0.00 s")
    peaks = sim.coupler_peaks()
    # the one peak summary, in kN; a braking train pulls its couplers and pushes some
    assert (values["peak_draft_kN"], values["peak_draft_coupler"]) == \
        (f"{peaks.draft_N / 1e3:.3f}", str(peaks.draft_coupler))
    assert (values["peak_buff_kN"], values["peak_buff_coupler"]) == \
        (f"{peaks.buff_N / 1e3:.3f}", str(peaks.buff_coupler))
    assert peaks.draft_N > 0.0 > peaks.buff_N and 1 <= peaks.draft_coupler <= 2
    assert values["stopping_distance_m"] == f"{sim.stopping_distance_m:.3f}"
    assert values["stop_time_s"] == f"{sim.stop_time_s:.3f}"  # the command came at t = 0
    assert values["brake_command_time_s"] == "0.000" and values["emergency_command"] == "true"
    assert abs(float(values["head_speed_kmh"])) < 0.01
    assert values["chunks"] == str(runner.stats.chunks) == str(round(sim.time_s / 0.1))
    assert values["sim_time_s"] == f"{sim.time_s:.3f}"
    assert (values["recording"], values["couplers_beyond_lut"]) == ("off", "0")
    assert values["inputs_handled"] == "1" and values["rejected_inputs"] == "0"


@pytest.mark.parametrize("settings, state", [({"lockstep": True}, "lockstep"),
                                             ({"real_time_factor": 1.0}, "running")])
def test_report_names_the_mode(settings, state):
    plant = make_plant(**settings)
    plant.run_until(plant.clock.t + 1.01)
    status = plant.statuses[-1][1]
    assert status.values["state"] == status.message == state
    assert "stopping_distance_m" not in status.values
    assert plant.request(plant.runner.pause(True))[0]
    plant.run_until(plant.clock.t + 1.01)
    assert plant.statuses[-1][1].values["state"] == ("lockstep" if settings.get("lockstep")
                                                     else "paused")


def test_stop_and_go_gives_two_stops_and_the_diagnostics_return_to_ok_after_the_drive_off():
    plant = make_plant(lockstep=True, chunk_s=0.1, steps_per_call=10)
    runner = plant.runner

    def step_until(done, limit_s=200.0):
        while not done() and runner.sim.time_s < limit_s:
            assert plant.request(runner.step())[0]

    def status():
        runner._report(plant.clock.t)
        return plant.statuses[-1][1]
    plant.request(runner.receive("brake_demand", 0.6))
    step_until(lambda: runner.sim.settled_time_s is not None)
    assert status().values["stops"] == "1" and status().level == OK
    # release with traction: a drive-off, no holding failure while the train moves
    plant.request(runner.receive("brake_demand", 0.0))
    plant.request(runner.receive("traction", 1.0))
    step_until(lambda: runner.sim.time_s > 60.0)
    moving = status()
    assert float(moving.values["head_speed_kmh"]) > 5.0
    assert moving.level == OK and moving.values["verdicts"] == "PASS"
    assert moving.values["verdict_standstill_holding"] == "not assessed"
    assert moving.values["phase"] == "moving"
    # an emergency stop later: a second record with its own distance
    plant.request(runner.receive("traction", 0.0))
    plant.request(runner.receive("emergency", True))
    step_until(lambda: runner.sim.settled_time_s is not None)
    first, second = runner.sim.stops
    assert (first.command, second.command) == ("service", "emergency")
    assert first.end == "drive-off" and second.end == "open"
    assert first.stopping_distance_m > 0.0 and second.stopping_distance_m > 0.0
    assert first.verdicts.status == second.verdicts.status == "PASS"
    done = status()
    assert done.values["stops"] == "2" and done.level == OK
    assert done.values["stopping_distance_m"] == f"{second.stopping_distance_m:.3f}"
