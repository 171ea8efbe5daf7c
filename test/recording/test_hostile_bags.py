"""Hostile recordings: the readers give the right messages or one BagError, never a wrong answer.

Folders mixing runs, ``metadata.yaml`` that is not rosbag2 metadata, files cut inside their
header, messages out of time order, damaged chunks, two types on one topic: every reader
(:func:`read_bag`, :func:`bag_info`, :func:`recover`) either reads the recording correctly or
raises :class:`BagError` whose one-line message names the file and the reason.
"""
from __future__ import annotations

import random
import shutil
import struct
import time

import pytest
from mcap.writer import Writer as McapWriter
from rclpy.serialization import serialize_message
from std_msgs.msg import Bool, Float64

from bag_helpers import write_messages
from ltd_brake_ros.recording import reader as reader_module
from ltd_brake_ros.recording.reader import (BagError, TruncatedBagWarning, bag_info, index_file,
                                            read_bag)
from ltd_brake_ros.recording.qos import qos_from_profile
from ltd_brake_ros.recording.recover import recover
from ltd_brake_ros.recording.ros_types import MessageTypeError, message_class

F64 = "std_msgs/msg/Float64"
RUN_A = {"consist": {"name": "A", "vehicles": 11}, "initial_speed_kmh": 50.0}
RUN_B = {"consist": {"name": "B", "vehicles": 25}, "initial_speed_kmh": 50.0}


def _msgs(times, topic="/x", offset=0.0):
    return [(topic, F64, t, serialize_message(Float64(data=float(offset + i))))
            for i, t in enumerate(times)]


def _values(path):
    from rclpy.serialization import deserialize_message

    return [(t, deserialize_message(d, Float64).data) for _topic, _typ, t, d in read_bag(path)]


def _one_line(exc: BagError, *words):
    text = str(exc)
    assert "\n" not in text and "Traceback" not in text
    for w in words:
        assert str(w) in text, (w, text)
    return text


def _every_reader_refuses(path, tmp_path, *words):
    """read_bag, bag_info and recover raise the same BagError; recover creates nothing."""
    messages = []
    for read in (lambda: list(read_bag(path)), lambda: bag_info(path),
                 lambda: recover(path, tmp_path / "recovered")):
        with pytest.raises(BagError) as err:
            read()
        messages.append(_one_line(err.value, *words))
    assert not (tmp_path / "recovered").exists()
    assert len(set(messages)) == 1
    return messages[0]


# --------------------------------------------------------------------------- mixed runs


@pytest.fixture
def two_runs(tmp_path):
    """Two runs of the same topics, both starting at t = 0, in one folder without metadata."""
    a = write_messages(tmp_path / "a", _msgs(range(0, 10_000, 100)), metadata=RUN_A)
    b = write_messages(tmp_path / "b", _msgs(range(0, 20_000, 100), offset=1e3), metadata=RUN_B)
    folder = tmp_path / "mixed"
    folder.mkdir()
    shutil.copy(a, folder / "a_0.mcap")
    shutil.copy(b, folder / "b_0.mcap")
    return folder


def test_two_runs_in_one_folder_are_refused_naming_both_files(two_runs, tmp_path):
    text = _every_reader_refuses(two_runs, tmp_path, "a_0.mcap", "b_0.mcap",
                                 "different run information", "consist.name", "give one .mcap")
    assert str(two_runs) in text
    # each file alone is one run and reads
    assert len(_values(two_runs / "a_0.mcap")) == 100
    assert len(_values(two_runs / "b_0.mcap")) == 200


def test_same_run_information_but_overlapping_times_is_refused(tmp_path):
    folder = tmp_path / "overlap"
    for name, times in (("p", range(0, 1000, 10)), ("q", range(500, 1500, 10))):
        src = write_messages(tmp_path / name, _msgs(times), metadata=RUN_A)
        folder.mkdir(exist_ok=True)
        shutil.copy(src, folder / f"{name}_0.mcap")
    _every_reader_refuses(folder, tmp_path, "p_0.mcap", "q_0.mcap", "overlap in time")


