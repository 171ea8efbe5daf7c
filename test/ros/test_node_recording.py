"""What the running ``sim_node`` records: independent readers, counts, report, flushing.

The node runs as the installed executable in the session's private DDS domain. What it
published is known three ways, and the recording must agree with each: a probe subscriber with a
deep reliable queue (byte-identical payloads, in order), the node's own chunk count (its last log
line) and, for the run's physics, the offline simulator.
"""
from __future__ import annotations

import json

import math
import signal
import time

import pytest
import yaml
# a broken ROS installation fails these tests; it never skips them
from diagnostic_msgs.msg import DiagnosticArray
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.duration import Duration
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.rosbag2 import Reader as RosbagsReader
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger

from ltd_brake_ros.analysis.plots import write_plots
from ltd_brake_ros.analysis.report import analyse
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.recording.bag import bag_info, type_name
from ltd_brake_ros.studies.runs import emergency_stop
from node_helpers import (ARRAY_TOPICS, PNG, STATE_TOPICS, chunks_from_log, diagnostics_of,
                          node_argv, plain, read_mcap)

pytestmark = pytest.mark.ros

TYPES = {**{t: "std_msgs/msg/Float64MultiArray" for t in ARRAY_TOPICS},
         **{t: "sensor_msgs/msg/JointState" for t in STATE_TOPICS},
         "clock": "rosgraph_msgs/msg/Clock", "brake_command": "std_msgs/msg/Bool",
         "brake_demand": "std_msgs/msg/Float64", "traction_command": "std_msgs/msg/Float64",
         "driver_brake_valve": "std_msgs/msg/String"}
#: A reader queue no run of these tests can fill: the probe keeps every message it gets.
DEEP = 1_000_000


def _start(processes, ns, folder, *params, name=None):
    return processes.start(*node_argv(ns, "record:=true", f"record_dir:={folder}", *params),
                           name=name or ns.strip("/"))


def _wait_until_heard(probe, ns, node, proc, state: bool = True):
    """Wait until the probe hears the node (diagnostics arrive), so the node has discovered
    every endpoint the probe created before it started, and (``state``) the probe's readers
    of the node's state are matched."""
    diag = probe.received["/diagnostics"]
    probe.spin_until(lambda: diagnostics_of(
        [deserialize_message(d, DiagnosticArray) for d in diag[-3:]], node),
        60, f"diagnostics of {node}:\n{proc.output()}")
    if state:
        probe.wait_matched([f"{ns}/{t}" for t in ("clock", *ARRAY_TOPICS)])


def _missed(got: list, recorded: list) -> int:
    """How many of ``recorded`` a subscriber that received ``got`` did not get.

    ``got`` must be ``recorded`` with some messages left out, in the same order (it fails the
    test otherwise). A subscriber may miss some: the initial state published before it was
    matched, and under load what the writer's KEEP_LAST 10 history replaced before the reader
    acknowledged it. The recording must not miss any.
    """
    i = 0
    for k, item in enumerate(got):
        while i < len(recorded) and recorded[i] != item:
            i += 1
        assert i < len(recorded), f"message {k} received is not in the recording (or out of order)"
        i += 1
    return len(recorded) - len(got)


def _diagnostics_compared(received: list, recorded: list, node: str) -> tuple[list, list]:
    """Decoded diagnostics of ``node``: as a subscriber got them, and as recorded.

    Compared decoded: the padding bytes after a CDR ``byte`` (the status level) are not
    defined, so equal messages need not serialize to equal bytes.
    """
    def mine(payloads):
        msgs = [deserialize_message(bytes(d), DiagnosticArray) for d in payloads]
        return [plain(m) for m in msgs if diagnostics_of([m], node)]
    return mine(received), mine(d for _, _, d in recorded)


# --------------------------------------------------------------------------- round trip


