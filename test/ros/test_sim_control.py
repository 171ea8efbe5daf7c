"""The installed sim_node under ROS's standard simulation control (``simulation_interfaces``),
a step of any length that stays interruptible, and a recording with the frames, replayed.

The node runs as a separate process (its own multi-threaded executor, as users run it); the
probe calls its services and reads what it publishes and records.
"""
from __future__ import annotations

import signal
import time

import pytest
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock

from conftest import executable
from ltd_brake_ros.recording.bag import bag_info, message_class, read_bag
from node_helpers import node_argv

pytestmark = pytest.mark.ros

si_msg = pytest.importorskip("simulation_interfaces.msg", reason="./dev.sh builds it")
from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures  # noqa: E402
from simulation_interfaces.srv import (GetSimulationState, GetSimulatorFeatures,  # noqa: E402
                                       ResetSimulation, SetSimulationState, StepSimulation)
from rcl_interfaces.srv import GetParameters  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

CHUNK_NS = 20_000_000
#: A step no test waits for: it must end by interruption.
ENDLESS = 10**12


def _ns(clock: Clock) -> int:
    return clock.clock.sec * 1_000_000_000 + clock.clock.nanosec


def _state(state: int) -> SetSimulationState.Request:
    return SetSimulationState.Request(state=SimulationState(state=state))


def test_standard_simulation_control_of_a_lock_step_plant(processes, probe):
    ns = "/sictl"
    node = f"{ns}/sim_node"
    types = {"get_simulator_features": GetSimulatorFeatures,
             "get_simulation_state": GetSimulationState,
             "set_simulation_state": SetSimulationState, "step_simulation": StepSimulation,
             "reset_simulation": ResetSimulation, "pause": SetBool,
             "get_parameters": GetParameters}
    for name, srv in types.items():  # before the node starts: it discovers them with the rest
        probe.client(srv, f"{node}/{name}")
    probe.subscribe(f"{ns}/clock", Clock)
    proc = processes.start(*node_argv(ns, "lockstep:=true", "consist:=scenario_1"), name="sim_node")

    def call(name, request=None, timeout_s=30.0):
        return probe.call(types[name], f"{node}/{name}", request or types[name].Request(),
                          timeout_s=timeout_s)

    def clock_ns() -> int:
        return _ns(probe.received[f"{ns}/clock"][-1])

    features = call("get_simulator_features", timeout_s=60).features
    f = SimulatorFeatures
    assert set(features.features) == {f.SIMULATION_RESET, f.SIMULATION_STATE_GETTING,
                                      f.SIMULATION_STATE_SETTING, f.SIMULATION_STATE_PAUSE,
                                      f.STEP_SIMULATION_SINGLE, f.STEP_SIMULATION_MULTIPLE}
    assert "chunk_s" in features.custom_info and not features.spawn_formats
    s = SimulationState
    assert call("get_simulation_state").state.state == s.STATE_PAUSED

    reply = call("step_simulation", StepSimulation.Request(steps=7))
    assert reply.result.result == Result.RESULT_OK, reply.result.error_message
    probe.spin_until(lambda: probe.received[f"{ns}/clock"] and clock_ns() == 7 * CHUNK_NS, 10,
                     "the clock after 7 steps")
    reply = call("set_simulation_state", _state(s.STATE_PLAYING))
    assert reply.result.result == SetSimulationState.Response.INCORRECT_TRANSITION
    assert "lockstep" in reply.result.error_message
    reply = call("reset_simulation", ResetSimulation.Request(scope=ResetSimulation.Request.SCOPE_TIME))
    assert reply.result.result == Result.RESULT_FEATURE_UNSUPPORTED
    assert call("reset_simulation").result.result == Result.RESULT_OK
    probe.spin_until(lambda: clock_ns() == 0, 10, "the clock back at 0 after the reset")

    # a step of any length: pause, parameter and state requests are answered while it runs,
    # and the pause ends it where it was served
    step = probe.client(StepSimulation, f"{node}/step_simulation").call_async(
        StepSimulation.Request(steps=ENDLESS))
    probe.spin_until(lambda: probe.received[f"{ns}/clock"] and clock_ns() > 0, 20,
                     "the long step to run")
    rtf = probe.call(GetParameters, f"{node}/get_parameters",
                     GetParameters.Request(names=["real_time_factor"]))
    assert rtf.values[0].double_value == 1.0 and not step.done()
    state = call("get_simulation_state")
    assert state.state.state == s.STATE_PAUSED and not step.done()
    paused = call("pause", SetBool.Request(data=True))
    assert paused.success and not step.done() or step.done()
    probe.spin_until(step.done, 10, "the long step to end after the pause")
    result = step.result().result
    assert result.result == Result.RESULT_OPERATION_FAILED
    assert result.error_message.startswith("interrupted by a pause after ")
    assert f"of {ENDLESS} chunks" in result.error_message
    # the step ended at the chunk the pause was served after
    paused_at = paused.message.split("t = ")[1].split(" s")[0]
    assert f"to t = {paused_at} s with" in result.error_message
    reply = call("step_simulation")
    assert reply.result.result == Result.RESULT_OPERATION_FAILED  # held by the pause
    # PAUSED lets the held lock-step plant be stepped again
    assert call("set_simulation_state", _state(s.STATE_PAUSED)).result.result == \
        Result.RESULT_OK
    assert call("step_simulation").result.result == Result.RESULT_OK

    # stopped: reset and held; then paused (steppable) again
    assert call("set_simulation_state", _state(s.STATE_STOPPED)).result.result == \
        Result.RESULT_OK
    assert call("get_simulation_state").state.state == s.STATE_STOPPED
    assert call("set_simulation_state", _state(s.STATE_STOPPED)).result.result == \
        SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    probe.spin_until(lambda: clock_ns() == 0, 10, "the clock back at 0 after the stop")
    assert call("step_simulation").result.result == Result.RESULT_OPERATION_FAILED
    assert call("set_simulation_state", _state(s.STATE_PAUSED)).result.result == \
        Result.RESULT_OK
    assert call("step_simulation", StepSimulation.Request(steps=2)).result.result == \
        Result.RESULT_OK
    probe.spin_until(lambda: clock_ns() == 2 * CHUNK_NS, 10, "two chunks after the stop")

    # shutdown during a step of any length: the node ends cleanly at once
    probe.client(StepSimulation, f"{node}/step_simulation").call_async(
        StepSimulation.Request(steps=ENDLESS))
    probe.spin_until(lambda: clock_ns() > 2 * CHUNK_NS, 20, "the second long step to run")
    start = time.monotonic()
    assert proc.stop(signal.SIGTERM, timeout_s=20) == 0, proc.output()
    assert time.monotonic() - start < 10
    assert "Traceback" not in proc.output()