def test_metadata_yaml_naming_two_runs_is_refused(two_runs, tmp_path):
    (two_runs / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  relative_file_paths: [a_0.mcap, b_0.mcap]\n")
    _every_reader_refuses(two_runs, tmp_path, "metadata.yaml lists 2 files",
                          "different run information")


def test_parts_of_one_run_are_read_as_one_in_time_order(tmp_path):
    # one run split in two files that follow on in time; their names sort the other way round
    folder = tmp_path / "split"
    folder.mkdir()
    first = write_messages(tmp_path / "early", _msgs(range(0, 1000, 10)), metadata=RUN_A)
    second = write_messages(tmp_path / "late", _msgs(range(1000, 2000, 10), offset=100),
                            metadata=RUN_A)
    shutil.copy(first, folder / "z_0.mcap")
    shutil.copy(second, folder / "a_1.mcap")
    assert _values(folder) == [(t, float(i)) for i, t in enumerate(range(0, 2000, 10))]
    info = bag_info(folder)
    assert info.message_count == 200 and info.metadata == RUN_A
    assert [f.name for f in info.files] == ["z_0.mcap", "a_1.mcap"]
    res = recover(folder, tmp_path / "joined")
    assert res["messages"] == 200 and _values(tmp_path / "joined") == _values(folder)


def _mcap(path, channels, metadata=()):
    """A file written by the mcap library: ``(topic, type, channel metadata, payload)``."""
    with open(path, "wb") as f:
        w = McapWriter(f)
        w.start(profile="ros2")
        for name, entries in metadata:
            w.add_metadata(name, entries)
        for i, (topic, msg_type, channel_meta, payload) in enumerate(channels):
            schema = w.register_schema(msg_type, "ros2msg", b"")
            channel = w.register_channel(topic, "cdr", schema, channel_meta)
            w.add_message(channel, log_time=i, data=payload, publish_time=i)
        w.finish()
    return path


def test_one_topic_with_two_types_is_refused(tmp_path):
    path = _mcap(tmp_path / "two_types.mcap", [
        ("/x\ny", F64, {}, serialize_message(Float64(data=1.0))),
        ("/x\ny", "std_msgs/msg/Bool", {}, serialize_message(Bool(data=True)))])
    # the message stays one line: the newline of the topic name is shown escaped
    _every_reader_refuses(path, tmp_path, path, "/x\\ny", "two message types",
                          "std_msgs/msg/Bool")


def test_one_file_with_two_runs_information_is_refused(tmp_path):
    path = _mcap(tmp_path / "two_runs.mcap", [("/x", F64, {}, b"")], metadata=[
        ("ltd_brake_ros.run", {"scenario": "7"}), ("ltd_brake_ros.run", {"scenario": "10"})])
    _every_reader_refuses(path, tmp_path, path, "information of two runs", "scenario: 7 vs 10")


@pytest.mark.parametrize("qos", ["- &a [*a, *a, *a]", "{not: a list}", "[unclosed", "x" * 70000])
def test_offered_qos_profiles_that_are_not_a_qos_list_are_refused(tmp_path, qos):
    path = _mcap(tmp_path / "qos.mcap", [("/x", F64, {"offered_qos_profiles": qos}, b"")])
    for read in (lambda: list(read_bag(path)), lambda: bag_info(path)):
        with pytest.raises(BagError) as err:
            read()
        _one_line(err.value, path, "offered_qos_profiles")
    # recovery salvages what comes before the damaged record: here, nothing
    res = recover(path, tmp_path / "rec")
    assert res["messages"] == 0 and "offered_qos_profiles" in res["stopped_at"]


# --------------------------------------------------------------------------- metadata.yaml


@pytest.mark.parametrize("text, words", [
    ("rosbag2_bagfile_information: [unclosed\n", ["not valid YAML"]),
    ("- a\n- b\n", ["rosbag2_bagfile_information", "not a mapping"]),
    ("rosbag2_bagfile_information: 7\n", ["rosbag2_bagfile_information", "not a mapping"]),
    ("rosbag2_bagfile_information:\n  relative_file_paths: run_0.mcap\n",
     ["relative_file_paths", "list of file names"]),
    ("rosbag2_bagfile_information:\n  relative_file_paths: [1, 2]\n",
     ["relative_file_paths", "list of file names"]),
    ("rosbag2_bagfile_information:\n  relative_file_paths: []\n",
     ["relative_file_paths", "list of file names"]),
    ("rosbag2_bagfile_information:\n  relative_file_paths: [other_0.mcap]\n",
     ["relative_file_paths", "other_0.mcap", "not a file"]),
    ("rosbag2_bagfile_information:\n  relative_file_paths: [run_0.mcap, run_0.mcap]\n",
     ["relative_file_paths", "twice"]),
    ("\x00\x01\x02 binary", ["metadata.yaml"]),
])
def test_odd_metadata_yaml_is_one_clear_error(tmp_path, text, words):
    folder = tmp_path / "run"
    write_messages(folder, _msgs(range(5)), metadata=RUN_A)
    (folder / "metadata.yaml").write_text(text)
    _every_reader_refuses(folder, tmp_path, folder / "metadata.yaml", "give one .mcap", *words)
    assert len(_values(folder / "run_0.mcap")) == 5  # the hint works


# --------------------------------------------------------------------------- cut and damaged


def test_a_file_cut_inside_its_header_reads_as_empty_and_unfinished(tmp_path):
    path = write_messages(tmp_path / "run", _msgs(range(5)), metadata=RUN_A)
    data = path.read_bytes()
    (opcode, length) = struct.unpack_from("<BQ", data, 8)
    assert opcode == 1  # the header record
    for cut in range(0, 8 + 9 + length + 1):
        part = tmp_path / f"cut{cut}.mcap"
        part.write_bytes(data[:cut])
        with pytest.warns(TruncatedBagWarning):
            assert list(read_bag(part)) == []
        info = bag_info(part)
        assert not info.complete and info.message_count == 0 and info.topics == {}
        assert recover(part, tmp_path / f"rec{cut}")["messages"] == 0


def test_a_damaged_chunk_is_refused_and_recover_keeps_what_comes_before(tmp_path):
    path = write_messages(tmp_path / "run", _msgs(range(0, 400_000, 1000)), chunk_size=512)
    index = index_file(path)
    assert index.chunk_count > 4
    third = index.spans[2]
    data = bytearray(path.read_bytes())
    data[third.offset + third.length - 3] ^= 0xFF  # inside the compressed records
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    with pytest.raises(BagError) as err:
        list(read_bag(bad))
    _one_line(err.value, bad, f"byte {third.offset}", "recover")
    res = recover(bad, tmp_path / "kept")
    before = sum(1 for t, _v in _values(path) if t < third.start)
    assert not res["complete"] and res["messages"] == before > 0
    assert f"bad chunk at byte {third.offset}" in res["stopped_at"]


def test_a_stated_chunk_size_beyond_the_bound_is_refused_without_allocating(tmp_path):
    path = write_messages(tmp_path / "run", _msgs(range(100)), compression="none")
    first = index_file(path).spans[0]
    data = bytearray(path.read_bytes())
    struct.pack_into("<Q", data, first.offset + 9 + 16, 1 << 62)  # uncompressed size
    bad = tmp_path / "huge.mcap"
    bad.write_bytes(bytes(data))
    start = time.process_time()
    with pytest.raises(BagError, match="MiB a reader accepts"):
        list(read_bag(bad))
    assert time.process_time() - start < 1.0


# --------------------------------------------------------------------------- time order


def test_messages_out_of_time_order_come_out_in_log_time_order(tmp_path):
    rng = random.Random(5)
    times = [t * 1000 for t in range(600)]
    shuffled = times[:]
    rng.shuffle(shuffled)  # across chunks and inside them
    messages = [("/x", F64, t, serialize_message(Float64(data=t / 1000))) for t in shuffled]
    path = write_messages(tmp_path / "run", messages, chunk_size=2048)
    assert index_file(path).chunk_count > 5
    assert _values(path) == [(t, t / 1000) for t in times]
    # ties keep file (recorded) order
    tied = [("/x", F64, 5, serialize_message(Float64(data=float(i)))) for i in range(20)]
    path = write_messages(tmp_path / "tied", _msgs([9, 3]) + tied, chunk_size=256)
    assert [v for _t, v in _values(path)] == [1.0] + [float(i) for i in range(20)] + [0.0]


def test_sorting_is_bounded_in_memory(tmp_path, monkeypatch):
    # the first chunk's messages are all later than the rest: sorting holds them all
    times = list(range(5000, 10_000, 10)) + list(range(0, 5000, 10))
    path = write_messages(tmp_path / "run", _msgs(times), chunk_size=1024)
    assert sorted(t for t, _v in _values(path)) == [t for t, _v in _values(path)]
    monkeypatch.setattr(reader_module, "MAX_REORDER_BYTES", 4096)
    with pytest.raises(BagError) as err:
        list(read_bag(path))
    _one_line(err.value, path, "out of log-time order")


@pytest.mark.parametrize("name", ["nonexistent_msgs/msg/Thing", ".a/msg/B", "os/msg/path",
                                  "std_msgs/msg/__class__", "std_msgs/msg/Bool\n", ""])
def test_a_recorded_type_that_is_no_installed_message_is_a_value_error(name):
    # replay_node creates publishers from recorded type names: its ValueError handler must
    # catch every bad one, and nothing is imported for a name that is not a type name
    with pytest.raises(MessageTypeError if name else ValueError):
        message_class(name)
    assert message_class("std_msgs/msg/Bool") is Bool


@pytest.mark.parametrize("profile", [
    {"depth": "abc"}, {"depth": 1e300}, {"depth": float("nan")}, {"depth": -3},
    {"deadline": "x"}, {"lifespan": {"sec": "a", "nsec": None}}, {"history": [1]},
    {"reliability": 99}, {"durability": None}])
def test_a_recorded_qos_value_that_is_no_policy_value_gives_the_default(profile):
    # replay_node offers each topic with its recorded QoS: a damaged value must not stop it
    qos = qos_from_profile(profile)
    default = qos_from_profile(None)
    for key in ("depth", "history", "reliability", "durability", "deadline", "lifespan"):
        assert getattr(qos, key) == getattr(default, key), key
