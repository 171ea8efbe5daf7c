"""sim_node as a ROS 2 plant: interface, pacing modes, services, parameters, packaging.

The node runs as a separate process (the installed ``sim_node`` executable) in the session's
private DDS domain, except for the fault-injection test, which needs the node in-process. The
physics numbers themselves are pinned by the physics tests; here the node must only reproduce the
offline run of the same simulator.
"""
from __future__ import annotations

import math
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
# a broken ROS installation fails these tests; it never skips them
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from conftest import RosProbe, executable
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.recording.bag import BagWriter, bag_info
from ltd_brake_ros.simulator import SimulationError, Simulator
from ltd_brake_ros.studies import runs
from node_helpers import chunks_from_log, node_argv, signal_group, wait_until_signals_handled

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
ARRAYS = {"vehicles/speed": "vehicle", "vehicles/position": "vehicle",
          "vehicles/brake_force": "vehicle", "couplers/force": "coupler"}


def start_node(processes, ns: str, *params: str, name: str | None = None,
               ros_args: tuple[str, ...] = ()):
    """Start the installed sim_node in namespace ``ns`` with its /clock moved under ``ns``."""
    return processes.start(*node_argv(ns, *params, ros_args=ros_args),
                           name=name or ns.strip("/"))


def diagnostics(probe: RosProbe, node: str) -> dict[str, str]:
    """Key/values of the latest diagnostics status of ``node`` ({} if none yet)."""
    for array in reversed(probe.received["/diagnostics"]):
        for status in array.status:
            if status.name == f"{node}: train plant":
                return {kv.key: kv.value for kv in status.values} | {"_level": status.level}
    return {}


def clock_s(msg: Clock) -> float:
    return msg.clock.sec + msg.clock.nanosec * 1e-9


def assert_clean_exit(proc, sig) -> str:
    status = proc.stop(sig)
    out = proc.output()
    assert status == 0, f"exit status {status} after {signal.Signals(sig).name}:\n{out}"
    assert "Traceback" not in out, out
    return out


# --------------------------------------------------------------------------- free-running plant


