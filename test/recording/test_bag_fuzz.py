"""Property-based fuzzing of the bag readers: a correct result or one BagError, nothing else.

Generated hostile recordings — random truncations and byte flips of a genuine file (each chunk
compression), two runs' files in one folder, messages in random time order, plant topics of the
wrong type — go through :func:`read_bag`, :func:`bag_info`, :func:`recover` and the report.
Every outcome must be either a correct result or :class:`BagError` with a one-line message
naming the file; never another exception and never a hang (each example has a deadline).

"Correct" where bytes were damaged: MCAP protects message payloads and times (chunk CRC) but
not, for instance, the run information, so a result is correct when every message read is one
the recorder wrote, with its time, in time order, and the readers agree with each other.
"""
from __future__ import annotations

import contextlib
import shutil
import warnings
from collections import Counter
from datetime import timedelta

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message
from std_msgs.msg import Bool, Float64

from bag_helpers import plant_messages, write_messages
from ltd_brake_ros.analysis.report import analyse
from ltd_brake_ros.recording.reader import BagError, TruncatedBagWarning, bag_info, read_bag
from ltd_brake_ros.recording.recover import recover

SETTINGS = dict(deadline=timedelta(seconds=10), derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
RUN_A = {"consist": {"name": "A", "vehicles": 3}}
RUN_B = {"consist": {"name": "B", "vehicles": 3}}


def _messages(n=120):
    """Messages of two types on three topics, 10 ms apart."""
    out = []
    for i in range(n):
        t = 1_000_000_000 + i * 10_000_000
        out.append(("/a", "std_msgs/msg/Float64", t, serialize_message(Float64(data=i * 0.5))))
        if i % 3 == 0:
            out.append(("/b", "std_msgs/msg/Bool", t, serialize_message(Bool(data=i % 2 == 0))))
        if i % 7 == 0:
            out.append(("/c", "std_msgs/msg/Float64", t,
                        serialize_message(Float64(data=-float(i)))))
    return out


ORIGINAL = _messages()
ORIGINAL_SET = Counter((t, d) for _topic, _typ, t, d in ORIGINAL)


@pytest.fixture(scope="module")
def genuine(tmp_path_factory):
    """One genuine file per chunk compression, several chunks each."""
    root = tmp_path_factory.mktemp("genuine")
    return {c: write_messages(root / c, ORIGINAL, metadata=RUN_A, compression=c,
                              chunk_size=700).read_bytes()
            for c in ("zstd", "lz4", "none")}


def _outcome(read, path):
    """``read()`` or the BagError it raised (checked: one line naming ``path``)."""
    try:
        return read()
    except BagError as exc:
        text = str(exc)
        assert "\n" not in text and str(path) in text, text
        return exc


def _check_messages(got):
    """Messages read are ones the recorder wrote, with their times, in time order."""
    times = [t for _topic, _typ, t, _d in got]
    assert times == sorted(times)
    assert not Counter((t, d) for _topic, _typ, t, d in got) - ORIGINAL_SET


@contextlib.contextmanager
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TruncatedBagWarning)
        yield


@settings(max_examples=120, **SETTINGS)
@given(compression=st.sampled_from(["zstd", "lz4", "none"]), cut=st.floats(0.0, 1.0),
       flips=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(1, 255)), max_size=3))
# an unfinished file whose surviving statistics name a channel id with one bit flipped: the
# counts must not be taken from them
@example(compression="zstd", cut=0.875, flips=[(0.9, 1)])
def test_truncated_and_flipped_files(genuine, tmp_path_factory, compression, cut, flips):
    data = bytearray(genuine[compression])
    for where, mask in flips:
        data[min(int(where * len(data)), len(data) - 1)] ^= mask
    if cut < 0.95:  # else whole
        data = data[: int(cut / 0.95 * len(data))]
    root = tmp_path_factory.mktemp("fuzz")
    path = root / "run.mcap"
    path.write_bytes(bytes(data))
    with _quiet():
        got = _outcome(lambda: list(read_bag(path)), path)
        info = _outcome(lambda: bag_info(path), path)
        res = _outcome(lambda: recover(path, root / "rec"), path)
    if not isinstance(got, BagError):
        _check_messages(got)
        if not isinstance(info, BagError):
            assert info.message_count == len(got)
    if isinstance(res, BagError):
        assert not (root / "rec").exists()
        return
    with _quiet():
        copied = list(read_bag(root / "rec"))
    assert Counter((t, d) for _topic, _typ, t, d in copied) <= ORIGINAL_SET
    assert res["messages"] == len(copied)
    if not isinstance(got, BagError):  # recovery keeps everything a strict reader reads
        assert Counter(m[2:] for m in copied) == Counter(m[2:] for m in got)


