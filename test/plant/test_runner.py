"""PlantRunner on a fake clock: pacing, overruns, lock-step, pause/step/reset, inputs, policy.

The runner is polled the way its thread polls it, on a clock that moves only when the runner
waits (or a chunk costs time), so wall times are exact and the tests take milliseconds. The
simulator is the real one, on a three-vehicle train.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from plant_helpers import CostlySimulator, FakeClock, Log, make_plant
from ltd_brake_ros.plant.diagnostics import ERROR, OK, WARN
from ltd_brake_ros.plant.pacing import Clock
from ltd_brake_ros.plant.runner import YIELD_MAX_S, YIELD_POLL_S, PlantRunner
from ltd_brake_ros.plant.settings import PlantSettings
from ltd_brake_ros.simulator import Commands, SimulationError

CHUNK_NS = 20_000_000  # the default chunk, 0.02 s


def chunk_walls(plant):
    """Wall times of the chunks published after the initial state."""
    return [wall for wall, _ in plant.states[1:]]


# --------------------------------------------------------------------------- pacing


@pytest.mark.parametrize("rtf", [0.5, 1.0, 2.0, 10.0])
def test_free_running_chunks_are_published_at_their_deadlines(rtf):
    plant = make_plant(real_time_factor=rtf)
    start, period = plant.clock.t, 0.02 / rtf
    plant.run_until(start + 3.0 + period / 2)
    n = round(3.0 / period)
    assert chunk_walls(plant) == pytest.approx([start + k * period for k in range(1, n + 1)],
                                               abs=1e-9)
    assert plant.stamps_ns == [k * CHUNK_NS for k in range(n + 1)]
    stats = plant.runner.stats
    assert stats.chunks == n and stats.overruns == 0
    assert len(stats.lateness_s) == n and max(map(abs, stats.lateness_s)) < 1e-9
    # one report per wall second; each window after the first holds a second of chunks
    # (the chunk due at the window's edge may fall on either side: one chunk of slack)
    reports = [s for _, s in plant.statuses]
    assert len(reports) == 3
    for status in reports[1:]:
        achieved = float(status.values["achieved_real_time_factor"])
        assert achieved == pytest.approx(rtf, abs=0.02 * rtf + 1e-3)
        assert status.level == OK and status.message == "running"


def test_real_time_factor_zero_runs_chunks_back_to_back_without_waiting():
    plant = make_plant(real_time_factor=0.0)
    start = plant.clock.t
    timeouts = [plant.runner.poll() for _ in range(100)]
    assert timeouts == [0.0] * 100
    assert plant.runner.stats.chunks == 100 and plant.clock.t == start
    assert not plant.runner.stats.lateness_s  # no deadline, no lateness


def published_at(plant, wall_s):
    """Simulated time of the last state published at or before ``wall_s`` [ns]."""
    return max(stamp for (wall, _), stamp in zip(plant.states, plant.stamps_ns) if wall <= wall_s)


def test_a_chunk_late_within_the_budget_is_caught_up_and_the_pace_stays_exactly_one():
    # chunk 61 costs 50 ms of wall time (2.5 periods): 30 ms behind, within the 0.2 s default
    plant = make_plant(cost_s=lambda k: 0.05 if k == 60 else 0.0)
    start = plant.clock.t
    assert plant.runner.settings.max_catch_up_s == 0.2
    plant.run_until(start + 3.0 + 0.01)
    walls = chunk_walls(plant)
    late_done = start + 61 * 0.02 + 0.05  # due at 1.22 s, done at 1.27 s
    # the two chunks already due run at once (never before their deadline), then the
    # schedule goes on where it was: no chunk is dropped and none is early
    due = [start + k * 0.02 for k in range(1, len(walls) + 1)]
    assert walls[60:63] == pytest.approx([late_done] * 3, abs=1e-9)
    assert walls[:60] + walls[63:] == pytest.approx(due[:60] + due[63:], abs=1e-9)
    assert all(w >= d - 1e-9 for w, d in zip(walls, due))
    stats = plant.runner.stats
    assert (stats.overruns, stats.caught_up) == (0, 2)  # chunks 61 and 62 ended behind
    assert stats.max_lag_s == pytest.approx(0.03, abs=1e-9)  # 1.27 s - 1.24 s
    # simulated time over a wall window spanning the slow chunk: exactly its length
    assert published_at(plant, start + 2.51) - published_at(plant, start + 0.51) == \
        100 * CHUNK_NS
    reports = [s for _, s in plant.statuses]
    assert [r.values["achieved_real_time_factor"] for r in reports[1:]] == ["1.000"] * 2
    assert [(r.level, r.message) for r in reports] == [(OK, "running")] * 3
    assert [r.values["peak_schedule_lag_s"] for r in reports] == ["0.000", "0.030", "0.000"]
    assert all(r.values["chunk_overruns"] == "0" for r in reports)


def test_lag_of_slow_chunks_accumulates_and_an_overrun_rebases_once_beyond_the_budget():
    # 20 chunks of 30 ms (1.5 periods) from chunk 11 on: each adds 10 ms of lag
    plant = make_plant(cost_s=lambda k: 0.03 if 10 <= k < 30 else 0.0, max_catch_up_s=0.1)
    start = plant.clock.t
    plant.run_until(start + 2.0 + 0.01)
    stats = plant.runner.stats
    # the 11th slow chunk ends 110 ms behind: an overrun and a new schedule; the last nine
    # end at most 90 ms behind it, and four chunks at once take the lag from 90 ms to 10 ms:
    # 10 + 9 + 4 chunks ended behind and were caught up
    assert stats.overruns == 1 and stats.caught_up == 10 + 9 + 4
    assert stats.max_lag_s == pytest.approx(0.11, abs=1e-9)
    walls = chunk_walls(plant)
    rebased = start + 0.22 + 11 * 0.03  # the 11th slow chunk ended here
    assert walls[20] == pytest.approx(rebased, abs=1e-9)
    back = rebased + 9 * 0.03  # the last slow chunk ended here, 90 ms behind the new schedule
    assert walls.count(pytest.approx(back, abs=1e-9)) == 1 + 5  # it and five chunks at once
    # then on the new schedule again: chunk 14 after the rebase is due 10 ms after them
    after = [w for w in walls if w > back + 1e-9]
    assert after == pytest.approx([rebased + k * 0.02 for k in range(14, 14 + len(after))],
                                  abs=1e-9)
    status = plant.statuses[0][1]
    assert status.level == WARN and status.message == "1 chunk overrun(s) in the last 1.0 s"
    assert status.values["peak_schedule_lag_s"] == "0.110"
    # the overrun gave up its lag: 110 ms of simulated time behind the wall clock for good
    assert stats.dropped_s == pytest.approx(0.11, abs=1e-9)
    assert status.values["schedule_dropped_s"] == "0.110"


@pytest.mark.parametrize("budget_s, cost_s", [(0.0, 0.05), (0.2, 0.25)])
def test_a_chunk_late_beyond_the_budget_counts_one_overrun_and_rebases_without_a_burst(
        budget_s, cost_s):
    # chunk 11 ends cost_s - 20 ms after chunk 12 was due: more than the budget
    plant = make_plant(cost_s=lambda k: cost_s if k == 10 else 0.0, max_catch_up_s=budget_s)
    start = plant.clock.t
    plant.run_until(start + 0.5 + cost_s)
    walls = chunk_walls(plant)
    late_done = start + 11 * 0.02 + cost_s  # the 11th chunk was due at 0.22 s
    assert walls[:11] == pytest.approx([start + k * 0.02 for k in range(1, 11)] + [late_done])
    # the next chunk right away, then one period apart: no catching up
    assert walls[11:14] == pytest.approx([late_done, late_done + 0.02, late_done + 0.04])
    stats = plant.runner.stats
    assert (stats.overruns, stats.caught_up) == (1, 0)
    assert sorted(stats.lateness_s)[-1] == pytest.approx(cost_s)
    plant.run_until(start + 1.0 + 1e-6)
    status = plant.statuses[-1][1]
    assert status.level == WARN and status.message == "1 chunk overrun(s) in the last 1.0 s"
    assert status.values["chunk_overruns"] == "1"
    assert status.values["peak_schedule_lag_s"] == f"{cost_s - 0.02:.3f}"
    assert status.values["schedule_dropped_s"] == f"{cost_s - 0.02:.3f}"
    # what the plant published: simulated time behind the wall by the lag it gave up, plus
    # at most one chunk of a schedule that is early until the next chunk is due
    behind = (plant.clock.t - start) - plant.stamps_ns[-1] / 1e9
    assert cost_s - 0.02 <= behind <= cost_s - 0.02 + 0.02 + 1e-9, behind


def test_diagnostics_report_the_lag_while_the_plant_catches_up():
    # chunk 49 ends 85 ms after its deadline, past the first report's time: that report
    # comes before the chunks due meanwhile run, and says how far behind the plant is
    plant = make_plant(cost_s=lambda k: 0.105 if k == 48 else 0.0)
    start = plant.clock.t
    plant.run_until(start + 1.2)
    (wall, status), = plant.statuses
    assert wall == pytest.approx(start + 0.98 + 0.105)
    assert status.values["schedule_lag_s"] == "0.085"  # behind chunk 50, due at 1.00 s
    assert status.values["peak_schedule_lag_s"] == "0.085"
    assert (status.level, status.values["chunk_overruns"]) == (OK, "0")
    assert status.values["schedule_dropped_s"] == "0.000"  # caught up: nothing given up
    assert plant.stamps_ns[-1] == round((1.2 - 1e-9) // 0.02) * CHUNK_NS  # caught up


def test_changing_the_real_time_factor_restarts_the_schedule_from_now():
    plant = make_plant(real_time_factor=1.0)
    start = plant.clock.t
    plant.run_until(start + 0.1 + 0.01)
    assert plant.request(plant.runner.set_real_time_factor(4.0)) is None
    assert plant.log.at("info")[-1] == "real_time_factor set to 4"
    changed = plant.clock.t
    plant.run_until(changed + 0.0225)
    assert chunk_walls(plant)[5:] == pytest.approx([changed + 0.005 * k for k in range(1, 5)])


def test_a_receiving_thread_steps_aside_only_while_a_chunk_is_due():
    plant = make_plant(real_time_factor=1.0)
    clock, runner = plant.clock, plant.runner
    runner.yield_to_plant()  # the next chunk is 20 ms away
    assert clock.t == 1000.0
    clock.t = 1000.0 + 0.02 - 0.001  # within the lead time: wait, but not for ever
    runner.yield_to_plant()
    assert clock.t - (1000.0 + 0.019) == pytest.approx(YIELD_MAX_S, abs=YIELD_POLL_S)
    for idle in (make_plant(real_time_factor=0.0), make_plant(lockstep=True)):
        t = idle.clock.t
        idle.runner.yield_to_plant()
        assert idle.clock.t == t


# --------------------------------------------------------------------------- lock-step


def lockstep_run(wall_between_calls):
    plant = make_plant(lockstep=True, steps_per_call=5, auto_brake_at_s=0.05)
    plant.run_until(plant.clock.t + 10.0)
    assert len(plant.states) == 1, "a lock-step plant advanced without being asked"
    replies = []
    for call in range(20):
        ok, text = plant.request(plant.runner.step())
        assert ok, text
        replies.append(text)
        assert len(plant.states) == 1 + 5 * (call + 1)
        plant.run_until(plant.clock.t + wall_between_calls(call))
        assert len(plant.states) == 1 + 5 * (call + 1)
    return plant, replies


def snapshot_arrays(states):
    return [np.concatenate([s.position_m, s.speed_m_s, s.brake_force_N, s.coupler_force_N])
            for _, s in states]


def test_lockstep_advances_exactly_the_chunks_asked_for_and_repeats_bit_for_bit():
    a, replies = lockstep_run(lambda call: 0.0)
    b, _ = lockstep_run(lambda call: 0.37 * (call % 3))  # other wall times between calls
    assert replies[0] == ("advanced 5 chunk(s) to t = 0.100 s with emergency=true "
                          "brake_demand=0.0 traction=0.0 overcharge=false (inputs handled: 1)")
    assert a.stamps_ns == b.stamps_ns == [k * CHUNK_NS for k in range(101)]
    for x, y in zip(snapshot_arrays(a.states), snapshot_arrays(b.states)):
        assert np.array_equal(x, y)
    # a reset restores the initial state bit for bit, and the run after it is the same run
    ok, text = a.request(a.runner.reset())
    assert ok and text == "reset to the initial state (brake released, t = 0 s)"
    assert np.array_equal(snapshot_arrays(a.states[-1:])[0], snapshot_arrays(a.states[:1])[0])
    first = snapshot_arrays(a.states[:101])
    for _ in range(20):
        assert a.request(a.runner.step())[0]
    again = snapshot_arrays(a.states[101:])
    assert len(again) == 101 and all(np.array_equal(x, y) for x, y in zip(first, again))
    assert [i[:3] for i in a.inputs] == [(60_000_000, "emergency", True)] * 2


def test_pause_stops_the_plant_step_advances_it_and_resume_restarts_the_schedule():
    plant = make_plant(real_time_factor=1.0, steps_per_call=3)
    runner, start = plant.runner, plant.clock.t
    plant.run_until(start + 0.09)
    assert plant.stamps_ns[-1] == 4 * CHUNK_NS
    ok, text = plant.request(runner.step())
    assert not ok and "free-running" in text and len(plant.states) == 5  # refused, not queued
    assert plant.request(runner.pause(True)) == (True, "paused at t = 0.080 s")
    plant.run_until(plant.clock.t + 5.0)
    assert len(plant.states) == 5
    ok, text = plant.request(runner.step())
    assert ok and text.startswith("advanced 3 chunk(s) to t = 0.140 s")
    assert plant.request(runner.pause(False)) == (True, "running at t = 0.140 s")
    resumed = plant.clock.t
    plant.run_until(resumed + 0.05)
    assert chunk_walls(plant)[7:] == pytest.approx([resumed + 0.02, resumed + 0.04])
    lockstep = make_plant(lockstep=True)
    assert lockstep.request(lockstep.runner.pause(False))[1] == \
        "running at t = 0.000 s (lock-step mode: the plant advances only on ~/step)"


def test_a_paused_lock_step_plant_refuses_steps_until_resumed():
    plant = make_plant(lockstep=True, steps_per_call=2)
    runner = plant.runner
    assert plant.request(runner.step())[1].startswith("advanced 2 chunk(s) to t = 0.040 s")
    assert plant.request(runner.pause(True)) == \
        (True, "paused at t = 0.040 s (lock-step mode: ~/step is refused until ~/pause false)")
    published = len(plant.states)
    for _ in range(3):  # a controller keeps stepping: the plant holds
        ok, text = plant.request(runner.step())
        assert not ok and text.startswith("paused at t = 0.040 s")
    assert len(plant.states) == published and runner.sim.time_s == pytest.approx(0.04)
    assert plant.request(runner.pause(False))[0]
    assert plant.request(runner.step())[1].startswith("advanced 2 chunk(s) to t = 0.080 s")


# --------------------------------------------------------------------------- run policy


# summed chunks of 0.02 s reach 0.1 s as 0.09999999999999999 s: a boundary all the same
@pytest.mark.parametrize("at_s, boundary_ns", [(0.05, 60_000_000), (0.06, 60_000_000),
                                                (0.1, 100_000_000), (0.0, 0)])
def test_auto_brake_is_an_input_at_the_first_chunk_boundary_at_or_after_its_time(at_s,
                                                                                 boundary_ns):
    plant = make_plant(real_time_factor=0.0, auto_brake_at_s=at_s)
    plant.polls(10)
    assert plant.inputs == [(boundary_ns, "emergency", True, None)]
    assert plant.runner.commands == Commands(emergency=True) and plant.runner.handled == 1
    applied = [e for _, s in plant.states for e in s.events if e.kind == "brake_applied"]
    assert [round(e.time_s * 1e9) for e in applied] == [boundary_ns]
    # once per run: again after a reset
    plant.request(plant.runner.reset())
    plant.polls(10)
    assert plant.inputs[1:] == [(boundary_ns, "emergency", True, None)]


def test_max_sim_time_finishes_after_exactly_its_chunks():
    plant = make_plant(real_time_factor=0.0, max_sim_time_s=0.5)
    plant.polls(40)
    runner = plant.runner
    assert runner.stats.chunks == 25 and plant.stamps_ns[-1] == 500_000_000
    assert runner.finished.is_set() and runner.finish_reason == "max_sim_time_s reached"
    assert "max_sim_time_s = 0.5 s reached; shutting down" in plant.log.at("info")
    assert plant.request(runner.pause(True))[0]
    assert plant.request(runner.step()) == \
        (False, "max_sim_time_s reached; the node is shutting down")
    plant.run_until(plant.clock.t + 1.5)
    assert plant.statuses[-1][1].values["state"] == "finished"
    assert plant.statuses[-1][1].message == "max_sim_time_s reached"
    # in lock-step mode a step stops at the limit
    lockstep = make_plant(lockstep=True, steps_per_call=100, max_sim_time_s=0.5)
    ok, text = lockstep.request(lockstep.runner.step())
    assert ok and text.startswith("advanced 25 chunk(s) to t = 0.500 s")


def test_shutdown_after_stop_finishes_at_the_first_boundary_that_long_after_the_stop():
    plant = make_plant(real_time_factor=0.0, chunk_s=0.1, auto_brake_at_s=0.0,
                       shutdown_after_stop_s=2.0)
    while not plant.runner.finished.is_set():
        plant.runner.poll()
        assert plant.runner.stats.chunks < 500, "the train never stopped"
    sim = plant.runner.sim
    assert sim.stop_time_s is not None
    # chunk ends are multiples of 0.1 s: the first one 2 s or more after the stop
    assert plant.stamps_ns[-1] == math.ceil(round((sim.stop_time_s + 2.0) * 1e9) / 1e8) * 10**8
    assert plant.runner.finish_reason == "shutdown_after_stop_s reached"
    assert "2 s after the stop; shutting down" in plant.log.at("info")
    assert sum("train stopped" in line for line in plant.log.at("info")) == 1


# --------------------------------------------------------------------------- inputs and jobs


def test_inputs_are_checked_against_the_command_ranges_counted_and_logged_sparingly():
    plant = make_plant(lockstep=True)
    runner = plant.runner
    for value in (0.5, math.nan, math.inf, -0.1, 1.5, 0.25):
        runner.receive("brake_demand", value, f"msg {value}")
    runner.receive("traction", -1.0)
    runner.receive("traction", -1.5)
    runner.receive("emergency", True)
    runner.poll()
    assert runner.commands == Commands(emergency=True, brake_demand=0.25, traction=-1.0)
    assert runner.handled == 9 and runner.rejected == {"brake_demand": 4, "traction": 1}
    # every input is handed on (to be recorded), accepted or not, in order
    assert [(name, msg) for _, name, _, msg in plant.inputs][:6] == \
        [("brake_demand", f"msg {v}") for v in (0.5, math.nan, math.inf, -0.1, 1.5, 0.25)]
    assert plant.log.at("warning") == [
        "/t/brake_demand: rejected nan, expected a finite number from 0 to 1; keeping the "
        "previous value (1 rejected so far)",
        "traction: rejected -1.5, expected a finite number from -1 to 1; keeping the previous "
        "value (1 rejected so far)"]
    plant.clock.t += 2.0  # the next rejection on a topic is logged two seconds later
    runner.receive("brake_demand", 2.0)
    runner.poll()
    assert plant.log.at("warning")[-1].endswith("(5 rejected so far)")
    plant.run_until(plant.clock.t + 1.0)
    status = plant.statuses[-1][1]
    assert (status.values["rejected_inputs"], status.values["inputs_handled"]) == ("6", "10")
    assert (status.values["brake_demand"], status.values["traction_command"],
            status.values["emergency_command"]) == ("0.25", "-1", "true")
    with pytest.raises(KeyError, match="unknown input"):
        runner.receive("sand", 1.0)


def test_driver_brake_valve_positions_set_the_commands_an_unknown_one_is_one_warning():
    from ltd_brake_ros.inputs.commands import FIRST_STEP_DEMAND
    from ltd_brake_ros.physics.brakes.base import EMERGENCY, OVERCHARGE, SERVICE

    plant = make_plant(lockstep=True)
    runner = plant.runner
    expected = [("full_service", Commands(brake_demand=1.0), (1.0, SERVICE)),
                ("lap", Commands(brake_demand=1.0), (1.0, SERVICE)),
                ("service", Commands(brake_demand=FIRST_STEP_DEMAND),
                 (FIRST_STEP_DEMAND, SERVICE)),
                ("release_overcharge", Commands(overcharge=True), (0.0, OVERCHARGE)),
                ("lap", Commands(overcharge=True), (0.0, OVERCHARGE)),
                ("running", Commands(), (0.0, SERVICE)),
                ("emergency", Commands(emergency=True), (1.0, EMERGENCY)),
                ("brake", Commands(emergency=True), (1.0, EMERGENCY)),
                ("running", Commands(), (0.0, SERVICE))]
    for position, commands, level in expected:
        runner.receive("driver_brake_valve", position, position)
        assert plant.request(runner.step())[0]
        assert (runner.commands, runner.sim.state.brake_command) == (commands, level), position
    assert runner.handled == len(expected) and runner.rejected == {"driver_brake_valve": 1}
    assert plant.log.at("warning") == [
        "driver_brake_valve: rejected 'brake', expected a position of the driver's brake valve: "
        "release_overcharge, running, lap, service, full_service, emergency; keeping the "
        "previous commands (1 rejected so far)"]


def test_jobs_run_between_chunks_a_failing_one_does_not_stop_the_plant():
    plant = make_plant(real_time_factor=0.0)
    runner = plant.runner
    later = []

    def boom():
        raise RuntimeError("boom")

    def submits_another():
        later.append(runner.submit(lambda: (True, "second")))
        return True, "first"

    failing, first = runner.submit(boom), runner.submit(submits_another)
    runner.poll()
    assert failing.result == (False, "RuntimeError: boom") and plant.log.at("error") == ["RuntimeError: boom"]
    assert first.result == (True, "first")
    # only the jobs queued before a poll run in it: a flood cannot starve the chunks
    assert not later[0].done.is_set() and runner.stats.chunks == 1
    runner.poll()
    assert later[0].result == (True, "second") and runner.stats.chunks == 2


# --------------------------------------------------------------------------- failures


def test_a_simulator_failure_stops_advancing_is_reported_and_reset_recovers(monkeypatch):
    plant = make_plant(real_time_factor=1.0)
    runner = plant.runner
    plant.run_until(plant.clock.t + 0.07)

    def diverge(*args, **kwargs):
        raise SimulationError("forced: Newton iteration did not converge")

    monkeypatch.setattr(runner.sim, "advance", diverge)
    plant.run_until(plant.clock.t + 0.02)
    assert runner.failure == "forced: Newton iteration did not converge"
    assert plant.log.at("error") == [
        "simulation failed at t = 0.060 s: forced: Newton iteration did not converge; the "
        "plant stopped advancing, call ~/reset to recover"]
    status = plant.statuses[-1][1]  # reported at once, not at the next second
    assert status.level == ERROR and status.message == runner.failure
    assert status.values["state"] == "failed" and status.values["error"] == runner.failure
    published = len(plant.states)
    plant.run_until(plant.clock.t + 2.0)
    assert len(plant.states) == published
    assert plant.request(runner.pause(True))[0]
    assert plant.request(runner.step()) == \
        (False, f"simulation failed: {runner.failure}; call ~/reset")
    monkeypatch.undo()
    assert plant.request(runner.reset())[0] and runner.failure is None
    assert plant.request(runner.step())[0] and plant.stamps_ns[-2:] == [0, CHUNK_NS]


def test_any_simulator_exception_is_a_failure_with_its_type():
    plant = make_plant(lockstep=True)
    plant.runner.sim.advance = lambda *a, **k: 1 / 0
    assert plant.request(plant.runner.step()) == \
        (False, "simulation failed: ZeroDivisionError: division by zero; call ~/reset")


# --------------------------------------------------------------------------- the thread


def threaded_runner(clock, publish_state, log=None, **kwargs):
    return PlantRunner(CostlySimulator(FakeClock()), PlantSettings(real_time_factor=0.0,
                                                                  max_sim_time_s=0.2),
                       publish_state=publish_state, publish_status=lambda s: None,
                       log=log or Log(), clock=clock, **kwargs)


def test_the_plant_thread_runs_until_finished_and_close_joins_it():
    idle = threaded_runner(FakeClock().clock(), lambda s: None)
    assert idle.result(idle.reset()) == (False, "the plant is not running (shutting down)")
    stamps = []
    runner = threaded_runner(Clock(), lambda s: stamps.append(round(s.time_s * 1e9)))
    runner.start()
    assert runner.finished.wait(30)
    assert runner.result(runner.pause(True)) == (True, "paused at t = 0.200 s")
    runner.close()
    assert stamps == [k * CHUNK_NS for k in range(11)] and runner.exit_status == 0


@pytest.mark.parametrize("host_ok", [True, False])
def test_an_unexpected_error_on_the_plant_thread_ends_the_run(host_ok):
    def publish(snap):
        if snap.time_s > 0.03:
            raise RuntimeError("publisher gone")

    log = Log()
    runner = threaded_runner(FakeClock().clock(), publish, log=log, host_ok=lambda: host_ok)
    runner.run()  # returns once the error ended the loop
    if host_ok:
        assert log.at("fatal") == ["plant thread stopped: RuntimeError: publisher gone"]
        assert runner.exit_status == 1 and runner.finished.is_set()
    else:  # the host is shutting down: expected, not reported
        assert log.lines == [] and runner.exit_status == 0


@pytest.mark.parametrize("kernel_s,publish_s", [
    (0.0, 0.0015),  # publishing holds the GIL: a yield after every 20 ms of it
    (0.009, 0.0015),  # the kernel runs without the GIL: its time does not count
    (0.0, 0.0045)])
def test_as_fast_as_possible_the_plant_yields_the_gil_after_holding_it_for_a_period(
        kernel_s, publish_s):
    from ltd_brake_ros.plant.runner import GIL_YIELD_PERIOD_S

    fake, yields = FakeClock(), []

    def sleep(seconds):
        yields.append(fake.t)
        fake.sleep(seconds)

    def publish_state(snap):
        fake.t += publish_s

    runner = PlantRunner(CostlySimulator(fake, lambda k: kernel_s),
                         PlantSettings(real_time_factor=0.0), publish_state=publish_state,
                         publish_status=lambda s: None, log=Log(),
                         clock=Clock(fake.monotonic, sleep, fake.wait))
    runner.begin()
    while len(yields) < 5:
        runner.poll()
    chunks_per_yield = math.ceil(GIL_YIELD_PERIOD_S / publish_s)
    assert np.diff(yields) == pytest.approx(chunks_per_yield * (kernel_s + publish_s))
