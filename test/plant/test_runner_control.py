"""PlantRunner on a fake clock: long steps stay interruptible, the simulation state and its
transitions, diagnostics by simulated time when the wall clock does not pace the plant.

Requests "from another thread" are queued by the simulator itself while it advances a given
chunk (the plant is polled on the test's thread), so where in a step they arrive is exact.
"""
from __future__ import annotations

import pytest

from plant_helpers import make_plant
from ltd_brake_ros.plant.runner import PAUSED, PLAYING, QUITTING, STOPPED

#: A step far longer than any test runs: it must end by interruption.
HUGE = 100_000


def on_chunk(plant, k: int, action):
    """Run ``action()`` while the simulator advances its chunk number ``k`` (0 = the first)."""
    sim = plant.runner.sim
    advance = sim.advance

    def advance_and_act(duration_s, commands=None):
        if sim.advanced == k:
            action()
        return advance(duration_s, commands)
    sim.advance = advance_and_act


def test_a_pause_during_a_long_lock_step_step_is_served_after_the_chunk_and_ends_the_step():
    plant = make_plant(lockstep=True, steps_per_call=HUGE)
    runner, jobs = plant.runner, []
    on_chunk(plant, 10, lambda: jobs.append(runner.pause(True)))
    ok, text = plant.request(runner.step())
    # queued during chunk 11 (index 10), served right after it: the step ends there
    assert runner.sim.advanced == 11 and plant.stamps_ns[-1] == 11 * 20_000_000
    assert not ok and text.startswith(f"interrupted by a pause after 11 of {HUGE} chunks: "
                                      "advanced 11 chunk(s) to t = 0.220 s")
    assert jobs[0].done.is_set() and jobs[0].result[0]
    assert runner.simulation_state() == (PAUSED, "held by ~/pause: steps are refused until "
                                                 "it is resumed")


def test_resuming_a_paused_free_running_plant_ends_its_step_and_the_plant_plays_on():
    plant = make_plant(real_time_factor=1.0)
    runner = plant.runner
    assert plant.request(runner.pause(True))[0]
    on_chunk(plant, 4, lambda: runner.pause(False))
    ok, text = plant.request(runner.step(HUGE))
    assert not ok and text.startswith(f"interrupted: the plant was resumed after 5 of {HUGE}")
    assert runner.simulation_state() == (PLAYING, "")
    start = plant.clock.t
    plant.run_until(start + 0.1 + 1e-9)
    assert runner.sim.advanced == 10  # playing again at its pace: 5 chunks in 0.1 s


def test_a_real_time_factor_set_during_a_step_applies_at_once_and_the_step_goes_on():
    plant = make_plant(lockstep=True)
    runner = plant.runner
    seen = []
    sim = runner.sim
    advance = sim.advance

    def advance_and_look(duration_s, commands=None):
        if sim.advanced == 10:
            runner.set_real_time_factor(3.0)
        seen.append(runner.real_time_factor)
        return advance(duration_s, commands)
    sim.advance = advance_and_look
    ok, text = plant.request(runner.step(50))
    assert ok and text.startswith("advanced 50 chunk(s) to t = 1.000 s")
    assert seen == [1.0] * 11 + [3.0] * 39


def test_inputs_arriving_during_a_step_wait_for_its_end():
    plant = make_plant(lockstep=True)
    runner, demands = plant.runner, []
    sim = runner.sim
    advance = sim.advance

    def advance_and_record(duration_s, commands=None):
        if sim.advanced == 3:
            runner.receive("brake_demand", 0.5)
        demands.append(commands.brake_demand)
        return advance(duration_s, commands)
    sim.advance = advance_and_record
    assert plant.request(runner.step(20))[0]
    assert demands == [0.0] * 20  # the step ran with the commands it was asked with
    assert plant.request(runner.step(1))[0]
    assert demands[-1] == 0.5


def test_shutdown_during_a_long_step_ends_it_after_the_chunk_in_progress():
    plant = make_plant(lockstep=True)
    runner = plant.runner
    on_chunk(plant, 7, runner.close)
    ok, text = plant.request(runner.step(HUGE))
    assert not ok and text.startswith(f"interrupted by shutdown after 8 of {HUGE} chunks")
    assert runner.sim.advanced == 8


def test_a_run_limit_ends_a_long_step_as_a_success():
    plant = make_plant(lockstep=True, max_sim_time_s=0.3)
    ok, text = plant.request(plant.runner.step(HUGE))
    assert ok and text.startswith("advanced 15 chunk(s) to t = 0.300 s")
    assert plant.runner.simulation_state() == (QUITTING, "max_sim_time_s reached")