def test_live_plant_stops_like_the_offline_simulator(processes, probe):
    ns, node = "/free", "/free/sim_node"
    scenario = get_scenario(6)
    consist = scenario.consist()
    n = consist.n
    # at real_time_factor 0 the probe cannot take every message: a short reader queue keeps
    # what it reads close to the newest state
    for topic in ARRAYS:
        probe.subscribe(f"{ns}/{topic}", Float64MultiArray, depth=10)
    probe.subscribe(f"{ns}/clock", Clock, depth=10)
    probe.prepare(node, "pause", "reset", "step", "set_parameters", "get_parameters")
    probe.subscribe("/diagnostics", DiagnosticArray)
    spawned = time.monotonic()
    proc = start_node(processes, ns, "real_time_factor:=1.0")
    got = probe.received
    clocks, positions = got[f"{ns}/clock"], got[f"{ns}/vehicles/position"]
    probe.spin_until(lambda: diagnostics(probe, node), 60, f"diagnostics of {node}")
    probe.spin_until(lambda: clocks, 60, f"{ns}/clock from the running node")
    probe.spin_for(0.5)
    # paced at real_time_factor 1: simulated time never runs ahead of the wall clock
    assert 0.0 < clock_s(clocks[-1]) <= time.monotonic() - spawned

    # pause, then reset: the node publishes the initial state once
    assert probe.call(SetBool, f"{node}/pause", SetBool.Request(data=True)).success
    reply = probe.call(Trigger, f"{node}/reset", Trigger.Request())
    assert reply.success, reply.message
    initial = Simulator(consist, scenario.speed_kmh).snapshot()
    probe.spin_until(lambda: positions and np.array_equal(positions[-1].data, initial.position_m)
                     and clock_s(clocks[-1]) == 0.0, 20, "the reset state")
    speeds = got[f"{ns}/vehicles/speed"]
    probe.spin_until(lambda: speeds and np.array_equal(speeds[-1].data, initial.speed_m_s), 20,
                     "the reset speeds")
    assert not np.any(got[f"{ns}/couplers/force"][-1].data)
    assert not np.any(got[f"{ns}/vehicles/brake_force"][-1].data)
    first = {topic: len(got[f"{ns}/{topic}"]) - 1 for topic in ARRAYS}
    first_clock = len(clocks) - 1

    # the emergency command is taken while paused and applied at t = 0 of the next chunk
    probe.publish(f"{ns}/brake_command", Bool(data=True))
    probe.spin_until(lambda: diagnostics(probe, node).get("emergency_command") == "true", 20,
                     "diagnostics to report the emergency command")

    # run-time parameters: bad values are rejected with a reason, the old value stays
    bad_rtf, = probe.set_parameters(node, real_time_factor=-1.0)
    assert not bad_rtf.successful and "real_time_factor" in bad_rtf.reason
    nan_rtf, = probe.set_parameters(node, real_time_factor=math.nan)
    assert not nan_rtf.successful and "real_time_factor" in nan_rtf.reason
    chunk, = probe.set_parameters(node, chunk_s=0.05)
    assert not chunk.successful and "read-only" in chunk.reason
    chunk, = probe.set_parameters(node, chunk_s=-0.02)
    assert not chunk.successful and "chunk_s" in chunk.reason
    catch_up, = probe.set_parameters(node, max_catch_up_s=1.0)
    assert not catch_up.successful and "read-only" in catch_up.reason
    assert probe.get_parameters(node, "real_time_factor", "chunk_s", "max_catch_up_s") == \
        [1.0, 0.02, 0.2]
    fast, = probe.set_parameters(node, real_time_factor=0.0)
    assert fast.successful, fast.reason
    assert probe.get_parameters(node, "real_time_factor") == [0.0]

    assert probe.call(SetBool, f"{node}/pause", SetBool.Request(data=False)).success
    reply = probe.call(Trigger, f"{node}/step", Trigger.Request())
    assert not reply.success and "free-running" in reply.message  # refused, not queued
    probe.spin_until(lambda: "stopping_distance_m" in diagnostics(probe, node), 120,
                     "the train to stop")
    # the plant keeps publishing (a steady standstill) after the stop
    stop_clock = clock_s(clocks[-1])
    probe.spin_until(lambda: clock_s(clocks[-1]) > stop_clock + 2.0, 30,
                     "/clock to keep advancing after the stop")
    # pause, then drain what is still queued: the last message of each topic is the final state
    reply = probe.call(SetBool, f"{node}/pause", SetBool.Request(data=True))
    paused_at_s = float(reply.message.split("t = ")[1].split()[0])
    probe.spin_until(lambda: abs(clock_s(clocks[-1]) - paused_at_s) < 1e-3, 20,
                     "the last /clock before the pause")
    probe.spin_for(0.5)

    # observed stopping distance = head position at standstill - head position at the command
    observed_m = positions[-1].data[0] - initial.position_m[0]
    reference = runs.emergency_stop(consist, scenario.speed_kmh)
    assert observed_m == pytest.approx(reference.stopping_distance_m, rel=0.005)
    # measured 2 s after the stop: the locomotive may have been pulled back a few centimetres as
    # the couplers relaxed (its brake holds less than the draft the train stored), never forward
    reported_m = float(diagnostics(probe, node)["stopping_distance_m"])
    assert reported_m - 0.05 <= observed_m <= reported_m + 0.01
    assert np.all(np.abs(speeds[-1].data) < 1e-2)

    # layout, lengths and sign conventions of everything published since the reset
    for topic, label in ARRAYS.items():
        msgs = got[f"{ns}/{topic}"][first[topic]:]
        assert len(msgs) > 10, topic
        size = n - 1 if label == "coupler" else n
        for msg in msgs:
            assert len(msg.layout.dim) == 1 and msg.layout.data_offset == 0
            dim = msg.layout.dim[0]
            assert (dim.label, dim.size, dim.stride, len(msg.data)) == (label, size, size, size)
    data = {topic: np.array([m.data for m in got[f"{ns}/{topic}"][first[topic]:]])
            for topic in ARRAYS}
    speed = data["vehicles/speed"]  # forward positive: from +v0 down to standstill
    assert speed[0] == pytest.approx(np.full(n, scenario.speed_kmh / 3.6))
    assert np.all(np.abs(speed[-1]) < 1e-2)
    assert data["vehicles/position"][-1, 0] > data["vehicles/position"][0, 0]
    assert data["vehicles/brake_force"].min() >= 0.0  # retarding force positive
    assert data["vehicles/brake_force"].max() > 0.0
    forces = data["couplers/force"]
    assert forces.max() > 0.0 and forces.min() < 0.0  # draft positive, buff negative both seen
    times = [clock_s(c) for c in clocks[first_clock:]]
    assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:])), "non-monotone clock"
    diag = diagnostics(probe, node)
    for key in ("achieved_real_time_factor", "chunk_overruns", "schedule_dropped_s",
                "schedule_lag_s", "peak_schedule_lag_s", "head_speed_kmh", "peak_draft_kN", "peak_buff_kN",
                "stop_time_s"):
        assert key in diag, key
    assert diag["_level"] in (DiagnosticStatus.OK, DiagnosticStatus.WARN)

    out = assert_clean_exit(proc, signal.SIGINT)
    assert out.count("train stopped") == 1, out  # the stopping distance is logged once