@settings(max_examples=40, **SETTINGS)
@given(same_run=st.booleans(), shift_ms=st.integers(-1500, 1500),
       names=st.permutations(["a_0.mcap", "b_0.mcap", "z_1.mcap"]), listed=st.booleans())
def test_two_files_in_one_folder(tmp_path_factory, same_run, shift_ms, names, listed):
    # the second file is the first one shifted in time, of the same run or another
    root = tmp_path_factory.mktemp("mixed")
    second = [(topic, typ, t + shift_ms * 1_000_000, d) for topic, typ, t, d in ORIGINAL]
    folder = root / "bag"
    folder.mkdir()
    for name, msgs, run in ((names[0], ORIGINAL, RUN_A),
                            (names[1], second, RUN_A if same_run else RUN_B)):
        shutil.copy(write_messages(root / name[:-5], msgs, metadata=run, chunk_size=900),
                    folder / name)
    if listed:
        (folder / "metadata.yaml").write_text(
            f"rosbag2_bagfile_information:\n  relative_file_paths: [{names[0]}, {names[1]}]\n")
    span_ms = (ORIGINAL[-1][2] - ORIGINAL[0][2]) // 1_000_000
    # one run only if the files follow on in time, in the listed order when there is a list
    follows = shift_ms > span_ms or (not listed and -shift_ms > span_ms)
    got = _outcome(lambda: list(read_bag(folder)), folder)
    assert (not isinstance(got, BagError)) == (same_run and follows)
    if not isinstance(got, BagError):
        assert [m[2:] for m in got] == sorted((m[2:] for m in ORIGINAL + second),
                                              key=lambda m: m[0])
    for read in (lambda: bag_info(folder), lambda: recover(folder, root / "rec")):
        assert isinstance(_outcome(read, folder), BagError) == isinstance(got, BagError)


@settings(max_examples=40, **SETTINGS)
@given(order=st.permutations(range(len(ORIGINAL))), chunk_size=st.integers(64, 4096),
       compression=st.sampled_from(["zstd", "none"]))
def test_messages_in_random_time_order(tmp_path_factory, order, chunk_size, compression):
    shuffled = [ORIGINAL[i] for i in order]
    path = write_messages(tmp_path_factory.mktemp("order") / "run", shuffled,
                          compression=compression, chunk_size=chunk_size)
    # log-time order; equal times keep the order in which they were recorded
    assert list(read_bag(path)) == sorted(shuffled, key=lambda m: m[2])
    assert bag_info(path).message_count == len(ORIGINAL)


PLANT = plant_messages(n_vehicles=4, samples=30)
PLANT_TOPICS = sorted({m[0] for m in PLANT})
TYPES = ["std_msgs/msg/Float64MultiArray", "std_msgs/msg/Bool", "std_msgs/msg/Float64"]


@settings(max_examples=30, **SETTINGS)
@given(retyped=st.dictionaries(st.sampled_from(PLANT_TOPICS), st.sampled_from(TYPES),
                               max_size=3))
def test_plant_topics_of_any_type(tmp_path_factory, retyped):
    # a topic keeps its payload but is declared with another type: only the plant's own
    # type for each topic gives a report
    messages = [(topic, retyped.get(topic, typ), t, d) for topic, typ, t, d in PLANT]
    folder = tmp_path_factory.mktemp("types") / "run"
    write_messages(folder, messages)
    wrong = sorted(topic for topic, typ in retyped.items()
                   if typ != next(m[1] for m in PLANT if m[0] == topic))
    rep = _outcome(lambda: analyse(folder), folder)
    if not wrong:
        assert not isinstance(rep, BagError) and rep.n_vehicles == 4
        return
    assert isinstance(rep, BagError) and any(t in str(rep) for t in wrong), rep
