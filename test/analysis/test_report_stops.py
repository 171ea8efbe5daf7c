"""Stops recorded on the plant's stops topic, rebuilt by the report as the simulator saw them."""
from __future__ import annotations

import contextlib
import csv
import io
import json

import pytest
import yaml

from bag_helpers import plant_messages, write_messages
from ltd_brake_ros.analysis.export import write_csv
from ltd_brake_ros.analysis.report import analyse
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.recording.cdr_encode import encode_string
from ltd_brake_ros.recording.cdr import decode_string
from ltd_brake_ros.recording.reader import BagError, read_bag

# scenario 6: a service stop from 40 km/h, drive off at 30 s, an emergency stop at 90 s
SCRIPT = {"commands": [{"t_s": 0.0, "brake_demand": 1.0},
                       {"t_s": 30.0, "brake_demand": 0.0, "traction": 1.0},
                       {"t_s": 90.0, "traction": 0.0, "emergency": True}]}


@pytest.fixture(scope="module")
def stop_and_go(tmp_path_factory):
    d = tmp_path_factory.mktemp("stops")
    (d / "script.yaml").write_text(yaml.safe_dump(SCRIPT))
    args = ["simulate", "--scenario", "6", "--speed-kmh", "40", "--commands",
            str(d / "script.yaml"), "--record", str(d / "run"), "--json"]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(args) == 0
    return d / "run", json.loads(buf.getvalue())


def test_each_recorded_stop_is_the_simulators(stop_and_go):
    folder, run = stop_and_go
    rep = analyse(folder)
    assert [s["command"] for s in rep.stops] == ["service", "emergency"]
    assert [s["end"] for s in rep.stops] == ["drive-off", "end of run"]
    # the second stop is a stop from speed, not a twitch at walking pace
    assert rep.stops[1]["command_speed_kmh"] > 10.0 and rep.stops[1]["stopping_distance_m"] > 5
    for ours, theirs in zip(rep.stops, run["stops"]):
        # the events carry the simulator's own numbers: equal, not sampled
        for key in ("number", "command_time_s", "command_speed_kmh", "stop_time_s",
                    "stop_duration_s", "stopping_distance_m", "settled_time_s",
                    "peak_draft_kN", "peak_draft_coupler", "peak_buff_kN", "peak_buff_coupler"):
            assert ours[key] == pytest.approx(theirs[key], abs=1e-9), key
        assert ours["verdict"] == theirs["verdicts"]["status"] == "PASS"
        assert ours["criteria"] == {c["criterion"]: c["status"]
                                    for c in theirs["verdicts"]["criteria"]}
    assert rep.stops[0]["end_time_s"] == pytest.approx(run["stops"][0]["end_time_s"], abs=1e-9)
    # the run ended within the second stop: the recording closes it there
    assert run["stops"][1]["end"] == "open"
    assert rep.stops[1]["end_time_s"] == pytest.approx(run["duration_s"], abs=1e-9)
    # the second stop's holding and runaway were judged by the plant, not by the report
    assert rep.stops[1]["criteria"]["standstill_holding"] == "PASS"
    assert rep.stops[1]["criteria"]["runaway"] == "PASS"
    text = rep.describe()
    assert "Stop 1 (service, t = 0.00 s at 40.0 km/h)" in text
    assert "ended by drive-off (t = 30.00 s): PASS" in text
    assert "the plant judged it at each stop" in text
    assert rep.as_dict()["stops"][1]["end"] == "end of run"


def test_stop_messages_are_strict_json(stop_and_go):
    folder, _ = stop_and_go

    def refuse(constant):
        raise AssertionError(f"{constant} is not JSON")
    events = [json.loads(decode_string(data), parse_constant=refuse)
              for topic, _, _, data in read_bag(folder) if topic == "/train/stops"]
    kinds = [e["event"] for e in events]
    assert kinds == ["stop_started", "stopped", "settled", "drive_off", "stop_ended",
                     "stop_started", "stopped", "settled", "stop_ended"]


def test_stops_are_exported_one_row_each(stop_and_go, tmp_path):
    folder, run = stop_and_go
    files = write_csv(analyse(folder), tmp_path)
    assert tmp_path / "stops.csv" in files
    rows = list(csv.DictReader((tmp_path / "stops.csv").open()))
    assert [r["end"] for r in rows] == ["drive-off", "end of run"]
    assert float(rows[0]["stopping_distance_m"]) == pytest.approx(
        run["stops"][0]["stopping_distance_m"], rel=1e-9)
    assert rows[1]["verdict_runaway"] == "PASS"


def test_a_stops_message_that_is_not_an_event_is_refused(tmp_path):
    messages = plant_messages(ns="/t")
    messages.append(("/t/train/stops", "std_msgs/msg/String", 10**8, encode_string("[1, 2]")))
    write_messages(tmp_path / "bad", sorted(messages, key=lambda m: m[2]))
    with pytest.raises(BagError, match="/t/train/stops.*does not decode"):
        analyse(tmp_path / "bad")