def test_free_running_state_transitions():
    plant = make_plant(real_time_factor=1.0)
    runner = plant.runner
    assert runner.simulation_state() == (PLAYING, "")
    assert plant.request(runner.set_simulation_state(PLAYING))[0] == "already"
    assert plant.request(runner.set_simulation_state(PAUSED))[0] == "ok"
    assert runner.simulation_state() == (PAUSED, "") and runner.paused
    assert plant.request(runner.set_simulation_state(PAUSED))[0] == "already"
    # a stop: reset to t = 0 and hold; a paused free-running plant may still be stepped
    assert plant.request(runner.step(5))[0]
    assert runner.stop_refusal() is None
    ok, text = plant.request(runner.reset(hold=True))
    assert ok and text.startswith("stopped: reset to the initial state")
    assert runner.simulation_state() == (STOPPED, "") and runner.sim.time_s == 0.0
    assert runner.stop_refusal() == ("already", "stopped at t = 0 s")
    plant.run_until(plant.clock.t + 1.0)
    assert runner.sim.time_s == 0.0  # holding
    assert plant.request(runner.step(2))[0]
    assert runner.simulation_state() == (PAUSED, "")
    assert plant.request(runner.set_simulation_state(PLAYING))[0] == "ok"
    assert runner.simulation_state() == (PLAYING, "")
    outcome, text = plant.request(runner.set_simulation_state("no_world"))
    assert outcome == "refused" and "no_world" in text
    assert plant.request(runner.set_simulation_state(QUITTING))[0] == "ok"
    assert runner.finished.is_set() and runner.simulation_state()[0] == QUITTING
    assert runner.stop_refusal()[0] == "refused"


def test_lock_step_state_transitions():
    plant = make_plant(lockstep=True)
    runner = plant.runner
    assert runner.simulation_state() == (PAUSED, "")
    outcome, text = plant.request(runner.set_simulation_state(PLAYING))
    assert outcome == "refused" and "advances only when stepped" in text
    assert plant.request(runner.set_simulation_state(PAUSED))[0] == "already"
    assert plant.request(runner.pause(True))[0]
    assert not plant.request(runner.step(1))[0]
    # PAUSED lets a held lock-step plant be stepped again
    assert plant.request(runner.set_simulation_state(PAUSED))[0] == "ok"
    assert plant.request(runner.step(3))[0]
    # stopped: held at t = 0, steps refused until PAUSED
    assert plant.request(runner.reset(hold=True))[0]
    assert runner.simulation_state() == (STOPPED, "")
    assert not plant.request(runner.step(1))[0]
    assert plant.request(runner.set_simulation_state(PAUSED))[0] == "ok"
    assert runner.simulation_state() == (PAUSED, "")
    ok, text = plant.request(runner.step(2))
    assert ok and "to t = 0.040 s" in text


def test_a_following_plant_refuses_state_changes_and_a_failed_one_says_why(monkeypatch):
    follower = make_plant(follow_clock=True)
    outcome, text = follower.request(follower.runner.set_simulation_state(PAUSED))
    assert outcome == "refused" and "clock:=follow" in text
    assert follower.runner.simulation_state()[0] == PLAYING
    assert follower.runner.stop_refusal()[0] == "refused"
    plant = make_plant(real_time_factor=0.0)
    runner = plant.runner
    monkeypatch.setattr(type(runner.sim), "advance",
                        lambda self, *a, **k: (_ for _ in ()).throw(ValueError("boom")))
    plant.polls(1)
    state, why = runner.simulation_state()
    assert state == PAUSED and why == "simulation failed: ValueError: boom; reset it"
    assert plant.request(runner.set_simulation_state(PLAYING))[0] == "failed"


# --------------------------------------------------------------------------- diagnostics


@pytest.mark.parametrize("settings", [{"real_time_factor": 0.0}, {"lockstep": True}])
def test_an_unpaced_plant_reports_every_simulated_second(settings):
    plant = make_plant(**settings)
    runner = plant.runner
    if settings.get("lockstep"):
        assert plant.request(runner.step(260))[0]
    else:
        plant.polls(260)
    assert plant.clock.t == 1000.0  # no wall time passed: every report is a simulated one
    assert [float(s.values["sim_time_s"]) for _, s in plant.statuses] == [1.0, 2.0, 3.0, 4.0,
                                                                          5.0]
    # a reset starts the count again from t = 0
    assert plant.request(runner.reset())[0]
    if settings.get("lockstep"):
        assert plant.request(runner.step(50))[0]
    else:
        plant.polls(51)
    assert float(plant.statuses[-1][1].values["sim_time_s"]) == 1.0


def test_a_plant_paced_by_the_wall_clock_reports_by_wall_time_only():
    plant = make_plant(real_time_factor=4.0)
    plant.run_until(plant.clock.t + 2.0 + 1e-6)
    # 8 simulated seconds, 2 reports (one per wall second)
    assert [float(s.values["sim_time_s"]) for _, s in plant.statuses] == \
        pytest.approx([4.0, 8.0], abs=0.021)
