"""Recording layer: MCAP/rosbag2 layout, independent readers, crash tolerance, recovery."""
from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Reader as RosbagsReader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64

from bag_helpers import array_msg
from ltd_brake_ros.recording.qos import parse_qos_profiles, qos_profiles_yaml
from ltd_brake_ros.recording.reader import TruncatedBagWarning, bag_info, read_bag
from ltd_brake_ros.recording.recover import recover
from ltd_brake_ros.recording.ros_types import message_definition, type_description_hash, type_name
from ltd_brake_ros.recording.writer import BagWriter

REPO = Path(__file__).resolve().parents[2]
SEP = "=" * 80

FLOAT64_MULTIARRAY_TEXT = f"""\
# This was originally provided as an example message.
# It is deprecated as of Foxy
# It is recommended to create your own semantically meaningful message.
# However if you would like to continue using this please use the equivalent in example_msgs.

# Please look at the MultiArrayLayout message definition for
# documentation on all multiarrays.

MultiArrayLayout  layout        # specification of data layout
float64[]         data          # array of data

{SEP}
MSG: std_msgs/MultiArrayLayout
# This was originally provided as an example message.
# It is deprecated as of Foxy
# It is recommended to create your own semantically meaningful message.
# However if you would like to continue using this please use the equivalent in example_msgs.

# The multiarray declares a generic multi-dimensional array of a
# particular data type.  Dimensions are ordered from outer most
# to inner most.
#
# Accessors should ALWAYS be written in terms of dimension stride
# and specified outer-most dimension first.
#
# multiarray(i,j,k) = data[data_offset + dim_stride[1]*i + dim_stride[2]*j + k]
#
# A standard, 3-channel 640x480 image with interleaved color channels
# would be specified as:
#
# dim[0].label  = "height"
# dim[0].size   = 480
# dim[0].stride = 3*640*480 = 921600  (note dim[0] stride is just size of image)
# dim[1].label  = "width"
# dim[1].size   = 640
# dim[1].stride = 3*640 = 1920
# dim[2].label  = "channel"
# dim[2].size   = 3
# dim[2].stride = 3
#
# multiarray(i,j,k) refers to the ith row, jth column, and kth channel.

MultiArrayDimension[] dim # Array of dimension properties
uint32 data_offset        # padding bytes at front of data

{SEP}
MSG: std_msgs/MultiArrayDimension
# This was originally provided as an example message.
# It is deprecated as of Foxy
# It is recommended to create your own semantically meaningful message.
# However if you would like to continue using this please use the equivalent in example_msgs.

string label   # label of given dimension
uint32 size    # size of given dimension (in type units)
uint32 stride  # stride of given dimension
"""

TYPES = {"F64A": "std_msgs/msg/Float64MultiArray", "BOOL": "std_msgs/msg/Bool",
         "F64": "std_msgs/msg/Float64", "CLOCK": "rosgraph_msgs/msg/Clock",
         "DIAG": "diagnostic_msgs/msg/DiagnosticArray"}
RUN_INFO = {"consist": {"name": "E402B + 3 wagons", "vehicles": 4, "length_m": 57.3},
            "initial_speed_kmh": 100.0, "scenario": "unit test", "parameters": {"rate": 50}}


def _stamp(t_ns):
    return Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)


def _diag(i, t_ns):
    msg = DiagnosticArray(status=[DiagnosticStatus(
        level=DiagnosticStatus.WARN if i % 2 else DiagnosticStatus.OK, name="sim_node: plant",
        message=f"tick {i}", hardware_id="ltd",
        values=[KeyValue(key="rtf", value=f"{1.0 + i / 10:.2f}")])])
    msg.header.stamp = _stamp(t_ns)
    msg.header.frame_id = "train"
    return msg


def _messages(n=60, n_vehicles=4):
    """Published messages of every recorded type: (topic, type, t_ns, msg, plain values)."""
    rng = np.random.default_rng(7)
    out = []
    for i in range(n):
        t = 1_000_000_000 + i * 20_000_000
        v = rng.normal(size=n_vehicles)
        c = rng.normal(size=n_vehicles - 1) * 1e5
        out.append(("/clock", TYPES["CLOCK"], t, Clock(clock=_stamp(t)), t))
        out.append(("/train/vehicles/speed", TYPES["F64A"], t, array_msg(v, "vehicle"),
                    v.tolist()))
        out.append(("/train/couplers/force", TYPES["F64A"], t, array_msg(c, "coupler"),
                    c.tolist()))
        if i % 10 == 3:
            out.append(("/train/brake_command", TYPES["BOOL"], t, Bool(data=i > 20), i > 20))
            out.append(("/train/brake_demand", TYPES["F64"], t, Float64(data=i / 100), i / 100))
        if i % 25 == 0:
            out.append(("/diagnostics", TYPES["DIAG"], t, _diag(i, t), f"tick {i}"))
    return [(topic, typ, t, serialize_message(m), m, plain) for topic, typ, t, m, plain in out]


