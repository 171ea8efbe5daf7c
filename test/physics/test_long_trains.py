"""Long trains: couplers beyond their valid range are summarised, and runs report progress.

A 1500-wagon train pushes about 1300 couplers beyond the coupler table; one warning per coupler
buries the result. The simulator summarises them (how many, the worst few with coupler, time
and excursion), and the whole-run functions call a progress hook after every chunk.
"""
import numpy as np
import pytest

from ltd_brake_ros.inputs import consist_from_mapping, load_command_script
from ltd_brake_ros.physics.kernel import SETTLE_S
from ltd_brake_ros.physics.couplers import linear
from ltd_brake_ros.simulator import Commands, CouplerExcursions, Simulator
from ltd_brake_ros.studies.runs import Progress, emergency_stop, scripted_run

#: A draw gear of 20 kN/mm with 10 mm slack and only 1 mm of travel: any coupler carrying
#: more than 20 kN goes beyond its valid range (+-11 mm).
SHORT_TRAVEL = linear.Params(stiffness_N_m=2e7, damping_N_s_m=2e5, slack_m=0.01,
                             travel_m=0.001)


def train(wagons=30):
    return consist_from_mapping({"name": "long", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": wagons, "mass_t": 80.0,
                            "brake_position": "G"}]}, "<test>")


def test_summary_ranks_the_worst_excursions_with_their_times():
    # fixed steps: one step per chunk, so that every step's excursion is seen here
    sim = Simulator(train(), 100.0, lut=SHORT_TRAVEL, tolerance_m_s=0.0)
    reach = SHORT_TRAVEL.slack_m + SHORT_TRAVEL.travel_m
    worst = np.zeros(sim.n - 1)
    when = np.zeros(sim.n - 1)
    sim.advance(sim.step_s, Commands(emergency=True))
    while sim.stop_time_s is None:
        # one step per chunk: the excursion of every coupler after every step
        x = sim.state.kinematics.x_m
        beyond = np.abs(x[:-1] - x[1:]) - reach
        grew = beyond > worst
        worst[grew], when[grew] = beyond[grew], sim.time_s
        sim.advance(sim.step_s)
    summary = sim.coupler_excursions(worst=4)
    assert isinstance(summary, CouplerExcursions)
    assert summary.total == sim.n - 1
    assert summary.count == np.count_nonzero(worst > 0) > 10      # most couplers went beyond
    assert len(summary.worst) == 4
    expected = np.argsort(-worst)[:4]
    assert [e.coupler for e in summary.worst] == list(expected + 1)
    for e, j in zip(summary.worst, expected):
        assert e.beyond_range_mm == pytest.approx(worst[j] * 1e3, abs=1e-9)
        assert e.time_s == pytest.approx(when[j], abs=1e-9)
        assert 0.0 < e.first_time_s <= e.time_s
    text = summary.describe()
    assert "\n" not in text and text.startswith(f"{summary.count} of {summary.total} couplers")
    assert f"coupler {summary.worst[0].coupler} by {summary.worst[0].beyond_range_mm:.1f} mm" \
        in text


def test_summary_of_a_train_within_its_table():
    sim = Simulator(train(5), 50.0)
    sim.advance(2.0, Commands(emergency=True))
    summary = sim.coupler_excursions()
    assert (summary.count, summary.total, summary.worst) == (0, 5, ())
    assert "no coupler" in summary.describe()


def test_stop_result_carries_the_summary():
    res = emergency_stop(train(), 100.0, lut=SHORT_TRAVEL)
    summary = res.out_of_range
    assert summary.count == res.couplers_beyond_lut > 10
    assert summary.worst[0].beyond_range_mm == res.max_beyond_lut_mm
    assert len(summary.worst) == 3
    assert res.as_dict()["out_of_range"]["worst"][0]["coupler"] == summary.worst[0].coupler


def test_emergency_stop_reports_progress_after_every_chunk():
    seen = []
    res = emergency_stop(train(10), 100.0, chunk_s=2.0, progress=seen.append)
    assert all(isinstance(p, Progress) for p in seen)
    times = [p.time_s for p in seen]
    assert times == pytest.approx([2.0 * (k + 1) for k in range(len(seen))])
    assert res.stop_time_s <= times[-1]
    # the run goes on until the train has settled (2 s at rest), ending with that chunk
    assert times[-2] < res.settled_time_s + SETTLE_S <= times[-1]
    assert all(p.fraction is None for p in seen)       # the end is not known in advance
    walls = [p.wall_s for p in seen]
    assert walls == sorted(walls) and walls[0] >= 0.0


def test_scripted_run_reports_the_fraction_done():
    script = load_command_script("commands/service_then_emergency.yaml")
    seen = []
    sim = scripted_run(train(10), 60.0, script, chunk_s=0.5, progress=seen.append)
    assert len(seen) == round(script.duration_s / 0.5)
    assert [p.fraction for p in seen] == pytest.approx(
        [p.time_s / script.duration_s for p in seen])
    assert seen[-1].fraction == pytest.approx(1.0) and seen[-1].time_s == sim.time_s