# --------------------------------------------------------------------------- lock-step


def test_lockstep_runs_are_bit_identical_and_reset_restores_the_start(processes, probe):
    chunks_per_call, calls = 5, 20
    params = ("lockstep:=true", f"steps_per_call:={chunks_per_call}", "auto_brake_at_s:=0.5",
              "real_time_factor:=1.0")
    runs_ns = ("/step_a", "/step_b")
    topics = [f"{ns}/{t}" for ns in runs_ns for t in ARRAYS]
    for topic in topics:
        probe.subscribe(topic, Float64MultiArray, raw=True)
    for ns in runs_ns:
        probe.subscribe(f"{ns}/clock", Clock)
        probe.prepare(f"{ns}/sim_node", "reset", "step")
    probe.subscribe("/diagnostics", DiagnosticArray)
    procs = [start_node(processes, ns, *params) for ns in runs_ns]
    got = probe.received
    # a node that reports to the probe has discovered the probe's endpoints, clients included
    for ns in runs_ns:
        probe.spin_until(lambda: diagnostics(probe, f"{ns}/sim_node"), 60,
                         f"diagnostics of {ns}/sim_node")

    lost_replies = []

    def reset(ns):
        """Reset ``ns`` once; return the reset state it published.

        Readiness is explicit: each node has reported to the probe, so it has matched the
        readers and clients the probe created before it started. A reply may still go missing
        (the node's response writer matches the client's reader on its own schedule); the
        node's reset counter in diagnostics then tells whether the reset happened. A lost
        reply of a reset that happened is tolerated once per test; a lost reset fails, and no
        reset is ever repeated.
        """
        node = f"{ns}/sim_node"
        resets = int(diagnostics(probe, node)["resets"])
        counts = {t: len(got[f"{ns}/{t}"]) for t in ARRAYS}
        try:
            reply = probe.call(Trigger, f"{node}/reset", Trigger.Request(), timeout_s=10)
            assert reply.success, reply.message
        except pytest.fail.Exception:
            lost_replies.append(ns)
            assert len(lost_replies) == 1, f"replies of ~/reset lost: {lost_replies}"
        probe.spin_until(lambda: int(diagnostics(probe, node)["resets"]) > resets, 10,
                         f"{node} to count the reset (a lost reset if it never does)")
        assert int(diagnostics(probe, node)["resets"]) == resets + 1
        probe.spin_until(lambda: all(len(got[f"{ns}/{t}"]) > counts[t] for t in ARRAYS), 20,
                         f"{ns}: the reset state on every topic")
        return {t: got[f"{ns}/{t}"][-1] for t in ARRAYS}

    def run(ns):
        start = {t: len(got[f"{ns}/{t}"]) for t in ARRAYS}
        final_clocks = []
        for k in range(1, calls + 1):
            reply = probe.call(Trigger, f"{ns}/sim_node/step", Trigger.Request())
            assert reply.success, reply.message
            # the reply names the inputs the chunks ran with (auto brake from t = 0.5 s)
            braked = k * chunks_per_call > 25  # 0.02 s chunks: braked from t = 0.5 s on
            assert f"emergency={'true' if braked else 'false'}" in reply.message, reply.message
            want_ns = k * chunks_per_call * 20_000_000
            probe.spin_until(
                lambda: all(len(got[f"{ns}/{t}"]) - start[t] == k * chunks_per_call
                            for t in ARRAYS) and got[f"{ns}/clock"]
                and got[f"{ns}/clock"][-1].clock.sec * 10**9
                + got[f"{ns}/clock"][-1].clock.nanosec == want_ns,
                10, f"{ns}: the chunks of step call {k}")
            final_clocks.append(clock_s(got[f"{ns}/clock"][-1]))
        # lock-step: nothing moves between calls
        probe.spin_for(0.3)
        assert all(len(got[f"{ns}/{t}"]) - start[t] == calls * chunks_per_call for t in ARRAYS)
        return {t: got[f"{ns}/{t}"][start[t]:] for t in ARRAYS}, final_clocks

    initial_a = reset("/step_a")
    first_a, clocks_a = run("/step_a")
    assert reset("/step_a") == initial_a  # reset mid-run restores the initial state
    second_a, clocks_a2 = run("/step_a")
    initial_b = reset("/step_b")
    first_b, clocks_b = run("/step_b")

    assert initial_b == initial_a
    assert first_a == second_a, "a run after ~/reset differs from the first one"
    assert first_a == first_b, "two lock-step runs differ"
    assert clocks_a == clocks_a2 == clocks_b
    brake = deserialize_message(first_a["vehicles/brake_force"][-1], Float64MultiArray)
    assert max(brake.data) > 0.0, "auto_brake_at_s did not apply the brake"

    for proc in procs:
        assert_clean_exit(proc, signal.SIGTERM)