def _write(folder, messages, **kw):
    clock_qos = qos_profiles_yaml(QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    with BagWriter(folder, metadata=RUN_INFO, **kw) as w:
        for topic, typ, *_ in messages:
            w.add_topic(topic, typ, clock_qos if topic == "/clock" else None)
        for topic, typ, t, data, *_ in messages:
            w.write(topic, data, t)
    return w


def _plain(topic, msg):
    """Comparable values of a decoded message (rclpy, mcap_ros2 or rosbags object)."""
    if topic == "/clock":
        return msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
    if topic.endswith(("speed", "force")):
        assert msg.layout.dim[0].label in ("vehicle", "coupler")
        assert msg.layout.dim[0].size == len(msg.data)
        return [float(x) for x in msg.data]
    if topic == "/diagnostics":
        assert msg.header.frame_id == "train"
        return msg.status[0].message
    return msg.data


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bags") / "roundtrip"
    messages = _messages()
    _write(folder, messages, chunk_size=4096)
    return folder, messages


# --------------------------------------------------------------------------- schema text


def test_schema_text_matches_rosbag2_layout_for_float64multiarray():
    assert message_definition(TYPES["F64A"]) == FLOAT64_MULTIARRAY_TEXT


def test_nested_definitions_each_once_depth_first():
    text = message_definition(TYPES["DIAG"])
    headers = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert headers == ["MSG: diagnostic_msgs/DiagnosticStatus", "MSG: diagnostic_msgs/KeyValue",
                       "MSG: std_msgs/Header", "MSG: builtin_interfaces/Time"]
    assert text.count(SEP) == 4
    assert message_definition(TYPES["CLOCK"]).count("MSG: builtin_interfaces/Time") == 1
    assert SEP not in message_definition(TYPES["BOOL"])


@pytest.mark.parametrize("name", sorted(TYPES.values()))
def test_schema_text_parses_with_rosbags_and_hash_is_known(name):
    types = get_types_from_msg(message_definition(name), name)
    assert name in types
    assert type_description_hash(name).startswith("RIHS01_")


# --------------------------------------------------------------------------- round trip


def test_layout_is_a_rosbag2_folder(recorded):
    folder, messages = recorded
    assert sorted(p.name for p in folder.iterdir()) == ["metadata.yaml", "roundtrip_0.mcap"]
    info = yaml.safe_load((folder / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["roundtrip_0.mcap"]
    assert info["message_count"] == len(messages) == info["files"][0]["message_count"]
    times = [m[2] for m in messages]
    assert info["starting_time"]["nanoseconds_since_epoch"] == min(times)
    assert info["duration"]["nanoseconds"] == max(times) - min(times)
    counts = {t["topic_metadata"]["name"]: t["message_count"]
              for t in info["topics_with_message_count"]}
    assert counts == {topic: sum(m[0] == topic for m in messages) for topic in counts}
    for t in info["topics_with_message_count"]:
        md = t["topic_metadata"]
        assert md["serialization_format"] == "cdr"
        assert md["type_description_hash"] == type_description_hash(md["type"])
        (qos,) = md["offered_qos_profiles"]
        assert qos["reliability"] == ("best_effort" if md["name"] == "/clock" else "reliable")
        assert qos["durability"] == "volatile" and qos["history"] == "keep_last"
    assert json.loads(info["custom_data"]["consist"]) == RUN_INFO["consist"]
    assert info["ros_distro"] == "jazzy"


def test_mcap_records_follow_the_ros2_profile(recorded):
    folder, messages = recorded
    with open(folder / "roundtrip_0.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary.statistics.message_count == len(messages)
        assert len(summary.chunk_indexes) == summary.statistics.chunk_count > 3
        assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
        assert all(c.message_index_offsets for c in summary.chunk_indexes)
        for schema in summary.schemas.values():
            assert schema.encoding == "ros2msg"
            assert schema.data.decode() == message_definition(schema.name)
        for channel in summary.channels.values():
            assert channel.message_encoding == "cdr"
            assert channel.topic.startswith("/")
            assert parse_qos_profiles(channel.metadata["offered_qos_profiles"])
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    # the rosbag2 record must be complete (with serialized_metadata), else rosbag2 reads the
    # QoS strings as version-8 integers
    serialized = yaml.safe_load(meta["rosbag2"]["serialized_metadata"])
    on_disk = yaml.safe_load((folder / "metadata.yaml").read_text())
    assert serialized == on_disk["rosbag2_bagfile_information"]
    assert json.loads(meta["ltd_brake_ros.run"]["parameters"]) == {"rate": 50}


def test_round_trip_mcap_reader_with_ros2_decoder(recorded):
    folder, messages = recorded
    with open(folder / "roundtrip_0.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        got = [(c.topic, s.name, m.log_time, m.publish_time, bytes(m.data), _plain(c.topic, d))
               for s, c, m, d in reader.iter_decoded_messages(log_time_order=False)]
    assert got == [(topic, typ, t, t, data, plain)
                   for topic, typ, t, data, _msg, plain in messages]


def test_round_trip_rosbags_reader_and_typestore(recorded):
    folder, messages = recorded
    store = get_typestore(Stores.ROS2_JAZZY)
    by_topic = {}
    for topic, typ, t, data, _msg, plain in messages:
        by_topic.setdefault(topic, []).append((typ, t, data, plain))
    with RosbagsReader(folder) as reader:
        assert reader.message_count == len(messages)
        assert reader.ros_distro == "jazzy"
        conns = {c.topic: c for c in reader.connections}
        assert set(conns) == set(by_topic)
        for topic, conn in conns.items():
            assert conn.msgtype == by_topic[topic][0][0]
            assert conn.msgcount == len(by_topic[topic])
            assert conn.msgdef.data == message_definition(conn.msgtype)
            (qos,) = conn.ext.offered_qos_profiles
            assert qos.reliability.name == ("BEST_EFFORT" if topic == "/clock" else "RELIABLE")
            assert qos.durability.name == "VOLATILE" and qos.history.name == "KEEP_LAST"
            assert qos.depth == (1 if topic == "/clock" else 10)
        got = {}
        for conn, t, raw in reader.messages():
            msg = store.deserialize_cdr(raw, conn.msgtype)
            got.setdefault(conn.topic, []).append((conn.msgtype, t, bytes(raw),
                                                   _plain(conn.topic, msg)))
    assert got == by_topic


def test_read_bag_and_bag_info(recorded):
    folder, messages = recorded
    expected = [(topic, typ, t, data) for topic, typ, t, data, *_ in messages]
    assert list(read_bag(folder)) == expected
    assert list(read_bag(folder / "roundtrip_0.mcap")) == expected
    info = bag_info(folder)
    assert info.complete and info.metadata == RUN_INFO
    assert info.message_count == len(messages)
    assert info.topics["/clock"].qos_profiles[0]["depth"] == 1
    assert info.topics["/train/brake_demand"].msg_type == TYPES["F64"]


@pytest.mark.parametrize("compression", ["lz4", "none"])
def test_other_chunk_compressions(tmp_path, compression):
    messages = _messages(20)
    _write(tmp_path / "bag", messages, compression=compression, chunk_size=2048)
    with open(tmp_path / "bag" / "bag_0.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert {c.compression for c in summary.chunk_indexes} == {"lz4" if compression == "lz4"
                                                              else ""}
    assert [m[3] for m in read_bag(tmp_path / "bag")] == [m[3] for m in messages]


def test_qos_yaml_from_rclpy_profile_parses_with_rosbags():
    from rosbags.rosbag2.metadata import parse_qos

    text = qos_profiles_yaml(QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=0,
                                        reliability=ReliabilityPolicy.RELIABLE,
                                        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    (q,) = parse_qos(text)
    assert (q.history.name, q.reliability.name, q.durability.name) == \
        ("KEEP_ALL", "RELIABLE", "TRANSIENT_LOCAL")
    assert q.deadline.sec == 9223372036  # rmw's infinite, as rosbag2 records it
    assert parse_qos_profiles(text)[0]["history"] == "keep_all"


def test_type_name_of_messages_and_classes():
    assert type_name(Bool()) == TYPES["BOOL"]
    assert type_name(DiagnosticArray) == TYPES["DIAG"]
    assert type_name(Clock) == TYPES["CLOCK"]


def test_writer_rules(tmp_path):
    w = BagWriter(tmp_path / "b")
    with pytest.raises(ValueError, match="fully qualified"):
        w.add_topic("relative", TYPES["BOOL"])
    w.add_topic("/a", TYPES["BOOL"])
    w.add_topic("/a", TYPES["BOOL"])  # again: no-op
    with pytest.raises(ValueError, match="declared as"):
        w.add_topic("/a", TYPES["F64"])
    with pytest.raises(KeyError):
        w.write("/b", b"", 0)
    w.close()
    w.close()  # idempotent
    with pytest.raises(ValueError, match="closed"):
        w.write("/a", serialize_message(Bool()), 0)
    with pytest.raises(FileExistsError):
        BagWriter(tmp_path / "b")


def test_flush_interval_writes_chunks_without_close(tmp_path):
    w = BagWriter(tmp_path / "f", flush_interval_s=0.0)
    w.add_topic("/a", TYPES["BOOL"])
    for i in range(5):
        w.write("/a", serialize_message(Bool(data=bool(i % 2))), i)
    assert not w.flush_if_due()  # nothing pending: each write sealed its chunk
    w.flush()  # wait for the writer thread
    assert w.messages_on_disk == 5
    size = w.path.stat().st_size
    with pytest.warns(TruncatedBagWarning):
        assert len(list(read_bag(w.path))) == 5
    w.close()
    assert w.path.stat().st_size > size
    with open(w.path, "rb") as f:
        assert make_reader(f).get_summary().statistics.chunk_count == 5


# --------------------------------------------------------------------------- crash tolerance


def _chunk_map(path):
    """(end offset of each chunk record, messages in it) from the summary."""
    import io

    from mcap.data_stream import ReadDataStream
    from mcap.records import Chunk
    from mcap.stream_reader import breakup_chunk

    out = []
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        for ci in summary.chunk_indexes:
            f.seek(ci.chunk_start_offset + 9)
            chunk = Chunk.read(ReadDataStream(io.BytesIO(f.read(ci.chunk_length - 9))))
            msgs = [r.data for r in breakup_chunk(chunk) if hasattr(r, "log_time")]
            out.append((ci.chunk_start_offset + ci.chunk_length, msgs))
    return out


def _mcap_stream_prefix(path):
    """Messages the plain mcap StreamReader yields before the cut stops it."""
    got = []
    with open(path, "rb") as f:
        try:
            for record in StreamReader(f, validate_crcs=True).records:
                if type(record).__name__ == "Message":
                    got.append(record.data)
        except Exception:  # noqa: BLE001 - the cut ends the stream one way or another
            pass
    return got


def test_cut_at_random_offsets_then_recover(tmp_path, recorded):
    folder, messages = recorded
    src = folder / "roundtrip_0.mcap"
    chunks = _chunk_map(src)
    data = src.read_bytes()
    rng = random.Random(1234)
    ends = [end for end, _ in chunks]
    cuts = {0, 5, 8, 30, len(data) - 1, len(data) - 9, ends[0] - 1, ends[0], ends[2] + 3}
    cuts |= {rng.randrange(0, len(data)) for _ in range(24)}
    for cut in sorted(cuts):
        part = tmp_path / f"cut{cut}.mcap"
        part.write_bytes(data[:cut])
        expected = [m for end, msgs in chunks if end <= cut for m in msgs]
        assert _mcap_stream_prefix(part)[: len(expected)] == expected
        res = recover(part, tmp_path / f"rec{cut}")
        assert res["messages"] == len(expected) and not res["complete"]
        assert res["chunks"] == sum(end <= cut for end in ends)
        with open(tmp_path / f"rec{cut}" / f"rec{cut}_0.mcap", "rb") as f:
            reader = make_reader(f)
            assert reader.get_summary().statistics.message_count == len(expected)
            got = [m.data for _s, _c, m in reader.iter_messages(log_time_order=False)]
        assert got == expected
        if expected:  # topics, types and QoS survive: rosbags opens the folder
            with RosbagsReader(tmp_path / f"rec{cut}") as reader:
                assert [bytes(raw) for _c, _t, raw in reader.messages()] == \
                    [d for _topic, _typ, _t, d in read_bag(tmp_path / f"rec{cut}")]
                assert bag_info(tmp_path / f"rec{cut}").metadata == RUN_INFO


@pytest.mark.parametrize("full_at", [(0x06, 2), (0x07, 1), (0x07, 2)])
def test_messages_on_disk_are_what_recovers_wherever_the_disk_fills(tmp_path, full_at):
    # the file stops growing at the n-th record group of one kind the writer emits: a chunk
    # (opcode 0x06) or the message indexes after it (0x07), where a full disk may land
    # between a chunk and its indexes; what the writer calls on disk is what recovers
    opcode, nth = full_at
    w = BagWriter(tmp_path / "f", flush_interval_s=0.0)
    emit, seen = w._emit, [0]

    def filling(parts):
        if parts and parts[0][0] == opcode:
            seen[0] += 1
            if seen[0] >= nth:
                raise OSError(27, "File too large")
        emit(parts)

    w._emit = filling
    w.add_topic("/a", TYPES["BOOL"])
    for i in range(4):
        try:
            w.write("/a", serialize_message(Bool(data=True)), i)
            w.flush()
        except OSError:
            break
    assert 0 < w.messages_on_disk < 4
    w._emit = emit
    res = recover(tmp_path / "f", tmp_path / "copy")
    assert res["messages"] == w.messages_on_disk and not res["complete"], res


def test_recover_a_complete_bag_keeps_everything(tmp_path, recorded):
    folder, messages = recorded
    res = recover(folder, tmp_path / "copy")
    assert res["complete"] and res["messages"] == len(messages)
    assert list(read_bag(tmp_path / "copy")) == list(read_bag(folder))
    with RosbagsReader(tmp_path / "copy") as reader:
        qos = {c.topic: c.ext.offered_qos_profiles[0].depth for c in reader.connections}
    assert qos["/clock"] == 1


CHILD = textwrap.dedent("""
    import signal, sys
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64
    from ltd_brake_ros.recording.writer import BagWriter
    signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))
    with BagWriter(sys.argv[1], metadata={"child": True}, flush_interval_s=0.05) as w:
        w.add_topic("/x", "std_msgs/msg/Float64")
        print("ready", flush=True)
        i = on_disk = 0
        while True:
            w.write("/x", serialize_message(Float64(data=float(i))), i * 1000)
            i += 1
            if w.messages_on_disk != on_disk:  # a chunk reached the file
                on_disk = w.messages_on_disk
                print(on_disk, flush=True)
""")


def _run_child(tmp_path, sig, flushes=6):
    folder = tmp_path / "child"
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(folder)], stdout=subprocess.PIPE,
                            text=True, cwd=REPO)
    flushed = 0
    try:
        assert proc.stdout.readline().strip() == "ready"
        for _ in range(flushes):
            flushed = int(proc.stdout.readline())
        proc.send_signal(sig)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
    return folder, flushed


def _values(folder):
    from rclpy.serialization import deserialize_message

    return [deserialize_message(d, Float64).data for *_x, d in read_bag(folder)]


def test_sigkill_keeps_every_complete_chunk(tmp_path):
    folder, flushed = _run_child(tmp_path, signal.SIGKILL)
    assert not (folder / "metadata.yaml").exists()
    mcap_file = folder / "child_0.mcap"
    assert len(_mcap_stream_prefix(mcap_file)) >= flushed > 0
    with pytest.warns(TruncatedBagWarning):
        values = _values(folder)
    assert len(values) >= flushed and values == [float(i) for i in range(len(values))]
    res = recover(folder)
    assert res["output"] == str(tmp_path / "child_recovered")
    assert res["messages"] == len(values)
    assert _values(res["output"]) == values
    with RosbagsReader(Path(res["output"])) as reader:
        assert reader.message_count == len(values)
    assert bag_info(res["output"]).metadata == {"child": True}


def test_sigterm_finishes_the_file(tmp_path):
    folder, flushed = _run_child(tmp_path, signal.SIGTERM, flushes=3)
    info = bag_info(folder)
    assert info.complete and info.message_count >= flushed
    with RosbagsReader(folder) as reader:
        assert reader.message_count == info.message_count
    assert _values(folder) == [float(i) for i in range(info.message_count)]


def test_readers_never_write_beside_the_recording(recorded):
    folder, _ = recorded
    before = sorted(os.listdir(folder))
    list(read_bag(folder))
    bag_info(folder)
    assert sorted(os.listdir(folder)) == before


def test_recover_refuses_what_is_not_mcap(tmp_path):
    (tmp_path / "notes.mcap").write_bytes(b"hello, this is not a recording")
    with pytest.raises(McapError, match="not an MCAP file"):
        recover(tmp_path / "notes.mcap", tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_former_single_module_still_exports_the_api():
    from ltd_brake_ros.recording import bag

    assert bag.BagWriter is BagWriter and bag.read_bag is read_bag and bag.recover is recover
    assert set(bag.__all__) <= set(dir(bag))
