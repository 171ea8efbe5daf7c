"""Hostile recordings through the report and the CSV export: the right numbers or one BagError.

Built from one recorded emergency stop (paper scenario 7) whose messages are then mixed with a
second run, reordered, resized, retyped or damaged. A report either equals the report of the
genuine recording or refuses with a one-line :class:`BagError` naming the recording, the topic,
the time and the reason; the CSV export refuses the same recordings and never drops samples.
"""
from __future__ import annotations

import random
import shutil

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64

from bag_helpers import F64, array_msg, record_emergency_stop, write_messages
from ltd_brake_ros.analysis.export import write_csv
from ltd_brake_ros.analysis.report import RunReport, analyse
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.recording.reader import BagError, bag_info

NS = "/train1"
SPEED, COUPLERS = f"{NS}/vehicles/speed", f"{NS}/couplers/force"


def _record(folder, scenario):
    sc = get_scenario(scenario)
    _sim, published = record_emergency_stop(folder, sc.consist(), sc.speed_kmh, ns=NS,
                                            chunk_size=1 << 16, keep=True)
    return published


@pytest.fixture(scope="module")
def genuine(tmp_path_factory):
    """Scenario 7 (11 vehicles, 50 km/h): its folder, its messages, its report."""
    folder = tmp_path_factory.mktemp("genuine") / "run"
    published = _record(folder, 7)
    return folder, published, analyse(folder)


def _refused(path, *words) -> str:
    with pytest.raises(BagError) as err:
        analyse(path)
    text = str(err.value)
    assert "\n" not in text
    for w in (path, *words):
        assert str(w) in text, (w, text)
    with pytest.raises(BagError) as csv_err:  # the export refuses the same recording
        write_csv(RunReport(source=str(path), namespace=NS), path.parent / "csv")
    assert str(csv_err.value) == text
    return text


def _rewrite(tmp_path, genuine, change, metadata=None):
    """The genuine recording with ``change(topic, msg_type, t_ns, data)`` applied to each
    message (and other run information, if given)."""
    folder, published, _rep = genuine
    folder_out = tmp_path / "hostile"
    write_messages(folder_out, [change(*m) for m in published],
                   metadata=metadata or bag_info(folder).metadata, chunk_size=1 << 16)
    return folder_out


def test_two_runs_in_one_folder_are_not_merged(genuine, tmp_path):
    # the reported defect: one run's consist, the other's couplers, a distance of neither
    folder, _published, _rep = genuine
    other = tmp_path / "other"
    _record(other, 10)  # 25 vehicles from 50 km/h
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    shutil.copy(folder / "run_0.mcap", mixed / "run_0.mcap")
    shutil.copy(other / "other_0.mcap", mixed / "other_0.mcap")
    text = _refused(mixed, "run_0.mcap", "other_0.mcap", "different run information",
                    "give one .mcap")
    assert "not parts of one run" in text


def test_an_array_that_changes_length_is_refused_with_topic_time_and_lengths(genuine, tmp_path):
    # from t = 10 s the train has 20 vehicles and a 199 kN draft: never report the first part

    def grow(topic, msg_type, t, data):
        if msg_type != F64 or t < 10_000_000_000:
            return topic, msg_type, t, data
        n = 19 if topic == COUPLERS else 20
        values = np.full(n, 199e3 if topic == COUPLERS else 1.0)
        label = "coupler" if topic == COUPLERS else "vehicle"
        return topic, msg_type, t, serialize_message(array_msg(values, label))

    path = _rewrite(tmp_path, genuine, grow)
    _refused(path, SPEED, "20 values at t = 10.000 s", "where 11 belong", "one train")


def test_coupler_array_not_one_shorter_than_the_train_is_refused(genuine, tmp_path):

    def widen(topic, msg_type, t, data):
        if topic == COUPLERS:
            data = serialize_message(array_msg(np.zeros(22), "coupler"))
        return topic, msg_type, t, data

    _refused(_rewrite(tmp_path, genuine, widen), COUPLERS, "22 values", "where 10 belong")


def test_messages_out_of_time_order_give_the_genuine_report(genuine, tmp_path):
    folder, published, rep = genuine
    shuffled = published[:]
    random.Random(11).shuffle(shuffled)
    path = tmp_path / "shuffled"
    write_messages(path, shuffled, metadata=bag_info(folder).metadata, chunk_size=1 << 14)
    got = analyse(path)
    assert got.stopping_distance_m == rep.stopping_distance_m > 0
    for key in ("command_time_s", "stop_time_s", "peak_draft_kN", "peak_draft_coupler",
                "peak_buff_kN", "peak_buff_coupler", "n_vehicles"):
        assert getattr(got, key) == getattr(rep, key), key
    np.testing.assert_array_equal(got.head_speed_m_s, rep.head_speed_m_s)
    ours = write_csv(got, tmp_path / "csv_shuffled")
    theirs = write_csv(rep, tmp_path / "csv_genuine")
    assert {p.name: p.read_bytes() for p in ours} == {p.name: p.read_bytes() for p in theirs}


