"""Replay: pacing logic without ROS, and a real replay_node heard by a raw subscriber."""
from __future__ import annotations

import shutil
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from std_msgs.msg import Bool

from conftest import executable
from ltd_brake_ros.recording.bag import BagWriter, parse_qos_profiles, qos_profiles_yaml, read_bag
from ltd_brake_ros.recording.player import Player
from ltd_brake_ros.recording.qos import qos_from_profile
from ltd_brake_ros.ros.messages import array_msg

SPEED, CMD = "/rt/vehicles/speed", "/rt/brake_command"


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    folder = tmp_path_factory.mktemp("replay") / "bag"
    with BagWriter(folder, chunk_size=512) as w:
        w.add_topic(SPEED, "std_msgs/msg/Float64MultiArray")
        w.add_topic(CMD, "std_msgs/msg/Bool", qos_profiles_yaml(depth=5))
        for i in range(40):
            t = 5_000_000_000 + i * 20_000_000  # 50 Hz of recorded time
            w.write(SPEED, serialize_message(array_msg("vehicle", np.full(1 + i % 5, i * 0.5))),
                    t)
            if i % 8 == 0:
                w.write(CMD, serialize_message(Bool(data=i >= 16)), t)
    return folder


# --------------------------------------------------------------------------- Player, no ROS


def test_player_publishes_everything_in_recorded_order(bag):
    got, clock = [], []
    player = Player(bag, lambda *m: got.append(m), rate=0.0, clock=clock.append)
    assert player.run() == len(got) == 45
    assert got == list(read_bag(bag))
    assert clock == sorted(set(m[2] for m in got))


def test_player_restart_loop_skip(bag):
    got = []

    def publish(*m):
        got.append(m)
        if len(got) == 5:
            player.restart()
        if len(got) == 5 + 45 + 20:
            player.stop()

    player = Player(bag, publish, rate=0.0, loop=True, skip_topics={CMD})
    player.run()
    speeds = [m for m in read_bag(bag) if m[0] == SPEED]
    # 5 before the restart, then a full pass (40 speeds), then the second pass up to the stop
    assert got[:5] == speeds[:5] and got[5:45] == speeds
    assert player.passes == 1 and all(m[0] == SPEED for m in got)


def test_player_start_paused_then_resumed(bag):
    got = []
    player = Player(bag, lambda *m: got.append(m), rate=0.0, start_paused=True)
    th = threading.Thread(target=player.run)
    th.start()
    try:
        time.sleep(0.3)
        assert got == [] and player.paused
        player.pause(False)
        th.join(timeout=10)
        assert len(got) == 45
    finally:
        player.stop()
        th.join()


def test_player_clock_arithmetic_pause_and_rate(bag):
    now = [100.0]
    player = Player(bag, None, rate=2.0, monotonic=lambda: now[0])
    now[0] = 101.0
    assert player.position_ns() == pytest.approx(2e9)
    player.pause(True)
    now[0] = 111.0  # ten paused seconds do not count
    player.pause(False)
    assert player.position_ns() == pytest.approx(2e9)
    player.set_rate(0.5)
    now[0] = 113.0
    assert player.position_ns() == pytest.approx(2e9 + 1e9)
    with pytest.raises(ValueError):
        player.set_rate(-1.0)
    with pytest.raises(ValueError):
        Player(bag, None, rate=-1.0)


def test_player_waits_for_each_message_on_the_wall_clock(bag):
    """Recorded at 50 Hz, played at rate 2: each message 10 ms of wall time after the last."""
    now = [100.0]
    got = []

    def wait(event, timeout_s):  # the player's only way to let time pass
        now[0] += timeout_s
        return False

    player = Player(bag, lambda *m: got.append((now[0], m[2])), rate=2.0,
                    monotonic=lambda: now[0], wait=wait)
    assert player.run() == 45
    first_wall, first_ns = got[0]
    for wall, log_ns in got:
        assert wall == pytest.approx(first_wall + (log_ns - first_ns) * 1e-9 / 2.0, abs=1e-9)


def test_qos_round_trip_through_recorded_profile():
    original = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=7,
                          reliability=ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
    (profile,) = parse_qos_profiles(qos_profiles_yaml(original))
    qos = qos_from_profile(profile)
    assert (qos.history, qos.depth, qos.reliability, qos.durability) == \
        (original.history, 7, original.reliability, original.durability)
    assert qos_from_profile(None).reliability == ReliabilityPolicy.RELIABLE
    # rosbag2 version 8 files hold integers
    assert qos_from_profile({"history": 1, "depth": 3, "reliability": 2,
                             "durability": 2}).reliability == ReliabilityPolicy.BEST_EFFORT


def test_entry_point_is_installed():
    from importlib.metadata import entry_points

    scripts = {e.name: e.value for e in entry_points(group="console_scripts")}
    assert scripts.get("replay_node") == "ltd_brake_ros.ros.replay_node:main"


# --------------------------------------------------------------------------- real ROS


