"""PlantRunner following another plant's clock, publishing every N-th chunk, starting a new run
at a reset, and warning about rejected inputs: on the fake clock of ``plant_helpers``."""
from __future__ import annotations

import numpy as np
import pytest

from plant_helpers import SPEED_KMH, CostlySimulator, make_plant
from ltd_brake_ros.inputs import consist_from_mapping
from ltd_brake_ros.plant.diagnostics import OK, WARN, format_fixed
from ltd_brake_ros.plant.runner import FOLLOW_SLICE_S
from ltd_brake_ros.plant.settings import PlantSettings
from ltd_brake_ros.simulator import Simulator

CHUNK_NS = 20_000_000  # the default chunk, 0.02 s


def test_a_follower_advances_whole_chunks_up_to_the_clock_and_refuses_step_and_pause():
    plant = make_plant(follow_clock=True, real_time_factor=0.0)
    runner = plant.runner
    plant.run_until(plant.clock.t + 5.0)
    assert plant.stamps_ns == [0]  # never by itself, even at real_time_factor 0
    runner.follow(50_000_000)  # 0.05 s: two whole chunks, the third would pass it
    runner.poll()
    assert plant.stamps_ns == [0, CHUNK_NS, 2 * CHUNK_NS]
    # only the latest time counts when several arrive before the plant thread gets to them
    for t_ns in (60_000_000, 80_000_000, 100_000_000):
        runner.follow(t_ns)
    runner.poll()
    assert plant.stamps_ns[3:] == [3 * CHUNK_NS, 4 * CHUNK_NS, 5 * CHUNK_NS]
    for request in (runner.step(), runner.pause(True)):
        ok, text = plant.request(request)
        assert not ok and "clock:=follow" in text and "plant that publishes it" in text
    assert plant.stamps_ns[-1] == 5 * CHUNK_NS
    plant.run_until(plant.clock.t + 1.0)
    assert plant.statuses[-1][1].values["state"] == "following"


def test_a_clock_that_goes_back_holds_the_follower_with_one_warning_until_it_passes_again():
    plant = make_plant(follow_clock=True)
    runner = plant.runner
    runner.follow(200_000_000)
    runner.poll()
    assert plant.stamps_ns[-1] == 10 * CHUNK_NS
    for t_ns in (0, 20_000_000, 40_000_000):  # the clock's source was reset
        runner.follow(t_ns)
        runner.poll()
    assert plant.stamps_ns[-1] == 10 * CHUNK_NS
    warnings = plant.log.at("warning")
    assert len(warnings) == 1 and "went back to t = 0.000 s" in warnings[0] \
        and "holds at t = 0.200 s" in warnings[0]
    # two sources alternating: logged at most every two seconds, counted
    for _ in range(3):
        runner.follow(200_000_000)
        runner.follow(0)
        runner.poll()
    assert len(plant.log.at("warning")) == 1 and runner.clock_backs == 6
    plant.clock.t += 2.0
    runner.follow(0)
    runner.poll()
    assert plant.log.at("warning")[-1].endswith("7 time(s) so far)")
    runner.follow(240_000_000)
    runner.poll()
    assert plant.stamps_ns[-2:] == [11 * CHUNK_NS, 12 * CHUNK_NS]


def test_a_clock_that_jumps_far_ahead_is_caught_up_in_slices_that_serve_requests():
    # every chunk costs 10 ms of wall time: a slice holds FOLLOW_SLICE_S / 10 ms chunks
    plant = make_plant(cost_s=lambda k: 0.01, follow_clock=True)
    runner = plant.runner
    runner.follow(100 * 10**9)  # the leader's clock jumps to 100 s
    runner.poll()
    per_slice = round(FOLLOW_SLICE_S / 0.01)
    assert len(plant.stamps_ns) - 1 <= per_slice + 1
    warnings = plant.log.at("warning")
    assert len(warnings) == 1 and "jumped ahead to t = 100.000 s" in warnings[0]
    # a request queued meanwhile is answered before the next slice
    request = runner.pause(True)
    runner.poll()
    assert request.done.is_set() and not request.result[0]
    assert plant.stamps_ns[-1] < 100 * 10**9
    polls = 0
    while plant.stamps_ns[-1] < 100 * 10**9:
        runner.poll()
        polls += 1
        assert polls < 5000 // per_slice + 10
    assert polls >= 5000 // per_slice - 3  # 5 000 chunks, a slice at a time
    assert plant.log.at("info")[-1] == "caught up with the followed clock at t = 100.000 s"
    assert len(plant.log.at("warning")) == 1