# --------------------------------------------------------------------------- start-up


def test_bad_start_up_parameters_end_with_one_clear_line(processes, tmp_path):
    taken = tmp_path / "taken"
    BagWriter(taken).close()  # an earlier run's recording
    broken = tmp_path / "broken.yaml"
    broken.write_text("sim_node:\n  ros__parameters: [1, 2\n")
    sim_node = executable("sim_node")
    # what a user may get wrong -> (command line, what the one line must say)
    cases = {
        "consist": (node_argv("/b1", "consist:=no_such_scenario"),
                    ["parameter consist", "unknown scenario"]),
        "brake_params_file": (node_argv("/b2", "brake_params_file:=/nonexistent/brakes.yaml"),
                              ["parameter brake_params_file", "does not exist"]),
        "chunk_s": (node_argv("/b3", "chunk_s:=-0.02"), ["parameter chunk_s", "out of range"]),
        "initial_speed_kmh": (node_argv("/b4", "consist:=consists/e402b_10_shimmns_80t.yaml"),
                              ["parameter initial_speed_kmh", "must be given"]),
        "real_time_factor": (node_argv("/b5", "real_time_factor:=-1.0"),
                             ["parameter real_time_factor", "out of range"]),
        # a typo would record nothing and exit 0
        "misspelt": (node_argv("/b6", "recrod:=true", "max_sim_time_s:=0.1"),
                     ["parameter recrod: sim_node has no such parameter (did you mean record or "
                      "record_dir?)"]),
        # a run is never recorded into another one's folder
        "record_dir": (node_argv("/b7", "record:=true", f"record_dir:={taken}"),
                       [f"parameter record_dir: {taken} exists and is not empty"]),
        "missing params file": (node_argv("/b8", ros_args=("--params-file", "/nonexistent.yaml")),
                                ["--params-file /nonexistent.yaml: no such file"]),
        "broken params file": (node_argv("/b9", ros_args=("--params-file", str(broken))),
                               [f"Couldn't parse params file: '--params-file {broken}'"]),
        # without --ros-args nothing would be set
        "stray argument": ([sim_node, "-p", "record:=true"],
                           ["unexpected argument '-p'; usage: sim_node [--ros-args"]),
    }
    started = {name: processes.start(*argv, name=name.replace(" ", "_"))
               for name, (argv, _) in cases.items()}
    finishing = start_node(processes, "/finish", "max_sim_time_s:=0.5", "real_time_factor:=0.0",
                           "auto_brake_at_s:=0.0",
                           ros_args=("--params-file", str(REPO / "config" / "sim_node.yaml")))
    for name, proc in started.items():
        status = proc.wait(60)
        out = proc.output().strip()
        assert status == 1, f"{name}: exit status {status}\n{out}"
        assert len(out.splitlines()) == 1 and out.startswith("[FATAL]"), f"{name}:\n{out}"
        assert "cannot start: " in out, f"{name}:\n{out}"
        for text in cases[name][1]:
            assert text in out, f"{name}:\n{out}"
    assert sorted(p.name for p in taken.iterdir()) == ["metadata.yaml", "taken_0.mcap"]
    assert finishing.wait(60) == 0, finishing.output()
    assert "max_sim_time_s = 0.5 s reached" in finishing.output()
    assert chunks_from_log(finishing.output()) == 25  # 0.5 s in chunks of 0.02 s, exactly


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_while_starting_ends_the_node_cleanly(processes, tmp_path, sig):
    """From the program's first line to the running plant, at fixed-seed moments: exit 0,
    only log lines, and either nothing left behind or a finished bag.

    The moments count from when the program handles SIGTERM (its first line); before that
    the interpreter and the ROS wheels' bootstrap start (about 0.1 s, longer on a loaded
    machine), where a signal gets the operating system's default action.
    """
    rng = random.Random(20250104 + sig)
    # start-up takes about 2 s here: imports, then parameters, inputs, kernel, endpoints
    delays = sorted(rng.uniform(0.0, 2.5) for _ in range(8))
    for batch in (delays[:4], delays[4:]):  # four at a time: the moments stay in start-up
        trials = []
        for delay in batch:
            folder = tmp_path / f"at_{delay:.2f}"
            proc = processes.start(*node_argv(f"/start{len(trials)}", "record:=true",
                                              f"record_dir:={folder}"),
                                   name=folder.name)
            trials.append((delay, folder, proc))
        for delay, folder, proc in trials:
            handled = wait_until_signals_handled(proc)
            time.sleep(max(0.0, handled + delay - time.monotonic()))
            signal_group(proc, sig)
        for delay, folder, proc in trials:
            what = f"{signal.Signals(sig).name} {delay:.2f} s after the program's first line"
            status = proc.wait(30)
            out = proc.output()
            assert status == 0, f"{what}: exit status {status}\n{out}"
            lines = out.strip().splitlines()
            assert lines and all(line.startswith("[") for line in lines), f"{what}:\n{out}"
            if "recording to" in out:
                assert "recording finished" in out and bag_info(folder).complete, what
            else:
                assert "while starting: stopped" in lines[-1], f"{what}:\n{out}"
                assert not folder.exists(), what
            print(f"{what}: {lines[-1].split(']: ')[-1]}")