def test_recorded_run_round_trips_through_independent_readers_and_reports_like_offline(
        processes, probe, tmp_path):
    ns, node = "/rec", "/rec/sim_node"
    folder = tmp_path / "run"
    scenario = get_scenario(6)
    for topic in (*ARRAY_TOPICS, "clock"):
        probe.subscribe(f"{ns}/{topic}", Float64MultiArray if topic != "clock" else Clock,
                        raw=True, depth=DEEP)
    probe.prepare(node, "set_parameters")
    probe.subscribe("/diagnostics", DiagnosticArray, raw=True, depth=DEEP)
    # the first chunk is due 20 s after start-up: time to match every reader before the run
    proc = _start(processes, ns, folder, "real_time_factor:=0.001", "auto_brake_at_s:=0.0",
                  "shutdown_after_stop_s:=1.0")
    _wait_until_heard(probe, ns, node, proc)

    # inputs: three that change nothing (emergency overrides service demand; lap holds) and
    # one rejected; every received command is recorded, rejected or not
    sent = [("brake_demand", Float64(data=0.0)), ("traction_command", Float64(data=0.0)),
            ("driver_brake_valve", String(data="lap")), ("brake_demand", Float64(data=math.nan))]
    for topic, msg in sent:
        probe.publish(f"{ns}/{topic}", msg)
    probe.spin_until(lambda: any(d.get("rejected_inputs") == "1" for d in diagnostics_of(
        [deserialize_message(x, DiagnosticArray) for x in probe.received["/diagnostics"][-3:]],
        node)), 20, "the node to handle the inputs")

    (switched,) = probe.set_parameters(node, real_time_factor=0.0)
    assert switched.successful, switched.reason
    end = time.monotonic() + 120
    while proc.popen.poll() is None and time.monotonic() < end:
        probe.spin_for(0.1)  # take every message while the node runs
    assert proc.wait(60) == 0, proc.output()
    probe.spin_for(0.5)
    out = proc.output()
    assert "Traceback" not in out, out
    chunks = chunks_from_log(out)
    stop_s = 29.6  # scenario 6 stops about here; one more second is recorded
    assert chunks * 0.02 > stop_s

    # --- the mcap reader: summary, types, counts, bytes
    summary, recorded = read_mcap(folder)
    assert summary is not None and summary.statistics is not None
    assert (folder / "metadata.yaml").is_file()
    expected_topics = {f"{ns}/{t}" for t in (*ARRAY_TOPICS, *STATE_TOPICS, "clock",
                                             "brake_command", "brake_demand",
                                             "traction_command", "driver_brake_valve",
                                             "train/description", "train/stops",
                                             "vehicles/block_temperature",
                                             "vehicles/wheel_temperature")} \
        | {"/diagnostics"}
    assert set(recorded) == expected_topics
    channels = {c.topic: c for c in summary.channels.values()}
    assert set(channels) == expected_topics
    for short, typ in TYPES.items():
        assert summary.schemas[channels[f"{ns}/{short}"].schema_id].name == typ, short
    assert summary.schemas[channels["/diagnostics"].schema_id].name == \
        "diagnostic_msgs/msg/DiagnosticArray"
    counts = summary.statistics.channel_message_counts
    assert summary.statistics.message_count == sum(len(v) for v in recorded.values())
    for topic, msgs in recorded.items():
        assert counts[channels[topic].id] == len(msgs), topic
        times = [t for t, _, _ in msgs]
        assert times == sorted(times), f"{topic}: log times go back"

    # count published = count recorded: every chunk, plus the initial state
    for topic in (*ARRAY_TOPICS, *STATE_TOPICS, "clock"):
        assert len(recorded[f"{ns}/{topic}"]) == chunks + 1, topic
    clock_ns = [t for t, _, _ in recorded[f"{ns}/clock"]]
    assert clock_ns == [k * 20_000_000 for k in range(chunks + 1)]
    # the inputs, as sent (the auto brake is a received command too, at t = 0); compared by
    # value: CDR padding bytes are not defined
    assert [(t, deserialize_message(d, Bool).data) for t, _, d in
            recorded[f"{ns}/brake_command"]] == [(0, True)]
    for short in ("brake_demand", "traction_command"):
        assert [repr(deserialize_message(d, Float64).data) for _, _, d in
                recorded[f"{ns}/{short}"]] == [repr(m.data) for t, m in sent if t == short]
    assert [deserialize_message(d, String).data for _, _, d in
            recorded[f"{ns}/driver_brake_valve"]] == ["lap"]
    # the train description once, at t = 0, as the run information of the recording says
    (t_desc, _, d_desc), = recorded[f"{ns}/train/description"]
    description = json.loads(deserialize_message(d_desc, String).data)
    assert t_desc == 0 and description["run"]["consist"]["vehicles"] == 33

    # --- what the subscriber received: byte-identical, in the recorded order
    for topic in (*ARRAY_TOPICS, "clock"):
        got = [bytes(d) for d in probe.received[f"{ns}/{topic}"]]
        bag = [bytes(d) for _, _, d in recorded[f"{ns}/{topic}"]]
        missed = _missed(got, bag)
        assert missed <= len(bag) // 2, f"{topic}: the probe got too little to compare"
    mine, bag_diag = _diagnostics_compared(probe.received["/diagnostics"],
                                           recorded["/diagnostics"], node)
    assert len(mine) >= 2 and _missed(mine, bag_diag) <= len(bag_diag) // 2

    # --- mcap + mcap_ros2 decoding (no rclpy): values equal rclpy's own decoding
    rclpy_types = {f"{ns}/{t}": Float64MultiArray for t in ARRAY_TOPICS} | {
        f"{ns}/{t}": JointState for t in STATE_TOPICS} | {
        f"{ns}/clock": Clock, "/diagnostics": DiagnosticArray, f"{ns}/brake_command": Bool}
    decoded = {}
    with open(next(folder.glob("*.mcap")), "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, msg in reader.iter_decoded_messages(
                log_time_order=False):
            decoded.setdefault(channel.topic, []).append((message.log_time, message.data, msg))
    assert {k: len(v) for k, v in decoded.items()} == {k: len(v) for k, v in recorded.items()}
    for topic, cls in rclpy_types.items():
        for log_time, data, msg in decoded[topic]:
            assert plain(msg) == plain(deserialize_message(data, cls)), topic
    final_speed = decoded[f"{ns}/vehicles/speed"][-1][2]
    assert final_speed.layout.dim[0].label == "vehicle" and len(final_speed.data) == 33
    assert max(abs(v) for v in final_speed.data) < 1e-2
    assert decoded[f"{ns}/couplers/force"][-1][2].layout.dim[0].size == 32

    # --- rosbags: folder reader and typestore agree message by message
    store = get_typestore(Stores.ROS2_JAZZY)
    meta = yaml.safe_load((folder / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    with RosbagsReader(folder) as reader:
        assert reader.message_count == summary.statistics.message_count == meta["message_count"]
        conns = {c.topic: c for c in reader.connections}
        assert set(conns) == expected_topics
        for short, typ in TYPES.items():
            assert conns[f"{ns}/{short}"].msgtype == typ
            assert conns[f"{ns}/{short}"].msgcount == len(recorded[f"{ns}/{short}"])
        via_rosbags = {}
        for conn, t, raw in reader.messages():
            via_rosbags.setdefault(conn.topic, []).append(
                (t, bytes(raw), store.deserialize_cdr(raw, conn.msgtype)))
    for topic, msgs in recorded.items():
        assert [(t, d) for t, d, _ in via_rosbags[topic]] == [(t, bytes(d)) for t, _, d in msgs]
    for topic in rclpy_types:
        assert [plain(m) for _, _, m in via_rosbags[topic]] == \
            [plain(m) for _, _, m in decoded[topic]], topic

    # --- the report on the recording equals the offline emergency stop
    ref = emergency_stop(scenario.consist(), scenario.speed_kmh)
    rep = analyse(folder)
    assert rep.complete and rep.namespace == ns
    assert rep.command_time_s == 0.0
    assert rep.stopping_distance_m == pytest.approx(ref.stopping_distance_m, rel=5e-3)
    assert rep.stopping_time_s == pytest.approx(ref.stop_time_s, abs=0.1)
    assert (rep.peak_draft_coupler, rep.peak_buff_coupler) == \
        (ref.peak_draft_coupler, ref.peak_buff_coupler)
    assert rep.peak_draft_kN == pytest.approx(ref.peak_draft_kN, rel=1e-2)
    assert rep.peak_buff_kN == pytest.approx(ref.peak_buff_kN, rel=1e-2)
    assert rep.metadata["consist"]["name"] == scenario.consist().name
    # the stop as the plant judged it, closed with its verdicts when the node shut down
    (stop,) = rep.stops
    assert (stop["command"], stop["command_time_s"], stop["end"]) == \
        ("emergency", 0.0, "end of run")
    assert stop["stopping_distance_m"] == pytest.approx(ref.stopping_distance_m, rel=5e-3)
    assert stop["verdict"] == rep.verdicts.status
    plots = write_plots(rep, tmp_path / "plots")
    # speed, brake force, coupler peaks and map, and the brake heat every run now records
    assert [p.name for p in plots] == ["speed.png", "brake_force.png", "coupler_peaks.png",
                                       "coupler_force_map.png", "brake_temperature.png"]
    for p in plots:
        assert p.read_bytes()[:8] == PNG and p.stat().st_size > 10_000, p


# --------------------------------------------------------------------------- long run


@pytest.mark.slow
def test_long_free_running_record_loses_nothing(processes, probe, tmp_path):
    """Four minutes of simulated time as fast as possible, commands arriving meanwhile.

    The order is explicit: the probe's publisher keeps every command until the node's reader
    has acknowledged it; only once the node reports that it handled all of them and simulated
    four minutes does the probe pause it (between two chunks) and end it with SIGINT, which
    finishes the bag. Ending at max_sim_time_s instead would race the commands (at full speed
    the plant can get there before the last one arrives), and a signal alone could land
    between two topics of a chunk. That max_sim_time_s ends after exactly its chunks is
    tested in the plant and by the start-up test.
    """
    ns, node = "/long", "/long/sim_node"
    folder = tmp_path / "long"
    sim_s = 240.0
    values = [round(0.001 * i, 3) for i in range(1, 201)]
    # the probe's endpoints exist before the node starts: the node discovers them together,
    # and its diagnostics reaching the probe show it has
    commands = probe.node.create_publisher(
        Float64, f"{ns}/brake_demand",
        QoSProfile(depth=len(values), reliability=ReliabilityPolicy.RELIABLE))
    probe.prepare(node, "set_parameters", "pause")
    probe.subscribe("/diagnostics", DiagnosticArray, raw=True, depth=DEEP)
    proc = _start(processes, ns, folder, "real_time_factor:=0.001")
    _wait_until_heard(probe, ns, node, proc, state=False)
    probe.spin_until(lambda: commands.get_subscription_count() > 0, 60,
                     f"the node's subscription to {ns}/brake_demand")
    (switched,) = probe.set_parameters(node, real_time_factor=0.0)
    assert switched.successful, switched.reason
    # service-brake demands while the plant runs flat out: each one must be in the bag
    for v in values:
        commands.publish(Float64(data=v))
        probe.spin_for(0.002)
    assert commands.wait_for_all_acked(Duration(seconds=30)), "the node did not take them all"

    def report():
        found = diagnostics_of([deserialize_message(d, DiagnosticArray)
                                for d in probe.received["/diagnostics"][-3:]], node)
        return found[-1] if found else {}
    probe.spin_until(lambda: int(report().get("inputs_handled", -1)) == len(values)
                     and float(report()["sim_time_s"]) >= sim_s, 120,
                     f"the node to handle {len(values)} commands and simulate {sim_s:g} s")
    assert report()["state"] == "running" and report()["brake_demand"] == "0.2"
    reply = probe.call(SetBool, f"{node}/pause", SetBool.Request(data=True))
    assert reply.success, reply.message
    paused_at_s = float(reply.message.split("t = ")[1].split()[0])
    assert proc.stop(signal.SIGINT) == 0, proc.output()
    probe.spin_for(0.5)
    out = proc.output()
    assert "Traceback" not in out, out
    chunks = chunks_from_log(out)
    assert chunks == round(paused_at_s / 0.02) and chunks >= round(sim_s / 0.02)

    summary, recorded = read_mcap(folder)
    assert summary is not None
    for topic in (*ARRAY_TOPICS, "clock"):
        assert len(recorded[f"{ns}/{topic}"]) == chunks + 1, topic
    got = [deserialize_message(d, Float64).data for _, _, d in recorded[f"{ns}/brake_demand"]]
    assert got == values, "a command the probe sent is missing from the recording"
    # every chunk flush and size seal kept the file consistent: the indexes cover it all
    assert summary.statistics.chunk_count >= 2
    assert sum(len(v) for v in recorded.values()) == summary.statistics.message_count
    mine, bag_diag = _diagnostics_compared(probe.received["/diagnostics"],
                                           recorded["/diagnostics"], node)
    assert mine and _missed(mine, bag_diag) <= len(bag_diag) // 2
    last = diagnostics_of([deserialize_message(recorded["/diagnostics"][-1][2],
                                               DiagnosticArray)], node)[-1]
    assert int(last["chunks"]) <= chunks
    info = bag_info(folder)
    assert info.complete and info.message_count == summary.statistics.message_count


# --------------------------------------------------------------------------- flushing when idle


def test_idle_plant_still_flushes_its_chunks_within_a_second(processes, probe, tmp_path):
    """In lock-step mode the plant sleeps between calls: what a call produced reaches the
    file anyway, within the flush interval (1 s) plus a margin, without closing the bag."""
    ns, node = "/idle", "/idle/sim_node"
    folder = tmp_path / "idle"
    probe.prepare(node, "step")
    probe.subscribe("/diagnostics", DiagnosticArray, raw=True, depth=DEEP)
    proc = _start(processes, ns, folder, "lockstep:=true", "steps_per_call:=5")
    _wait_until_heard(probe, ns, node, proc, state=False)
    file = folder / "idle_0.mcap"
    delays = []
    for call in (1, 2):
        reply = probe.call(Trigger, f"{node}/step", Trigger.Request())
        assert reply.success, reply.message
        done = time.monotonic()
        want = 1 + 5 * call  # the initial state, then five chunks per call
        while True:
            info = bag_info(file)  # no summary yet: a scan up to the last complete chunk
            assert not info.complete
            clock = info.topics.get(f"{ns}/clock")
            if clock is not None and clock.message_count >= want:
                break
            assert time.monotonic() - done < 10, "the chunk never reached the file"
            time.sleep(0.02)
        delays.append(time.monotonic() - done)
        time.sleep(0.5)
    # a chunk is handed over at most 1 s after the previous one; a margin for the machine
    assert max(delays) < 1.5, delays
    assert proc.stop(signal.SIGINT) == 0, proc.output()
    assert bag_info(folder).complete


def test_report_of_a_bag_recorded_by_another_recorder_reads_simulated_time(
        processes, probe, tmp_path):
    """A recorder that logs receive times (as ``ros2 bag record`` does) of a run at 4x real
    time: the report takes time from the states' stamps and the train from the latched
    description, and stops where the node's own recording says, within one chunk's travel."""
    import os

    from rclpy.qos import DurabilityPolicy

    from ltd_brake_ros.recording.writer import BagWriter

    ns, own = "/other", tmp_path / "own"
    types = {**{f"{ns}/{t}": Float64MultiArray for t in ARRAY_TOPICS},
             **{f"{ns}/{t}": JointState for t in STATE_TOPICS},
             f"{ns}/clock": Clock, f"{ns}/brake_command": Bool,
             f"{ns}/train/description": String}
    import threading

    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    heard = []  # (topic, receive time [ns], bytes): what a bag recorder stores
    # the recorder spins on a thread of its own, as ros2 bag record does: receive times are
    # when messages arrive, not when the test gets round to them
    recorder = rclpy.create_node(f"bag_recorder_{os.getpid()}", context=probe.node.context)
    executor = SingleThreadedExecutor(context=probe.node.context)
    executor.add_node(recorder)
    subs = {}
    for topic, cls in types.items():
        latched = topic.endswith("description")
        qos = QoSProfile(depth=DEEP, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                         else DurabilityPolicy.VOLATILE)
        subs[topic] = recorder.create_subscription(
            cls, topic, lambda data, topic=topic: heard.append((topic, time.time_ns(), data)),
            qos, raw=True)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.005)

    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()
    node = f"{ns}/sim_node"
    probe.prepare(node, "pause")
    try:
        proc = _start(processes, ns, own, "consist:=scenario_1", "real_time_factor:=4.0",
                      "shutdown_after_stop_s:=1.0")
        probe.spin_until(lambda: all(s.get_publisher_count() for t, s in subs.items()
                                     if not t.endswith("brake_command")), 120,
                         "the recorder matched with the plant")
        probe.spin_until(lambda: sum(t == f"{ns}/vehicles/state" for t, _, _ in heard) > 20,
                         60, "states at 4x real time")
        # the plant's reader of the command matched: a release it has handled (reported in
        # its diagnostics), then the emergency command a controller would send
        probe.subscribe("/diagnostics", DiagnosticArray)
        probe.publish(f"{ns}/brake_command", Bool(data=False))
        probe.spin_until(lambda: any(int(d.get("inputs_handled", 0)) >= 1 for d in
                                     diagnostics_of(probe.received["/diagnostics"],
                                                    f"{ns}/sim_node")), 30,
                         "the plant to handle the release")
        # the emergency command, given while the plant is paused: it applies from the state
        # the recorder heard last, whatever the machine's delays (free-running, the plant may
        # advance a few chunks between the two receipts)
        reply = probe.call(SetBool, f"{node}/pause", SetBool.Request(data=True))
        assert reply.success, reply.message
        probe.publish(f"{ns}/brake_command", Bool(data=True))
        probe.spin_until(lambda: any(int(d.get("inputs_handled", 0)) >= 2 for d in
                                     diagnostics_of(probe.received["/diagnostics"], node))
                         and sum(t.endswith("brake_command") for t, _, _ in heard) >= 2, 30,
                         "the plant and the recorder to take the emergency command")
        reply = probe.call(SetBool, f"{node}/pause", SetBool.Request(data=False))
        assert reply.success, reply.message
        probe.spin_until(lambda: proc.popen.poll() is not None, 120,
                         "the stop and the node's end")
        assert proc.wait(30) == 0, proc.output()
    finally:
        stop.set()
        spinner.join(5)
        executor.shutdown()
        recorder.destroy_node()
    assert any(t.endswith("brake_command") for t, _, _ in heard)
    other = tmp_path / "other"
    writer = BagWriter(other)  # no run information: only messages at receive times
    for topic, cls in types.items():
        writer.add_topic(topic, type_name(cls))
    for topic, t_ns, data in sorted(heard, key=lambda h: h[1]):
        writer.write(topic, bytes(data), t_ns)
    writer.close()

    mine, theirs = analyse(own), analyse(other)
    assert theirs.stamped and not mine.stamped
    assert theirs.start_time_s < 60.0 < time.time()  # simulated seconds, not an epoch
    assert theirs.metadata["consist"]["vehicles"] == mine.metadata["consist"]["vehicles"] == 11
    assert any("simulated times stamped" in n for n in theirs.notes)
    assert any("run information from" in n for n in theirs.notes)
    # the command applies from the state it follows: the same chunk for the paused plant and
    # the recorder (0.02 s; 0.45 m at 80 km/h)
    print(f"\nanother recorder: command at t = {theirs.command_time_s:.3f} s, the plant's own "
          f"recording at {mine.command_time_s:.3f} s")
    assert theirs.command_time_s == pytest.approx(mine.command_time_s, abs=0.021)
    assert theirs.stopping_distance_m == pytest.approx(mine.stopping_distance_m, abs=1.0)
    assert theirs.peak_buff_kN == pytest.approx(mine.peak_buff_kN, rel=1e-9)