@pytest.mark.parametrize("every", [1, 3, 7])
def test_publish_every_publishes_the_nth_chunks_and_always_a_steps_last(every):
    free = make_plant(real_time_factor=0.0, publish_every=every, max_sim_time_s=0.42)
    free.run_until(free.clock.t + 1.0)
    assert free.runner.stats.chunks == 21
    assert free.stamps_ns == [0] + [k * CHUNK_NS for k in range(every, 22, every)]
    # the state advanced all the same: the last chunk's time is known to the host
    assert free.runner.stamp_ns == 21 * CHUNK_NS
    stepped = make_plant(lockstep=True, steps_per_call=5, publish_every=every)
    for _ in range(2):
        assert stepped.request(stepped.runner.step())[0]
    published = {k * CHUNK_NS for k in range(every, 11, every)} | {5 * CHUNK_NS, 10 * CHUNK_NS}
    assert stepped.stamps_ns == [0] + sorted(published)
    # a reset restarts the count
    before = len(stepped.states)
    assert stepped.request(stepped.runner.reset())[0]
    assert stepped.request(stepped.runner.step())[0]
    assert stepped.stamps_ns[before:] == [0] + sorted(
        {k * CHUNK_NS for k in range(every, 6, every)} | {5 * CHUNK_NS})


def test_a_reset_with_a_replacement_starts_the_new_run_with_the_modes_in_force():
    plant = make_plant(lockstep=True, max_sim_time_s=100.0)
    runner = plant.runner
    assert plant.request(runner.step())[0]
    longer = consist_from_mapping({"name": "longer", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": 4, "mass_t": 50.0}]}, "<test>")
    new = Simulator(longer, 2 * SPEED_KMH)
    ok, text = plant.request(runner.reset(
        (new, PlantSettings(lockstep=False, chunk_s=1.0, max_sim_time_s=0.04))))
    assert ok, text
    assert runner.sim is new and plant.states[-1][1].position_m.size == 5
    np.testing.assert_allclose(plant.states[-1][1].speed_m_s, 2 * SPEED_KMH / 3.6)
    # chunk and mode stay (structural), the run policy is the new one's
    assert (runner.settings.lockstep, runner.settings.chunk_s) == (True, 0.02)
    for _ in range(2):
        assert plant.request(runner.step())[0]
    assert runner.finished.is_set() and plant.stamps_ns[-1] == 2 * CHUNK_NS


def test_rejected_inputs_turn_the_report_to_warn_for_the_window_they_were_rejected_in():
    plant = make_plant(lockstep=True)
    runner = plant.runner
    runner.receive("brake_demand", float("nan"))
    plant.run_until(plant.clock.t + 1.5)
    status = plant.statuses[-1][1]
    assert status.level == WARN and status.message.startswith("1 input(s) rejected in the last")
    plant.run_until(plant.clock.t + 1.5)
    assert plant.statuses[-1][1].level == OK


@pytest.mark.parametrize("value, text", [(-0.0, "0.000"), (-1e-9, "0.000"), (-0.0004, "0.000"),
                                         (-0.0016, "-0.002"), (0.0, "0.000"), (2.5, "2.500"),
                                         (-12.25, "-12.250")])
def test_numbers_in_reports_never_read_minus_zero(value, text):
    assert format_fixed(value) == text


def test_a_report_of_a_train_at_rest_has_no_minus_zero():
    plant = make_plant(lockstep=True)
    sim = plant.runner.sim
    assert isinstance(sim, CostlySimulator)
    plant.runner.receive("traction", -0.0)
    plant.run_until(plant.clock.t + 1.5)
    values = plant.statuses[-1][1].values
    assert not [k for k, v in values.items() if v.startswith("-0") and not v.strip("-0.")], values