def test_parameter_file_declares_every_parameter_with_its_default():
    import yaml

    from ltd_brake_ros.ros.params import PARAMETERS

    listed = yaml.safe_load((REPO / "config" / "sim_node.yaml").read_text())
    (key, section), = listed.items()  # sim_node, or /**/sim_node for any namespace
    assert key.rsplit("/", 1)[-1] == "sim_node"
    values = section["ros__parameters"]
    assert values == {p.name: p.default for p in PARAMETERS}
    for p in PARAMETERS:
        d = p.descriptor()
        assert d.description and d.type != 0, p.name
        if isinstance(p.default, (int, float)) and not isinstance(p.default, bool):
            assert d.floating_point_range or d.integer_range, f"{p.name} has no range"
    writable = {p.name for p in PARAMETERS if not p.descriptor().read_only}
    at_reset = {"consist", "initial_speed_kmh", "brake_params_file", "coupler_lut_file",
                "tolerance_m_s",
                "track_file", "start_chainage_m", "auto_brake_at_s", "max_sim_time_s",
                "shutdown_after_stop_s"}
    assert writable == {"real_time_factor", "steps_per_call"} | at_reset
    assert all("next ~/reset" in p.descriptor().description for p in PARAMETERS
               if p.name in at_reset)


# --------------------------------------------------------------------------- wiring (in-process)