def test_a_recording_with_the_frames_holds_them_and_diagnostics_by_simulated_time(
        processes, probe, tmp_path):
    from nav_msgs.msg import Odometry
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import MarkerArray

    ns, folder = "/framed", tmp_path / "run"
    proc = processes.start(*node_argv(ns, "consist:=scenario_1", "real_time_factor:=0.0",
                                      "max_sim_time_s:=3.0", "record:=true",
                                      f"record_dir:={folder}", "record_frames:=true",
                                      "tf_vehicle_rate_hz:=5.0"), name="sim_node")
    assert proc.wait(120) == 0, proc.output()
    info = bag_info(folder)
    topics = {name: t.msg_type for name, t in info.topics.items()}
    assert topics["/tf"] == "tf2_msgs/msg/TFMessage"
    assert topics[f"{ns}/odom"] == "nav_msgs/msg/Odometry"
    assert topics[f"{ns}/train/markers"] == "visualization_msgs/msg/MarkerArray"
    messages = {}
    for topic, _, log_ns, data in read_bag(folder):
        messages.setdefault(topic, []).append((log_ns, data))
    chunks = 3_000_000_000 // CHUNK_NS
    assert len(messages[f"{ns}/odom"]) == chunks + 1  # t = 0 and every chunk
    tf = [deserialize_message(d, TFMessage) for _, d in messages["/tf"]]
    vehicles = [m for m in tf if m.transforms[0].header.frame_id == "framed/base_link"]
    # 5 Hz of simulated time from t = 0 to 3 s; the markers drawn with them
    assert [log for log, d in messages["/tf"]
            if deserialize_message(d, TFMessage).transforms[0].header.frame_id
            == "framed/base_link"] == [k * 200_000_000 for k in range(16)]
    # a box per vehicle and coupler and a label per vehicle: 3 n - 1 markers
    markers = deserialize_message(messages[f"{ns}/train/markers"][0][1], MarkerArray).markers
    assert 3 * len(vehicles[0].transforms) - 1 == len(markers)
    assert {m.header.frame_id for m in markers} == {"framed/base_link"}
    assert [log for log, _ in messages[f"{ns}/train/markers"]] == \
        [k * 200_000_000 for k in range(16)]
    odom = deserialize_message(messages[f"{ns}/odom"][-1][1], Odometry)
    assert odom.header.stamp.sec == 3 and odom.twist.twist.linear.x > 0.0
    # as fast as possible, /diagnostics every simulated second (and at the end)
    stamps = [log for log, _ in messages["/diagnostics"]]
    assert {1_000_000_000, 2_000_000_000, 3_000_000_000} <= set(stamps)

    # replay_node republishes the frames as recorded (it starts once every topic is heard)
    for name, topic in info.topics.items():
        probe.subscribe(name, message_class(topic.msg_type), raw=True)
    replay = processes.start(executable("replay_node"), str(folder), "--ros-args",
                             "-p", "rate:=1.0", "-p", "wait_for_subscribers:=1",
                             name="replay_node")
    assert replay.wait(60) == 0, replay.output()
    probe.spin_for(1.0)
    types = {"/tf": TFMessage, f"{ns}/odom": Odometry, f"{ns}/train/markers": MarkerArray}

    def decoded(topic, payloads):  # DDS may pad what it delivers: compare the messages
        return [deserialize_message(bytes(d), types[topic]) for d in payloads]

    for topic in ("/tf", f"{ns}/odom"):
        assert decoded(topic, probe.received[topic]) == \
            decoded(topic, [d for _, d in messages[topic]]), topic
    # the markers keep only the newest picture (depth 1, as recorded): in order, the last one
    recorded = decoded(f"{ns}/train/markers", [d for _, d in messages[f"{ns}/train/markers"]])
    got = decoded(f"{ns}/train/markers", probe.received[f"{ns}/train/markers"])
    assert got and got[-1] == recorded[-1]
    assert [recorded.index(m) for m in got] == sorted(recorded.index(m) for m in got)
