"""Replay: pacing logic without ROS, and a real replay_node heard by a raw subscriber."""
from __future__ import annotations

import threading
import time

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
    node = processes.start(executable("replay_node"), str(bag), "--ros-args",
                           "-p", "rate:=2.0", "-p", "start_paused:=true",
                           "-p", "wait_for_subscribers:=1", name="replay_node")
    response = probe.call(SetBool, "/replay_node/pause", SetBool.Request(data=False))
    assert response.success and response.message == "playing"
    probe.spin_until(lambda: sum(map(len, probe.received.values())) >= 45, 60,
                     f"45 replayed messages; replay_node said:\n{node.output()}")
    # DDS orders samples per topic (one writer each), not across topics
    assert dict(probe.received) == expected
    assert node.wait(30) == 0  # without loop it ends by itself once everything is delivered