@pytest.mark.parametrize("clock", ["publish", "none"])
def test_topics_qos_and_services_are_wired_as_documented(ros_context, clock):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64, String
    from visualization_msgs.msg import MarkerArray
    from nav_msgs.msg import Odometry
    from simulation_interfaces.srv import (GetSimulationState, GetSimulatorFeatures,
                                           ResetSimulation, SetSimulationState, StepSimulation)
    from tf2_msgs.msg import TFMessage

    from ltd_brake_ros.ros.sim_node import SimNode

    node = SimNode(context=ros_context, namespace="/wired", parameter_overrides=[
        Parameter("lockstep", value=True), Parameter("clock", value=clock)])
    try:
        # state topics lossless for a reader that keeps up, /clock and markers only the newest,
        # commands deep; only the description latched
        outputs = {f"/wired/{topic}": (Float64MultiArray, 10) for topic in
                   ("vehicles/speed", "vehicles/position", "vehicles/brake_force",
                    "vehicles/traction_force", "couplers/force")}
        outputs |= {f"/wired/{topic}": (JointState, 10) for topic in
                    ("vehicles/state", "couplers/state")}
        outputs["/diagnostics"] = (DiagnosticArray, 10)
        outputs["/wired/train/description"] = (String, 1)  # latched: checked below
        outputs["/wired/train/stops"] = (String, 100)  # each event kept for a slow reader
        outputs["/wired/train/markers"] = (MarkerArray, 1)
        # where the train is: the head's odometry, and the frames on the shared /tf
        outputs["/wired/odom"] = (Odometry, 10)
        outputs["/tf"] = (TFMessage, 100)
        # the brake heat of every vehicle, as every brake model gives it
        outputs |= {f"/wired/vehicles/{t}": (Float64MultiArray, 10) for t in
                    ("block_temperature", "wheel_temperature")}
        if clock == "publish":
            outputs["/clock"] = (Clock, 1)
        inputs = {"/wired/brake_command": Bool, "/wired/brake_demand": Float64,
                  "/wired/traction_command": Float64, "/wired/driver_brake_valve": String}
        # rclpy's own /rosout and /parameter_events publishers are not the node's outputs
        publishers = {p.topic_name: p for p in node.publishers
                      if p.topic_name not in ("/rosout", "/parameter_events")}
        assert set(publishers) == set(outputs)
        endpoints = [(publishers[t], typ, depth) for t, (typ, depth) in outputs.items()]
        subscriptions = {s.topic_name: s for s in node.subscriptions
                         if s.topic_name != "/parameter_events"}
        assert set(subscriptions) == set(inputs)
        endpoints += [(subscriptions[t], typ, 1000) for t, typ in inputs.items()]
        for endpoint, msg_type, depth in endpoints:
            q = endpoint.qos_profile
            latched = endpoint.topic_name == "/wired/train/description"
            assert endpoint.msg_type is msg_type, endpoint.topic_name
            assert (q.history, q.depth, q.reliability, q.durability) == (
                HistoryPolicy.KEEP_LAST, depth, ReliabilityPolicy.RELIABLE,
                DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE), \
                endpoint.topic_name
        services = {s.service_name: s.srv_type for s in node.services}
        for name, srv_type in (("reset", Trigger), ("pause", SetBool), ("step", Trigger),
                               ("step_simulation", StepSimulation),
                               ("reset_simulation", ResetSimulation),
                               ("get_simulation_state", GetSimulationState),
                               ("set_simulation_state", SetSimulationState),
                               ("get_simulator_features", GetSimulatorFeatures)):
            assert services.get(f"/wired/sim_node/{name}") is srv_type, name
    finally:
        node.close()


# --------------------------------------------------------------------------- faults (in-process)


def test_simulation_error_is_reported_and_reset_recovers(ros_context, probe, monkeypatch):
    from ltd_brake_ros.ros.sim_node import SimNode

    node = SimNode(context=ros_context, namespace="/inproc",
                   parameter_overrides=[Parameter("lockstep", value=True),
                                        Parameter("consist", value="scenario_7"),
                                        Parameter("clock", value="publish")])
    seen = []
    node.add_tap(lambda topic, msg, stamp_ns, inbound: seen.append((topic, msg, inbound)))
    probe.executor.add_node(node)
    node.start()
    try:
        name = "/inproc/sim_node"
        probe.publish("/inproc/brake_command", Bool(data=True))
        probe.spin_until(lambda: any(inbound for _, _, inbound in seen), 10,
                         "the command to reach the input hook")
        assert probe.call(Trigger, f"{name}/step", Trigger.Request()).success

        def diverge(*args, **kwargs):
            raise SimulationError("forced: Newton iteration did not converge")

        monkeypatch.setattr(node.simulator, "advance", diverge)
        reply = probe.call(Trigger, f"{name}/step", Trigger.Request())
        assert not reply.success and "forced" in reply.message
        errors = [msg for topic, msg, _ in seen if topic == "/diagnostics"
                  and msg.status[0].level == DiagnosticStatus.ERROR]
        assert errors and "forced" in errors[-1].status[0].message
        reply = probe.call(Trigger, f"{name}/step", Trigger.Request())
        assert not reply.success and "reset" in reply.message  # no advancing until reset
        monkeypatch.undo()
        assert probe.call(Trigger, f"{name}/reset", Trigger.Request()).success
        reply = probe.call(Trigger, f"{name}/step", Trigger.Request())
        assert reply.success, reply.message
        assert node.runner.sim_time_s == pytest.approx(0.02)
        topics = {topic for topic, _, inbound in seen if not inbound}
        assert {"/inproc/vehicles/speed", "/inproc/couplers/force", "/clock",
                "/diagnostics"} <= topics
    finally:
        probe.executor.remove_node(node)
        node.close()


