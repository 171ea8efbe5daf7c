"""sim_node's driver's brake valve topic: each position, in lock-step, sets the commands."""
from __future__ import annotations

import pytest
from rclpy.parameter import Parameter
from std_msgs.msg import String
from std_srvs.srv import Trigger

from ltd_brake_ros.inputs.commands import FIRST_STEP_DEMAND
from ltd_brake_ros.physics.brakes.base import EMERGENCY, OVERCHARGE, SERVICE

pytestmark = pytest.mark.ros


def test_each_valve_position_is_in_the_next_step_and_an_unknown_one_is_a_warning(
        ros_context, probe, capfd):
    from ltd_brake_ros.ros.sim_node import SimNode

    ns = "/valve"
    node = SimNode(context=ros_context, namespace=ns, parameter_overrides=[
        Parameter("lockstep", value=True), Parameter("consist", value="scenario_7"),
        Parameter("clock", value="none")])
    seen = []
    node.add_tap(lambda topic, msg, stamp_ns, inbound: inbound and seen.append(msg.data))
    probe.executor.add_node(node)
    node.start()
    # position, (emergency, brake_demand, overcharge) in the step reply, brake command issued
    expected = [
        ("service", ("false", repr(FIRST_STEP_DEMAND), "false"), (FIRST_STEP_DEMAND, SERVICE)),
        ("full_service", ("false", "1.0", "false"), (1.0, SERVICE)),
        ("lap", ("false", "1.0", "false"), (1.0, SERVICE)),
        ("release_overcharge", ("false", "0.0", "true"), (0.0, OVERCHARGE)),
        ("running", ("false", "0.0", "false"), (0.0, SERVICE)),
        ("emergency", ("true", "0.0", "false"), (1.0, EMERGENCY)),
        ("apply", ("true", "0.0", "false"), (1.0, EMERGENCY)),  # unknown: nothing changes
    ]
    try:
        for k, (position, (emergency, demand, overcharge), level) in enumerate(expected):
            probe.publish(f"{ns}/driver_brake_valve", String(data=position))
            probe.spin_until(lambda: len(seen) == k + 1, 10, f"{position} to reach the node")
            reply = probe.call(Trigger, f"{ns}/sim_node/step", Trigger.Request())
            assert reply.success, reply.message
            assert (f"emergency={emergency} brake_demand={demand} traction=0.0 "
                    f"overcharge={overcharge} ") in reply.message, (position, reply.message)
            assert node.simulator.state.brake_command == level, position
        assert seen == [position for position, _, _ in expected]
        assert node.runner.rejected == {"driver_brake_valve": 1}
        warnings = [line for line in capfd.readouterr().err.splitlines() if "WARN" in line]
        assert len(warnings) == 1 and (
            f"{ns}/driver_brake_valve: rejected 'apply', expected a position of the driver's "
            "brake valve: release_overcharge, running, lap, service, full_service, "
            "emergency") in warnings[0], warnings
        assert node.running()  # the node goes on
    finally:
        probe.executor.remove_node(node)
        node.close()
