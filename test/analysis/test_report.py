"""Run report: numbers against the offline simulator, plots, CSV."""
from __future__ import annotations

import numpy as np
import pytest
from rclpy.serialization import serialize_message

from bag_helpers import array_msg, record_emergency_stop
from ltd_brake_ros.analysis.export import write_csv
from ltd_brake_ros.analysis.plots import write_plots
from ltd_brake_ros.analysis.report import _HeatMap, analyse
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.recording.recover import recover
from ltd_brake_ros.recording.writer import BagWriter
from ltd_brake_ros.studies.runs import emergency_stop

PNG = b"\x89PNG\r\n\x1a\n"
SCENARIO = 7  # E402B + 10 Shimmns from 50 km/h: the shortest of the paper's runs


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    sc = get_scenario(SCENARIO)
    folder = tmp_path_factory.mktemp("report") / "run"
    # small chunks, so that a cut file still holds several complete ones
    sim, _ = record_emergency_stop(folder, sc.consist(), sc.speed_kmh, ns="/train1",
                                   chunk_size=1 << 16)
    return folder, sc, sim


@pytest.fixture(scope="module")
def report(run):
    return analyse(run[0])


def test_numbers_match_the_offline_simulator(run, report):
    _folder, sc, _sim = run
    ref = emergency_stop(sc.consist(), sc.speed_kmh)
    assert report.namespace == "/train1"
    assert report.command_time_s == 0.0
    assert report.stopping_distance_m == pytest.approx(ref.stopping_distance_m, rel=5e-3)
    assert report.stopping_time_s == pytest.approx(ref.stop_time_s, abs=0.1)
    assert report.peak_draft_coupler == ref.peak_draft_coupler
    assert report.peak_buff_coupler == ref.peak_buff_coupler
    assert report.peak_draft_kN == pytest.approx(ref.peak_draft_kN, rel=1e-2)
    assert report.peak_buff_kN == pytest.approx(ref.peak_buff_kN, rel=1e-2)
    assert report.peak_buff_kN < 0 < report.peak_draft_kN
    assert report.n_vehicles == ref.vehicles and report.n_couplers == ref.vehicles - 1


def test_per_coupler_peaks_match_the_simulator(run, report):
    sim = run[2]
    np.testing.assert_allclose(report.coupler_peak_draft_N, sim.peak_draft_N, rtol=1e-2,
                               atol=1e-3 * np.abs(sim.peak_draft_N).max())
    np.testing.assert_allclose(report.coupler_peak_buff_N, sim.peak_buff_N, rtol=1e-2,
                               atol=1e-3 * np.abs(sim.peak_buff_N).max())


def test_consist_summary_comes_from_the_stored_metadata(report):
    text = report.describe()
    assert "E402B + 10 Shimmns" in text and "11 vehicles" in text
    assert "Emergency command: t = 0.00 s" in text
    assert "stopping distance" in text and "coupler 1" in text
    assert report.metadata["initial_speed_kmh"] == 50.0
    assert report.complete


def test_plots_are_png(report, tmp_path):
    paths = write_plots(report, tmp_path / "plots")
    assert sorted(p.name for p in paths) == ["brake_force.png", "coupler_force_map.png",
                                             "coupler_peaks.png", "speed.png"]
    for p in paths:
        assert p.read_bytes()[:8] == PNG and p.stat().st_size > 10_000


def test_csv_holds_the_arrays(run, report, tmp_path):
    paths = {p.name: p for p in write_csv(report, tmp_path / "csv")}
    assert {"speed_m_s.csv", "position_m.csv", "brake_force_N.csv", "coupler_force_N.csv",
            "brake_command.csv", "coupler_peaks.csv"} <= set(paths)
    header = paths["coupler_force_N.csv"].read_text().splitlines()[0].split(",")
    assert header == ["time_s"] + [f"coupler_{j}" for j in range(1, 11)]
    forces = np.loadtxt(paths["coupler_force_N.csv"], delimiter=",", skiprows=1)
    assert forces.shape == (report.topics["/train1/couplers/force"], 11)
    assert forces[:, 1:].max() == pytest.approx(report.peak_draft_kN * 1e3, rel=1e-9)
    speeds = np.loadtxt(paths["speed_m_s.csv"], delimiter=",", skiprows=1)
    np.testing.assert_allclose(speeds[:, 1], report.head_speed_m_s, rtol=1e-9)
    peaks = np.loadtxt(paths["coupler_peaks.csv"], delimiter=",", skiprows=1)
    np.testing.assert_allclose(peaks[:, 3], report.coupler_peak_buff_N, rtol=1e-9)


def test_report_on_a_killed_recording_and_on_its_recovery(run, tmp_path):
    data = (run[0] / "run_0.mcap").read_bytes()
    cut = tmp_path / "killed.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    rep = analyse(cut)
    assert not rep.complete and rep.command_time_s == 0.0
    assert rep.stop_time_s is None  # the end of the run is gone
    recover(cut)
    rec = analyse(tmp_path / "killed_recovered")
    assert rec.complete and rec.peak_buff_kN == rep.peak_buff_kN


def test_heat_map_stays_bounded_and_keeps_extremes():
    rng = np.random.default_rng(3)
    heat = _HeatMap(max_bins=8)
    data = rng.normal(size=(1001, 4))
    for i, row in enumerate(data):
        heat.add(i * 0.02, row)
    t0, t1, values = heat.result()
    assert values.shape[0] <= 17 and values.shape[1] == 4
    assert values.max() == data.max() and values.min() == data.min()
    assert t0[0] == 0.0 and t1[-1] == pytest.approx(1000 * 0.02)
    assert np.all(np.diff(t0) > 0)


def test_no_plant_topics_is_an_error(tmp_path):
    with BagWriter(tmp_path / "b") as w:
        w.add_topic("/other", "std_msgs/msg/Float64MultiArray")
        w.write("/other", serialize_message(array_msg([1.0], "vehicle")), 0)
    with pytest.raises(ValueError, match="vehicles/speed"):
        analyse(tmp_path / "b")