@pytest.mark.ros
def test_subscriber_receives_byte_identical_payloads_in_order(bag, processes, probe):
    from std_msgs.msg import Float64MultiArray
    from std_srvs.srv import SetBool

    expected = {SPEED: [], CMD: []}
    for topic, _typ, _t, data in read_bag(bag):
        expected[topic].append(data)
    probe.subscribe(SPEED, Float64MultiArray, raw=True)
    probe.subscribe(CMD, Bool, raw=True)
    probe.prepare("/replay_node", "pause")
    node = processes.start(executable("replay_node"), str(bag), "--ros-args",
                           "-p", "rate:=2.0", "-p", "start_paused:=true",
                           "-p", "wait_for_subscribers:=1", name="replay_node")
    # it plays nothing before every topic has a subscriber: the probe's readers are matched
    probe.wait_matched([SPEED, CMD])
    response = probe.call(SetBool, "/replay_node/pause", SetBool.Request(data=False))
    assert response.success and response.message == "playing"
    probe.spin_until(lambda: sum(map(len, probe.received.values())) >= 45, 60,
                     f"45 replayed messages; replay_node said:\n{node.output()}")
    # DDS orders samples per topic (one writer each), not across topics
    assert dict(probe.received) == expected
    assert node.wait(30) == 0  # without loop it ends by itself once everything is delivered


def _raw_bag(path, schema_name: str) -> None:
    """A one-topic MCAP whose message type is ``schema_name`` (BagWriter only takes installed
    types)."""
    from mcap.writer import Writer

    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        sid = w.register_schema(name=schema_name, encoding="ros2msg", data=b"float64 data")
        cid = w.register_channel(topic="/odd/x", message_encoding="cdr", schema_id=sid)
        for i in range(3):
            w.add_message(channel_id=cid, log_time=i * 1000, publish_time=i * 1000,
                          data=b"\0\1\0\0" + bytes(8), sequence=i)
        w.finish()


def _hostile_recordings(bag, tmp: Path) -> dict[str, tuple[list[str], str]]:
    """Recordings (and command lines) replay_node must refuse: name -> (arguments, text the
    one line must hold)."""
    cases = {}
    for name, text, expect in (("not_yaml", "{[: :", "metadata.yaml"),
                               ("a_list", "- 1\n- 2\n", "rosbag2_bagfile_information"),
                               ("wrong_files", "rosbag2_bagfile_information:\n"
                                "  relative_file_paths: [elsewhere.mcap]\n", "elsewhere.mcap")):
        folder = tmp / name
        shutil.copytree(bag, folder)
        (folder / "metadata.yaml").write_text(text)
        cases[f"metadata.yaml {name}"] = ([str(folder)], expect)
    # two runs' files in one folder, no metadata.yaml: never played as one
    mixed = tmp / "mixed"
    mixed.mkdir()
    for k in (1, 2):
        with BagWriter(tmp / f"run{k}", metadata={"run": k}) as w:
            w.add_topic(CMD, "std_msgs/msg/Bool")
            w.write(CMD, serialize_message(Bool(data=True)), k * 1_000_000_000)
        shutil.copy(tmp / f"run{k}" / f"run{k}_0.mcap", mixed / f"part{k}.mcap")
    cases["two runs"] = ([str(mixed)], "part1.mcap and part2.mcap")
    for name, schema in (("uninstalled", "foo_msgs/msg/Bar"), ("malformed", "notatype")):
        _raw_bag(tmp / f"{name}.mcap", schema)
        cases[f"{name} type"] = ([str(tmp / f"{name}.mcap")], f"/odd/x: cannot be replayed")
    cases["misspelt parameter"] = ([str(bag), "--ros-args", "-p", "rat:=2.0"],
                                   "parameter rat: replay_node has no such parameter "
                                   "(did you mean rate?)")
    cases["negative rate"] = ([str(bag), "--ros-args", "-p", "rate:=-1.0"], "parameter rate")
    cases["stray argument"] = ([str(bag), "extra"], "unexpected argument 'extra'")
    cases["no recording"] = ([], "parameter bag: no recording given")
    cases["missing params file"] = ([str(bag), "--ros-args", "--params-file", "/nonexistent.yaml"],
                                    "--params-file /nonexistent.yaml: no such file")
    return cases


@pytest.mark.ros
def test_a_recording_or_command_line_that_cannot_be_played_is_one_line(bag, processes,
                                                                       tmp_path):
    cases = _hostile_recordings(bag, tmp_path)
    # a chunk damaged further in: found while playing, after the messages before it
    damaged = tmp_path / "damaged"
    with BagWriter(damaged, chunk_size=600, compression="none") as w:
        w.add_topic(SPEED, "std_msgs/msg/Float64MultiArray")
        for i in range(60):
            w.write(SPEED, serialize_message(array_msg("vehicle", np.full(3, 1.0 * i))),
                    i * 20_000_000)
    file = damaged / "damaged_0.mcap"
    data = bytearray(file.read_bytes())
    data[len(data) // 2] ^= 0xFF
    file.write_bytes(bytes(data))
    cases["damaged chunk"] = ([str(damaged), "--ros-args", "-p", "rate:=0.0"],
                              f"replay failed after ")
    procs = {name: processes.start(executable("replay_node"), *args,
                                   name=name.replace(" ", "_").replace(".", "_"))
             for name, (args, _) in cases.items()}
    for name, proc in procs.items():
        status = proc.wait(60)
        out = proc.output().strip()
        lines = out.splitlines()
        assert status == 1, f"{name}: exit status {status}\n{out}"
        assert lines and all(line.startswith("[") for line in lines), f"{name}:\n{out}"
        assert cases[name][1] in lines[-1], f"{name}:\n{out}"
        if name != "damaged chunk":
            assert len(lines) == 1 and "cannot start: " in out, f"{name}:\n{out}"
    assert str(file) in procs["damaged chunk"].output()