@pytest.mark.parametrize("topic, msg_type, words", [
    (SPEED, "std_msgs/msg/Float64", ["recorded as std_msgs/msg/Float64, not "
                                     "std_msgs/msg/Float64MultiArray"]),
    (f"{NS}/brake_command", F64, ["not std_msgs/msg/Bool"]),
])
def test_a_plant_topic_with_another_type_is_refused(genuine, tmp_path, topic, msg_type, words):

    def retype(name, typ, t, data):
        if name != topic:
            return name, typ, t, data
        if msg_type == "std_msgs/msg/Float64":
            return name, msg_type, t, serialize_message(Float64(data=1.0))
        return name, msg_type, t, serialize_message(array_msg([1.0], "vehicle"))

    _refused(_rewrite(tmp_path, genuine, retype), topic, *words)


@pytest.mark.parametrize("damage, words", [
    (lambda data: data[:-9], ["does not decode", "runs past the end"]),
    (lambda data: data[:6], ["does not decode"]),
    (lambda data: data[:-8] + np.array([np.nan]).tobytes(), ["non-finite value"]),
])
def test_a_plant_payload_that_is_not_a_plant_array_is_refused(genuine, tmp_path, damage, words):
    changed = []

    def hurt(topic, msg_type, t, data):
        if topic == SPEED and t >= 5_000_000_000 and not changed:
            changed.append(t)
            data = damage(data)
        return topic, msg_type, t, data

    _refused(_rewrite(tmp_path, genuine, hurt), SPEED, "t = 5.000 s", *words)


def test_run_information_at_odds_with_the_arrays_is_refused(genuine, tmp_path):
    path = _rewrite(tmp_path, genuine, lambda *m: m,
                    metadata={"consist": {"name": "other", "vehicles": 25}})
    with pytest.raises(BagError, match="11 vehicles in the arrays, but the run information "
                                       "says 25"):
        analyse(path)


def test_odd_run_information_is_shown_as_text_not_a_traceback(genuine, tmp_path):
    odd = {"consist": {"name": ["x"], "vehicles": "eleven", "length_m": "long",
                       "mass_t": 10 ** 400, "braked_weight_percent": None},
           "initial_speed_kmh": "fast", "emergency_time_s": True}
    rep = analyse(_rewrite(tmp_path, genuine, lambda *m: m, metadata=odd))
    text = rep.describe()
    assert "eleven vehicles" in text and "long m" in text and "Initial speed: fast km/h" in text
    assert rep.command_time_s == 0.0  # from the recorded command, not the odd metadata


# --------------------------------------------------------------------------- another recorder


def _foreign(folder, stamps_s):
    """A recording as ``ros2 bag record`` makes it of a plant of 3 vehicles: log times are
    receive times (1 ms after each state, in list order), simulated time only in the
    states' header stamps ``stamps_s`` [s]."""
    from ltd_brake_ros.recording.cdr_encode import (encode_bool, encode_float64_array,
                                                    encode_joint_state)

    joint = "sensor_msgs/msg/JointState"
    names = [f"vehicle_{i}" for i in range(3)]
    messages = [(f"{NS}/brake_command", "std_msgs/msg/Bool", 0, encode_bool(True))]
    for k, t in enumerate(stamps_s):
        log = 1_000_000_000 + k * 1_000_000  # the recorder's clock, not the plant's
        v = max(10.0 - 0.5 * t, 0.0)
        messages += [
            (f"{NS}/vehicles/state", joint, log, encode_joint_state(
                round(t * 1e9), names, 10.0 * t - np.arange(3.0), np.full(3, v),
                np.full(3, 1e4))),
            (f"{NS}/couplers/state", joint, log, encode_joint_state(
                round(t * 1e9), names[:2], np.zeros(2), np.zeros(2), np.full(2, -5e3))),
            (SPEED, F64, log, encode_float64_array("vehicle", np.full(3, v)))]
    write_messages(folder, messages, chunk_size=1 << 16)
    return folder


def test_a_foreign_recording_with_increasing_stamps_is_reported(tmp_path):
    rep = analyse(_foreign(tmp_path / "one", [0.1 * k for k in range(40)]))
    assert rep.stamped and rep.speed_time_s[-1] == pytest.approx(3.9)


@pytest.mark.parametrize("stamps, cause", [
    ([0.1 * k for k in range(20)] + [0.1 * k for k in range(20)], "a reset: time restarts"),
    ([0.1 * k for k in range(20)] + [1.9] + [0.1 * k for k in range(20, 30)], "a repeated stamp"),
    ([0.1 * k for k in range(10)] + [1.2, 1.1] + [0.1 * k for k in range(13, 20)],
     "two states delivered out of order"),
    ([0.1 * k for k in range(0, 40, 2)] + [0.1 * k for k in range(1, 40, 2)],
     "two plants on one namespace, interleaved"),
])
def test_a_foreign_recording_whose_stamps_do_not_increase_is_refused(tmp_path, stamps, cause):
    """Not one report of several runs mixed: one line naming the topic and the stamps."""
    folder = _foreign(tmp_path / "mixed", stamps)
    with pytest.raises(BagError) as err:
        analyse(folder)
    text = str(err.value)
    assert "\n" not in text and str(folder) in text, cause
    for words in (f"{NS}/vehicles/state", "not strictly increasing", "logged at",
                  "more than one run"):
        assert words in text, (words, text)
    with pytest.raises(BagError) as csv_err:  # the export of its states refuses it alike
        write_csv(RunReport(source=str(folder), namespace=NS, stamped=True), tmp_path / "csv")
    assert str(csv_err.value) == text