def test_a_late_subscriber_gets_the_description_and_a_viewer_sees_the_train(ros_context,
                                                                             probe):
    import json

    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import Marker, MarkerArray

    from ltd_brake_ros.ros.sim_node import SimNode

    node = SimNode(context=ros_context, namespace="/seen",
                   parameter_overrides=[Parameter("lockstep", value=True),
                                        Parameter("consist", value="scenario_6"),
                                        Parameter("clock", value="publish")])
    probe.executor.add_node(node)
    node.start()
    try:
        name = "/seen/sim_node"
        assert probe.call(Trigger, f"{name}/step", Trigger.Request()).success
        # joins after the description was published: a transient-local reader still gets it
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        got = []
        probe.node.create_subscription(String, "/seen/train/description", got.append, latched)
        probe.spin_until(lambda: got, 20, "the latched description")
        d = json.loads(got[0].data)
        assert d["run"]["consist"]["vehicles"] == 33 and len(d["vehicles"]) == 33
        assert d["vehicles"][0]["joint"] == "vehicle_0" and d["vehicles"][0]["type"] == "E402B"
        assert d["couplers"][0] == {"index": 1, "joint": "coupler_1", "between": [0, 1],
                                    "draft_strength_kN": 850.0, "buff_strength_kN": 2000.0}
        assert d["brake_model"] == "uic_empirical" and "draft (tension) positive" in \
            d["conventions"]["signs"]
        # markers only while someone looks: one box per vehicle and coupler, labels
        probe.subscribe("/seen/train/markers", MarkerArray)
        # where the train is: the head's odometry with every chunk, /tf (the head with every
        # chunk, the vehicles at tf_vehicle_rate_hz, 10 Hz of simulated time by default)
        probe.subscribe("/seen/odom", Odometry)
        probe.subscribe("/tf", TFMessage)
        probe.subscribe("/seen/vehicles/state", JointState)
        probe.wait_matched(["/seen/train/markers", "/seen/odom", "/tf",
                            "/seen/vehicles/state"])
        probe.publish("/seen/brake_command", Bool(data=True))
        for _ in range(250):  # 5 s of braking: the wagons' cylinders fill in about 5 s
            assert probe.call(Trigger, f"{name}/step", Trigger.Request()).success
        received = probe.received["/seen/train/markers"]

        def late() -> bool:  # a picture of the train after 4 s of braking
            return bool(received) and received[-1].markers[0].header.stamp.sec >= 4

        for _ in range(100):
            if late():
                break
            probe.spin_for(0.15)  # beyond the markers' period: the next step shows
            assert probe.call(Trigger, f"{name}/step", Trigger.Request()).success
            probe.spin_for(0.05)
        assert late(), "no marker picture of the braking train"
        probe.spin_until(lambda: probe.received["/seen/vehicles/state"][-1].header.stamp
                         == probe.received["/seen/odom"][-1].header.stamp, 10, "the last odom")

        def ns(stamp) -> int:
            return stamp.sec * 1_000_000_000 + stamp.nanosec

        states = {ns(m.header.stamp): m for m in probe.received["/seen/vehicles/state"]}
        odoms = probe.received["/seen/odom"]
        assert len(odoms) == len(states) >= 250
        for odom in odoms:  # the head's centre and speed at the same instant
            state = states[ns(odom.header.stamp)]
            assert (odom.header.frame_id, odom.child_frame_id) == ("map", "seen/base_link")
            assert odom.pose.pose.position.x == state.position[0]
            assert odom.twist.twist.linear.x == state.velocity[0]
        heads, vehicles = [], []
        for msg in probe.received["/tf"]:
            (heads if len(msg.transforms) == 1 else vehicles).append(msg)
        assert [ns(m.transforms[0].header.stamp) for m in heads] == sorted(states)
        for m in heads:
            t, = m.transforms
            assert (t.header.frame_id, t.child_frame_id) == ("map", "seen/base_link")
            assert t.transform.translation.x == states[ns(t.header.stamp)].position[0]
            assert t.transform.rotation.w == 1.0
        # every 0.1 s of simulated time (5 chunks)
        stamps = [ns(m.transforms[0].header.stamp) for m in vehicles]
        first = stamps[0] // 100_000_000
        assert stamps == [(first + k) * 100_000_000 for k in range(len(stamps))]
        assert len(stamps) >= 50
        last = vehicles[-1].transforms
        assert [t.child_frame_id for t in last] == [f"seen/vehicle_{i}" for i in range(33)]
        assert {t.header.frame_id for t in last} == {"seen/base_link"}
        state = states[stamps[-1]]
        assert [t.transform.translation.x for t in last] == \
            pytest.approx([x - state.position[0] for x in state.position], abs=1e-9)
        markers = received[-1].markers
        by_ns = {}
        for m in markers:
            by_ns.setdefault(m.ns, []).append(m)
        assert {k: len(v) for k, v in by_ns.items()} == {
            "seen/vehicles": 33, "seen/couplers": 32, "seen/labels": 33}
        head, second = by_ns["seen/vehicles"][:2]
        # drawn in the head's frame, which /tf moves: a view that follows it follows the train
        assert head.type == Marker.CUBE and head.header.frame_id == "seen/base_link"
        assert head.pose.position.x == 0.0 and head.frame_locked
        # the head ahead of the wagon behind by half their lengths (19.42 / 2 + 12.64 / 2 m),
        # give or take the coupler's deflection (its travel is below 0.15 m)
        assert head.pose.position.x - second.pose.position.x == pytest.approx(16.03, abs=0.15)
        # braking: the wagons' boxes are no longer grey (orange has more red than blue)
        assert second.color.r > second.color.b + 0.1
        assert by_ns["seen/labels"][0].text == "0 E402B"
    finally:
        probe.executor.remove_node(node)
        node.close()


