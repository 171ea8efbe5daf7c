"""sim_node in-process: one clock for several trains, the stamped state, lock-step with commands,
run-defining parameters taken at a reset.

Every node's ``/clock`` is remapped under its test's own name, so tests running side by side
(and the other test files' nodes) never see each other's clock.
"""
from __future__ import annotations

import re

import numpy as np
import pytest
# a broken ROS installation fails these tests; it never skips them
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.ros.params import StartupError
from ltd_brake_ros.simulator import Commands, Simulator

pytestmark = pytest.mark.ros

CHUNK_NS = 20_000_000


def make_node(context, ns: str, clock_topic: str, **params):
    """A started SimNode in ``ns`` whose /clock is ``clock_topic``."""
    from ltd_brake_ros.ros.sim_node import SimNode

    node = SimNode(context=context, namespace=ns,
                   cli_args=["--ros-args", "-r", f"/clock:={clock_topic}"],
                   parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    return node


def stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


@pytest.fixture
def nodes(probe):
    """Started nodes, spun by the probe's executor, closed when the test ends."""
    started = []

    def start(node):
        probe.executor.add_node(node)
        node.start()
        started.append(node)
        return node

    yield start
    for node in reversed(started):
        probe.executor.remove_node(node)
        node.close()


def test_auto_follows_the_plant_that_publishes_the_clock_and_its_steps_step_the_follower(
        ros_context, probe, nodes):
    clock = "/lead_follow/clock"
    leader = nodes(make_node(ros_context, "/lead", clock, lockstep=True, steps_per_call=5))
    assert leader.clock_mode == "publish"
    follower = nodes(make_node(ros_context, "/follow", clock, chunk_s=0.05))
    assert follower.clock_mode == "follow" and follower.runner.settings.follow_clock
    probe.subscribe("/follow/vehicles/state", JointState)
    probe.wait_matched(["/follow/vehicles/state"])
    for k in range(1, 5):
        reply = probe.call(Trigger, "/lead/sim_node/step", Trigger.Request())
        assert reply.success, reply.message
        # the follower advances whole chunks of its own up to the leader's time
        want = (k * 5 * CHUNK_NS) // 50_000_000 * 50_000_000
        probe.spin_until(lambda: probe.received["/follow/vehicles/state"]
                         and stamp_ns(probe.received["/follow/vehicles/state"][-1]) == want,
                         10, f"the follower at {want} ns")
    for service, srv, request in (("step", Trigger, Trigger.Request()),
                                  ("pause", SetBool, SetBool.Request(data=True))):
        reply = probe.call(srv, f"/follow/sim_node/{service}", request)
        assert not reply.success and "clock:=follow" in reply.message
    # the follower never publishes the clock: one source of simulated time
    assert follower.count_publishers(clock) == 1


def test_a_second_clock_publisher_is_warned_about_by_name(ros_context, probe, nodes, capfd):
    clock = "/two_clocks/clock"
    nodes(make_node(ros_context, "/first", clock, lockstep=True, clock="publish"))
    nodes(make_node(ros_context, "/second", clock, lockstep=True, clock="publish"))
    probe.spin_until(lambda: "also publish" in capfd.readouterr().err.replace("\n", " ")
                     or False, 10, "a warning about the second /clock")


def test_a_follower_cannot_be_in_lock_step_and_a_bad_clock_mode_is_one_line(ros_context):
    for params, expected in (({"clock": "follow", "lockstep": True},
                              "parameter clock: follow cannot be combined with lockstep"),
                             ({"clock": "both"}, "parameter clock: must be one of auto, "
                                                 "publish, follow, none, got 'both'"),
                             ({"initial_speed_kmh": -0.5}, "parameter initial_speed_kmh: must "
                                                           "be -1 (the scenario's speed)")):
        with pytest.raises(StartupError) as caught:
            make_node(ros_context, "/refused", "/refused/clock", **params)
        assert str(caught.value).startswith(expected), caught.value


def test_the_stamped_state_carries_the_arrays_with_names_and_coupler_elongations(
        ros_context, probe, nodes):
    topics = {"/st/vehicles/state": JointState, "/st/couplers/state": JointState,
              "/st/vehicles/speed": Float64MultiArray, "/st/couplers/force": Float64MultiArray,
              "/st/vehicles/brake_force": Float64MultiArray,
              "/st/vehicles/position": Float64MultiArray}
    for topic, msg_type in topics.items():
        probe.subscribe(topic, msg_type)
    node = nodes(make_node(ros_context, "/st", "/st/clock", lockstep=True, steps_per_call=25,
                           auto_brake_at_s=0.0))
    probe.wait_matched(list(topics))
    got = probe.received
    for _ in range(4):
        assert probe.call(Trigger, "/st/sim_node/step", Trigger.Request()).success
    probe.spin_until(lambda: all(len(got[t]) >= 101 for t in topics), 20, "101 states")
    # the same run offline: positions of the vehicles' centres from their displacements
    sim = Simulator(get_scenario(6).consist(), get_scenario(6).speed_kmh)
    n = sim.n
    for k in range(101):
        vehicles, couplers = got["/st/vehicles/state"][k], got["/st/couplers/state"][k]
        assert stamp_ns(vehicles) == stamp_ns(couplers) == k * CHUNK_NS
        assert list(vehicles.name) == [f"vehicle_{i}" for i in range(n)]
        assert list(couplers.name) == [f"coupler_{j}" for j in range(1, n)]
        speed = np.array(got["/st/vehicles/speed"][k].data)
        np.testing.assert_array_equal(vehicles.velocity, speed)
        np.testing.assert_array_equal(vehicles.position, got["/st/vehicles/position"][k].data)
        np.testing.assert_array_equal(vehicles.effort, got["/st/vehicles/brake_force"][k].data)
        np.testing.assert_array_equal(couplers.effort, got["/st/couplers/force"][k].data)
        np.testing.assert_array_equal(couplers.velocity, speed[:-1] - speed[1:])
        if k:
            sim.advance(0.02, Commands(emergency=True))
        x = sim._state.kinematics.x_m
        # elongation = relative displacement of neighbours (the coupler model's deflection);
        # published through chainages of up to ~600 m: rounding ~1e-13 m
        np.testing.assert_allclose(couplers.position, x[:-1] - x[1:], rtol=0, atol=1e-9)
    assert np.abs(couplers.position).max() > 1e-3  # the braking train's couplers moved [m]
    assert node.runner.sim_time_s == pytest.approx(2.0)


def test_every_step_of_a_controller_stepping_as_fast_as_it_can_uses_its_command(
        ros_context, probe, processes):
    """The node as its own process (commands and requests cross process boundaries)."""
    from node_helpers import node_argv

    ns, steps = "/fast_lock", 400
    probe.prepare(f"{ns}/sim_node", "step")
    demand = probe.node.create_publisher(Float64, f"{ns}/brake_demand", 10)
    traction = probe.node.create_publisher(Float64, f"{ns}/traction_command", 10)
    processes.start(*node_argv(ns, "lockstep:=true", "chunk_s:=0.02"), name="fast_lock")
    client = probe.client(Trigger, f"{ns}/sim_node/step")
    probe.spin_until(lambda: client.service_is_ready() and demand.get_subscription_count()
                     and traction.get_subscription_count(), 60, "the plant")
    # a first step whose reply arrives: the plant's reply writer has matched our reader
    probe.spin_until(lambda: probe.call(Trigger, f"{ns}/sim_node/step", Trigger.Request(),
                                        timeout_s=2).success, 60, "a first step")
    pattern = re.compile(r"brake_demand=(\S+) traction=(\S+) ")
    for k in range(1, steps + 1):
        b, t = k / (2 * steps), -k / (2 * steps)  # a new value every step
        demand.publish(Float64(data=b))
        traction.publish(Float64(data=t))
        future = client.call_async(Trigger.Request())
        probe.spin_until(future.done, 10, f"the reply of step {k}")
        reply = future.result()
        assert reply.success, reply.message
        assert pattern.search(reply.message).groups() == (repr(b), repr(t)), \
            f"step {k} ran without the command sent before it: {reply.message}"


def test_run_parameters_take_effect_at_the_next_reset_and_a_bad_run_is_refused(
        ros_context, probe, nodes):
    node = nodes(make_node(ros_context, "/rs", "/rs/clock", lockstep=True))
    name = "/rs/sim_node"
    probe.subscribe("/rs/vehicles/speed", Float64MultiArray)
    probe.wait_matched(["/rs/vehicles/speed"])
    assert probe.call(Trigger, f"{name}/step", Trigger.Request()).success
    # refused at once: not a speed, and out of range
    for value in (-0.5, 401.0):
        result, = probe.set_parameters(name, initial_speed_kmh=value)
        assert not result.successful and "initial_speed_kmh" in result.reason
    # accepted now, in force after the reset: a longer, slower train
    results = probe.set_parameters(name, consist="scenario_1", initial_speed_kmh=50.0)
    assert all(r.successful for r in results), results
    assert node.runner.sim.consist.name == get_scenario(6).consist().name  # not yet
    reply = probe.call(Trigger, f"{name}/reset", Trigger.Request())
    assert reply.success and "new run" in reply.message, reply.message
    speeds = probe.received["/rs/vehicles/speed"]
    consist = get_scenario(1).consist()
    probe.spin_until(lambda: len(speeds[-1].data) == consist.n, 10, "the new train's state")
    np.testing.assert_allclose(speeds[-1].data, 50.0 / 3.6)
    # a run that cannot be built is refused at param set, with the reason; the values in
    # force stay (param get reads them) and the run goes on
    result, = probe.set_parameters(name, consist="no_such_scenario")
    assert not result.successful and "consist" in result.reason \
        and "unknown scenario" in result.reason, result.reason
    assert node.get_parameter("consist").value == "scenario_1"
    result, = probe.set_parameters(name, brake_params_file="no/such/file.yaml")
    assert not result.successful and "brake_params_file" in result.reason, result.reason
    reply = probe.call(Trigger, f"{name}/step", Trigger.Request())
    assert reply.success and "t = 0.020 s" in reply.message, reply.message
    assert node.runner.sim.n == consist.n


def test_the_last_log_line_keeps_the_namespace(ros_context, probe, capfd):
    node = make_node(ros_context, "/last/line", "/last/line/clock", lockstep=True)
    probe.executor.add_node(node)
    node.start()
    assert probe.call(Trigger, "/last/line/sim_node/step", Trigger.Request()).success
    probe.executor.remove_node(node)
    node.close()
    lines = capfd.readouterr().err.strip().splitlines()
    assert "[last.line.sim_node]: stopped at t = 0.020 s after 1 chunks" in lines[-1], lines


def test_a_brake_models_further_quantities_are_published_per_vehicle(ros_context, probe,
                                                                       nodes):
    from pathlib import Path

    pipe = Path(__file__).resolve().parents[2] / "config" / "brake_params" / \
        "uic_brake_pipe.yaml"
    topics = ("/ex/vehicles/brake_pipe_pressure", "/ex/vehicles/brake_cylinder_pressure")
    for topic in topics:
        probe.subscribe(topic, Float64MultiArray)
    nodes(make_node(ros_context, "/ex", "/ex/clock", lockstep=True, steps_per_call=100,
                    auto_brake_at_s=0.0, brake_params_file=str(pipe)))
    probe.wait_matched(list(topics))
    assert probe.call(Trigger, "/ex/sim_node/step", Trigger.Request()).success
    got = probe.received
    probe.spin_until(lambda: all(len(got[t]) >= 101 for t in topics), 20, "101 states")
    pipe_pa, cylinder_pa = (np.array([m.data for m in got[t]]) for t in topics)
    assert pipe_pa.shape == cylinder_pa.shape == (101, 33)
    # charged to the UIC running pressure, 5 bar gauge (UIC 540), brakes released
    np.testing.assert_allclose(pipe_pa[0], 5e5, rtol=0.01)
    np.testing.assert_allclose(cylinder_pa[0], 0.0, atol=1e3)
    # two seconds after the emergency command the pipe vents from the head backwards and the
    # head's cylinder fills
    assert pipe_pa[-1, 0] < pipe_pa[-1, 16] < 5e5 and cylinder_pa[-1, 0] > 1e5
