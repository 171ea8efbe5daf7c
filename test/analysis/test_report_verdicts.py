"""Run report: the speed at the brake command and the verdicts from a recording."""
from __future__ import annotations

import dataclasses

import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import Bool

from bag_helpers import ARRAYS, array_msg, declare_topics, snapshot_arrays
from ltd_brake_ros.analysis.plots import write_plots
from ltd_brake_ros.analysis.report import analyse
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.inputs.consist import VehicleLimits
from ltd_brake_ros.recording.metadata import run_metadata
from ltd_brake_ros.recording.writer import BagWriter
from ltd_brake_ros.simulator import Commands, Simulator
from ltd_brake_ros.verdicts import limits_metadata

COAST_S = 1.0  # the demo coasts before the emergency command
CHUNK_S = 0.05
AFTER_STOP_S = 1.0  # recorded on after the stop, as the node does, until all stand still


def record(folder, sim, *, limits: bool):
    """Coast, apply the emergency brake, record every chunk until the stop (as the node)."""
    meta = run_metadata(sim)
    assert meta["limits"] == limits_metadata(sim.limits)  # every recording carries its limits
    if not limits:
        del meta["limits"]  # as a recording made before limits were stored
    with BagWriter(folder, metadata=meta) as w:
        declare_topics(w, "/t")

        def publish(snap):
            t_ns = round(snap.time_s * 1e9)
            for (name, label), values in zip(ARRAYS, snapshot_arrays(snap)):
                w.write(f"/t/{name}", serialize_message(array_msg(values, label)), t_ns)
            return t_ns

        publish(sim.snapshot())
        while sim.time_s < COAST_S - 1e-9:
            publish(sim.advance(CHUNK_S))
        snap = sim.advance(CHUNK_S, Commands(emergency=True))
        w.write("/t/brake_command", serialize_message(Bool(data=True)),
                round((snap.time_s - CHUNK_S) * 1e9))
        publish(snap)
        while sim.stop_time_s is None or sim.time_s < sim.stop_time_s + AFTER_STOP_S:
            publish(sim.advance(CHUNK_S))
    return folder


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    sc = get_scenario(2)  # 16 wagons of 50 t from 100 km/h
    c = sc.consist()
    # a weak draw gear behind the locomotive: the verdict must name coupler 1
    vs = (dataclasses.replace(c.vehicles[0], limits=VehicleLimits(draft_strength_N=50e3)),
          *c.vehicles[1:])
    sim = Simulator(dataclasses.replace(c, vehicles=vs), sc.speed_kmh)
    folder = record(tmp_path_factory.mktemp("verdicts") / "run", sim, limits=True)
    return sim, analyse(folder)


def test_the_speed_at_the_brake_command_and_the_distance_from_it(run):
    sim, rep = run
    assert rep.command_time_s == pytest.approx(COAST_S)
    # coasting 1 s on level track the train slows by running resistance only
    assert rep.command_speed_kmh == pytest.approx(sim.command_speed_kmh, abs=1e-6)
    assert rep.command_speed_kmh < sim.speed_kmh
    assert rep.stopping_distance_m == pytest.approx(sim.stopping_distance_m, rel=5e-3)
    text = rep.describe()
    assert f"Emergency command: t = 1.00 s at {sim.command_speed_kmh:.2f} km/h" in text
    assert rep.as_dict()["command_speed_kmh"] == rep.command_speed_kmh


def test_report_verdicts_agree_with_the_simulator(run):
    sim, rep = run
    ours, theirs = rep.verdicts, sim.verdicts()
    # a recording holds no brake state at rest: holding and runaway are the simulator's alone
    # (each recorded stop carries them); this one has no temperature topics (a recording with
    # them: test_report_heat)
    own = ("standstill_holding", "runaway", "wheel_temperature")
    assert [c.name for c in ours.criteria] == [c.name for c in theirs.criteria]
    assert [c.status for c in ours.criteria if c.name not in own] \
        == [c.status for c in theirs.criteria if c.name not in own]
    assert ours["standstill_holding"].status == "not assessed"
    assert "recording" in ours["standstill_holding"].origin
    assert ours["wheel_temperature"].status == "not assessed"
    assert "vehicles/wheel_temperature" in ours["wheel_temperature"].origin
    assert theirs["wheel_temperature"].status == "PASS"
    assert ours["draft_strength"].status == "FAIL"
    assert 1 in {e.number for e in ours["draft_strength"].exceedances}
    # recorded every 0.05 s: the sampled peaks fall short by at most a chunk's change
    for name in ("draft_strength", "buff_strength"):
        assert ours[name].worst_value == pytest.approx(theirs[name].worst_value, rel=0.02)
        assert ours[name].worst_number == theirs[name].worst_number
    # mean utilised adhesion: sampled every 0.05 s over a braked part of ~20 s, the window's
    # ends are placed within a sample (< 1 % of its distance)
    a, b = ours["adhesion"], theirs["adhesion"]
    assert a.status == b.status == "PASS"
    assert a.worst_value == pytest.approx(b.worst_value, rel=0.01)
    assert a.worst_number == b.worst_number
    # the demand against the rail: the same samples as the simulator's chunk ends (which of
    # the 16 identical wagons is worst is a tie, not compared)
    assert ours["adhesion_demand"].worst_value == pytest.approx(
        theirs["adhesion_demand"].worst_value, rel=0.01)
    assert ours["coupler_travel"].status == "PASS" and not ours.non_physical
    text = rep.describe()
    assert "Verdicts: FAIL" in text and "Coupler draft strength" in text
    assert rep.as_dict()["verdicts"]["criteria"][0]["status"] == "FAIL"


def test_a_recording_without_limits_is_judged_by_the_standards(run, tmp_path):
    sc = get_scenario(8)
    sim = Simulator(sc.consist(), sc.speed_kmh)
    rep = analyse(record(tmp_path / "run", sim, limits=False))
    v = rep.verdicts
    assert v["draft_strength"].limit_min == 850e3 and v["draft_strength"].status == "PASS"
    assert v["adhesion"].status == "not assessed"
    assert "no vehicle masses" in "\n".join(v.describe())


def test_the_peaks_plot_draws_the_limits_it_comes_near(run, tmp_path):
    _sim, rep = run
    paths = {p.name: p for p in write_plots(rep, tmp_path)}
    assert paths["coupler_peaks.png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the 50 kN draw gear of coupler 1 is within reach of the peaks: its line is drawn
    assert rep.coupler_peak_draft_N.max() >= 0.5 * rep.limits.draft_strength_N.min()