# --------------------------------------------------------------------------- packaging


def test_colcon_build_installs_what_ros2_run_resolves(tmp_path):
    colcon = Path(sys.executable).parent / "colcon"
    if not colcon.exists():
        pytest.fail("colcon is not installed (run ./dev.sh setup)")
    src = tmp_path / "src" / "ltd_brake_ros"
    src.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc", "*.egg-info")
    for entry in ("package.xml", "setup.py", "setup.cfg", "README.md", "LICENSE", "CHANGELOG.md",
                  "resource", "config", "launch", "layouts", "examples", "ltd_brake_ros"):
        path = REPO / entry
        if path.is_dir():
            shutil.copytree(path, src / entry, ignore=ignore)
        elif path.exists():
            shutil.copy2(path, src / entry)
    build = subprocess.run(
        [str(colcon), "--log-base", "log", "build", "--base-paths", "src", "--build-base",
         "build", "--install-base", "install"], cwd=tmp_path, capture_output=True, text=True,
        timeout=300)
    assert build.returncode == 0, build.stdout + build.stderr
    prefix = tmp_path / "install" / "ltd_brake_ros"
    assert os.access(prefix / "lib" / "ltd_brake_ros" / "sim_node", os.X_OK)
    # what ros2 launch and a workspace user find: launch files, layouts, the example
    # controller, and the bash setup script users source
    share = prefix / "share" / "ltd_brake_ros"
    for launch_file in (REPO / "launch").iterdir():
        assert (share / "launch" / launch_file.name).is_file(), launch_file.name
    assert sorted(p.name for p in (share / "layouts").iterdir()) == \
        sorted(p.name for p in (REPO / "layouts").iterdir())
    assert os.access(prefix / "lib" / "ltd_brake_ros" / "speed_controller.py", os.X_OK)
    assert (tmp_path / "install" / "setup.bash").is_file()

    # what `ros2 run ltd_brake_ros sim_node` does: package prefix from the ament index, then the
    # executable in <prefix>/lib/<package>
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix),
               PYTHONPATH=str(next(prefix.glob("lib/python*/site-packages"))))
    resolve = (
        "import os\n"
        "from ament_index_python.packages import get_package_prefix, get_package_share_directory\n"
        "import ltd_brake_ros\n"
        "prefix = get_package_prefix('ltd_brake_ros')\n"
        "libdir = os.path.join(prefix, 'lib', 'ltd_brake_ros')\n"
        "exes = sorted(f for f in os.listdir(libdir) if os.access(os.path.join(libdir, f), os.X_OK))\n"
        "print(prefix); print(get_package_share_directory('ltd_brake_ros'))\n"
        "print(os.path.join(libdir, 'sim_node') if 'sim_node' in exes else 'missing')\n"
        "print(ltd_brake_ros.__file__)\n")
    out = subprocess.run([sys.executable, "-c", resolve], env=env, cwd=tmp_path,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    got_prefix, share, exe, module = out.stdout.split()
    assert Path(got_prefix) == prefix
    assert (Path(share) / "package.xml").is_file()
    assert (Path(share) / "config" / "scenarios.yaml").is_file()
    assert (Path(prefix) / "share/ament_index/resource_index/packages/ltd_brake_ros").is_file()
    assert Path(exe) == prefix / "lib" / "ltd_brake_ros" / "sim_node"
    assert Path(module).is_relative_to(prefix), "the installed package was not the one imported"

    # the installed executable runs the installed code, which finds its config through the index
    run = subprocess.run([exe, "--ros-args", "-p", "consist:=no_such_scenario"], env=env,
                         cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "unknown scenario" in run.stderr and "12" in run.stderr, run.stderr
    assert "Traceback" not in run.stderr
