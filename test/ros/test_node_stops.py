"""sim_node in lock-step as a plant for stop-and-go control: each stop judged and published."""
from __future__ import annotations

import json

import pytest
from rclpy.parameter import Parameter
from std_msgs.msg import Bool, Float64, String
from std_srvs.srv import Trigger

pytestmark = pytest.mark.ros

CHUNK_S = 0.1
STEPS_PER_CALL = 20  # 2 s of simulated time a ~/step


def test_a_service_stop_a_drive_off_and_an_emergency_stop_are_two_judged_stops(
        ros_context, probe):
    from ltd_brake_ros.ros.sim_node import SimNode

    ns = "/stopgo"
    probe.subscribe(f"{ns}/train/stops", String)
    node = SimNode(context=ros_context, namespace=ns, parameter_overrides=[
        Parameter("lockstep", value=True), Parameter("consist", value="scenario_6"),
        Parameter("initial_speed_kmh", value=40.0), Parameter("chunk_s", value=CHUNK_S),
        Parameter("steps_per_call", value=STEPS_PER_CALL), Parameter("clock", value="none")])
    taken = []
    node.add_tap(lambda topic, msg, stamp_ns, inbound: inbound and taken.append(topic))
    probe.executor.add_node(node)
    node.start()
    events = probe.received[f"{ns}/train/stops"]

    def kinds():
        return [json.loads(m.data)["event"] for m in events]

    def send(topic, msg):
        before = len(taken)
        probe.publish(f"{ns}/{topic}", msg)
        probe.spin_until(lambda: len(taken) > before, 10, f"{topic} to reach the node")

    def step_until(kind, count, max_calls):
        for _ in range(max_calls):
            if kinds().count(kind) >= count:
                return
            reply = probe.call(Trigger, f"{ns}/sim_node/step", Trigger.Request())
            assert reply.success, reply.message
            # the events of the step's chunks are published before the step's reply
            probe.spin_for(0.05)
        pytest.fail(f"no {count}. {kind} within {max_calls} steps: {kinds()}")

    try:
        probe.wait_matched([f"{ns}/train/stops"])
        send("brake_demand", Float64(data=1.0))
        # full service from 40 km/h: a standstill within 40 s, 2 s more to settle
        step_until("settled", 1, 20)
        send("brake_demand", Float64(data=0.0))
        send("traction_command", Float64(data=1.0))
        step_until("stop_ended", 1, 5)
        for _ in range(30):  # a minute of full traction: about 13 km/h
            assert probe.call(Trigger, f"{ns}/sim_node/step", Trigger.Request()).success
        send("traction_command", Float64(data=0.0))
        send("brake_command", Bool(data=True))
        step_until("settled", 2, 20)
        assert kinds() == ["stop_started", "stopped", "settled", "drive_off", "stop_ended",
                           "stop_started", "stopped", "settled"]
        parsed = [json.loads(m.data) for m in events]
        first_end = parsed[4]
        assert first_end["stop"] == 1 and first_end["end"] == "drive-off"
        assert first_end["verdicts"] == "PASS" and first_end["verdict_runaway"] == "PASS"
        assert [parsed[0]["command"], parsed[5]["command"]] == ["service", "emergency"]
        assert parsed[5]["command_speed_kmh"] > 10.0 and parsed[6]["stopping_distance_m"] > 5
        records = node.simulator.stops
        assert [(s.number, s.command, s.end) for s in records] == [
            (1, "service", "drive-off"), (2, "emergency", "open")]
        # the published stop is the simulator's own
        assert parsed[1]["stopping_distance_m"] == pytest.approx(
            records[0].stopping_distance_m, abs=1e-9)
        assert all(s.verdicts.status == "PASS" for s in records)
        # a reset ends the run: its open stop is closed with its verdicts, then the run restarts
        reply = probe.call(Trigger, f"{ns}/sim_node/reset", Trigger.Request())
        assert reply.success, reply.message
        probe.spin_until(lambda: kinds().count("stop_ended") == 2, 10, "the last stop's end")
        last = json.loads(events[-1].data)
        assert last["stop"] == 2 and last["end"] == "end of run" and last["verdicts"] == "PASS"
        assert node.simulator.stops == ()
    finally:
        probe.executor.remove_node(node)
        node.close()
