"""``sim_node``: the train simulator served as a live ROS 2 plant.

An adapter: parameters (:mod:`.params`) -> run spec -> :class:`~ltd_brake_ros.simulator.Simulator`
-> :class:`~ltd_brake_ros.plant.runner.PlantRunner` (the plant thread: chunks paced by a
real-time factor, jobs, lock-step, run policy, recorder lifecycle), wired to ROS here. Topic names
are relative (``-r __ns:=/train1`` moves them); SI units; vehicle 0 is the head, coupler 1 the
one behind it:

* publishes once per chunk ``vehicles/speed`` [m/s, forward positive], ``vehicles/position``
  [m, each vehicle's centre], ``vehicles/brake_force`` [N, retarding positive],
  ``vehicles/traction_force`` [N, dynamic brake negative] and ``couplers/force`` [N, draft
  positive, buff negative] (``std_msgs/Float64MultiArray``, ``layout.dim[0]`` labelled
  ``vehicle`` or ``coupler``), and ``/clock`` when ``publish_clock``; ``/diagnostics`` about
  once per wall second;
* subscribes ``brake_command`` (``std_msgs/Bool``: emergency brake from the next chunk on,
  false releases), ``brake_demand`` (``std_msgs/Float64``, 0-1, service brake) and
  ``traction_command`` (``std_msgs/Float64``, -1 full dynamic brake to 1 full traction); a
  NaN, infinite or out-of-range value is rejected and logged;
* records every message it publishes and receives with ``record:=true`` (rosbag2 MCAP folder);
* serves ``~/reset`` and ``~/step`` (``std_srvs/Trigger``; a step advances ``steps_per_call``
  chunks in lock-step mode or paused) and ``~/pause`` (``std_srvs/SetBool``).

Everything the node publishes or receives passes through :meth:`SimNode._emit` or
:meth:`SimNode._input_handled` on the plant thread, where :meth:`SimNode.add_tap` observers see
it in order. The program (:func:`main`, :mod:`.program`) refuses in one line a parameter the node
does not have (a typo), an argument outside ``--ros-args`` and an unreadable parameter file;
SIGINT or SIGTERM at any moment ends it cleanly, the recording finished.
"""
from __future__ import annotations

from .program import install_if_program, run, unknown_parameters

# before the imports below (a second or two): a signal while they load ends the program cleanly
_SIGNALS = install_if_program("sim_node")

import sys  # noqa: E402
import time  # noqa: E402
from typing import Any, Callable  # noqa: E402

import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Bool, Float64MultiArray  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from ..plant.diagnostics import PlantStatus  # noqa: E402
from ..plant.recorder import Recorder  # noqa: E402
from ..plant.runner import PlantRunner  # noqa: E402
from ..recording.bag import message_class, type_name  # noqa: E402
from ..recording.metadata import run_metadata  # noqa: E402
from ..recording.plant_topics import ARRAY_TOPICS, CLOCK_TOPIC, COMMAND_TOPICS  # noqa: E402
from ..recording.qos import qos_profiles_yaml  # noqa: E402
from ..simulator import Snapshot  # noqa: E402
from .messages import (CLOCK_QOS, COMMAND_QOS, DIAGNOSTICS_QOS, STATE_QOS,  # noqa: E402
                       array_msg, diagnostics_msg, time_msg)
from .params import (PARAMETERS, StartupError, build_simulator,  # noqa: E402
                     check_run_time_change, declare_parameters, load_plant_inputs,
                     plant_settings)

NODE_NAME = "sim_node"
DIAGNOSTICS_TOPIC = "/diagnostics"
#: Input topics: message class and the plant input each one sets (the one table of
#: :mod:`~ltd_brake_ros.recording.plant_topics`, which the published arrays come from too).
INPUT_TOPICS = {topic: (message_class(msg_type), name)
                for topic, (msg_type, name) in COMMAND_TOPICS.items()}

Tap = Callable[[str, Any, int, bool], None]


class SimNode(Node):
    """The simulator as a ROS 2 plant (see the module docstring for the interface).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ...).

    Raises
    ------
    StartupError
        A parameter value is unusable, a given parameter is not one of the node's, or
        ``record_dir`` holds anything; the node is destroyed again.
    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.runner: PlantRunner | None = None
        try:
            self._setup()
        except BaseException:  # a bad parameter, or SIGINT/SIGTERM during start-up
            self.destroy_node()
            raise

    def _setup(self) -> None:
        p = declare_parameters(self)
        unknown = unknown_parameters(self, [spec.name for spec in PARAMETERS])
        if unknown:
            raise StartupError(*unknown)
        self.inputs = spec = load_plant_inputs(
            p["consist"], p["initial_speed_kmh"], p["brake_params_file"], p["coupler_lut_file"],
            p["track_file"], p["start_chainage_m"])
        self.simulator = build_simulator(spec, p["chunk_s"])
        self._taps: list[Tap] = []
        self._outputs = {topic: self.create_publisher(Float64MultiArray, topic, STATE_QOS)
                         for topic, _, _ in ARRAY_TOPICS}
        if p["publish_clock"]:
            self._outputs[CLOCK_TOPIC] = self.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
        self._outputs[DIAGNOSTICS_TOPIC] = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self._inputs = {name: self.create_subscription(msg_type, topic, self._receiver(name),
                                                       COMMAND_QOS)
                        for topic, (msg_type, name) in INPUT_TOPICS.items()}
        recorder = None
        if p["record"]:
            endpoints = [*self._outputs.values(), *self._inputs.values()]
            recorder = Recorder(
                p["record_dir"] or time.strftime("runs/run_%Y%m%d-%H%M%S"),
                [(e.topic_name, type_name(e.msg_type), qos_profiles_yaml(e.qos_profile))
                 for e in endpoints], self.get_logger(),
                metadata=run_metadata(self.simulator, scenario=spec.origin, parameters=dict(p),
                                      brake_params=str(spec.params.source),
                                      coupler_lut=str(spec.lut.source),
                                      track=str(spec.track.source)))
            recorder.check()
        self.runner = PlantRunner(
            self.simulator, plant_settings(p), publish_state=self._publish_state,
            publish_status=self._publish_status, input_handled=self._input_handled,
            log=self.get_logger(), recorder=recorder, host_ok=self.context.ok,
            labels={name: sub.topic_name for name, sub in self._inputs.items()})
        self.create_service(Trigger, "~/reset", lambda q, r: self._reply(self.runner.reset(), r))
        self.create_service(SetBool, "~/pause",
                            lambda q, r: self._reply(self.runner.pause(q.data), r))
        self.create_service(Trigger, "~/step", lambda q, r: self._reply(self.runner.step(), r))
        self.add_on_set_parameters_callback(
            lambda params: check_run_time_change(params, self.runner.real_time_factor))
        self.add_post_set_parameters_callback(self._apply_parameters)
        c, s = spec.consist, self.runner.settings
        mode = "lock-step" if s.lockstep else f"real_time_factor {s.real_time_factor:g}"
        self.get_logger().info(
            f"{c.name}: {c.n} vehicles, {c.length_m:.0f} m, {c.mass_kg / 1e3:.0f} t "
            f"({spec.origin}) at {spec.speed_kmh:g} km/h; chunk {s.chunk_s:g} s, {mode}")

    def _receiver(self, name: str) -> Callable[[Any], None]:
        def receive(msg):
            self.runner.receive(name, msg.data, msg)
            self.runner.yield_to_plant()
        return receive

    def _reply(self, job, response):
        response.success, response.message = self.runner.result(job)
        return response

    def _apply_parameters(self, params) -> None:
        for p in params:
            if p.name == "real_time_factor":
                self.runner.set_real_time_factor(p.value)
            elif p.name == "steps_per_call":
                self.runner.steps_per_call = p.value

    # ------------------------------------------------------------------ public API

    def add_tap(self, tap: Tap) -> None:
        """Observe every message the node publishes or receives.

        Parameters
        ----------
        tap : callable
            Called on the plant thread as ``tap(topic, msg, sim_time_ns, inbound)`` with the
            fully qualified topic name, the message, the simulated time [ns] it belongs to and
            whether it was received (True) or published (False).
        """
        self._taps.append(tap)

    def start(self) -> None:
        """Open the recording (if any) and start the plant thread (initial state, then runs).

        Raises
        ------
        StartupError
            The recording cannot be opened (parameter ``record_dir``).
        """
        if self.runner.recorder is not None:
            self.runner.recorder.open()
        self.runner.start()

    def running(self) -> bool:
        """False once a run-policy limit ended the run or the plant thread died."""
        return not self.runner.finished.is_set()

    @property
    def exit_status(self) -> int:
        """0, or 1 once the plant thread died of an unexpected error."""
        return self.runner.exit_status

    def close(self) -> None:
        """Stop the plant thread, finish the recording and destroy the node."""
        runner = self.runner
        runner.close()
        self.destroy_node()
        if runner.stats.chunks or runner.stamp_ns:
            rclpy.logging.get_logger(NODE_NAME).info(
                f"stopped at t = {runner.sim_time_s:.3f} s after {runner.stats.chunks} chunks")

    # ------------------------------------------------------------------ the one way out and in

    def _emit(self, topic: str, msg: Any) -> None:
        """Publish ``msg`` on ``topic`` (a key of ``self._outputs``), record it, show it to taps."""
        publisher, runner = self._outputs[topic], self.runner
        if runner.recorder is not None and runner.recorder.active:
            # serialise once: the recording holds exactly the bytes sent
            data = serialize_message(msg)
            publisher.publish(data)
            runner.recorder.write(publisher.topic_name, data, runner.stamp_ns)
        else:
            publisher.publish(msg)
        for tap in self._taps:
            tap(publisher.topic_name, msg, runner.stamp_ns, False)

    def _input_handled(self, name: str, value: Any, msg: Any) -> None:
        """Record and show a received (or the plant's own) input, on the plant thread."""
        topic, runner = self._inputs[name].topic_name, self.runner
        msg = msg if msg is not None else Bool(data=bool(value))
        if runner.recorder is not None and runner.recorder.active:
            runner.recorder.write(topic, serialize_message(msg), runner.stamp_ns)
        for tap in self._taps:
            tap(topic, msg, runner.stamp_ns, True)

    def _publish_state(self, snap: Snapshot) -> None:
        for topic, attribute, label in ARRAY_TOPICS:
            self._emit(topic, array_msg(label, getattr(snap, attribute)))
        if CLOCK_TOPIC in self._outputs:
            self._emit(CLOCK_TOPIC, Clock(clock=time_msg(self.runner.stamp_ns)))

    def _publish_status(self, status: PlantStatus) -> None:
        self._emit(DIAGNOSTICS_TOPIC, diagnostics_msg(
            status, f"{self.get_fully_qualified_name()}: train plant",
            self.inputs.consist.name, self.runner.stamp_ns))


def main(args: list[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM or a run-policy limit (``max_sim_time_s``, ...).

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments (default: ``sys.argv``), e.g. ``--ros-args -p chunk_s:=0.05``.

    Returns
    -------
    int
        Exit status: 0 after a clean shutdown (a signal included), 1 when the node cannot start
        (one line names the parameter or argument) or the plant thread died of an unexpected
        error.
    """
    return run(NODE_NAME, args, lambda _positional: SimNode(),
               usage="sim_node [--ros-args -p name:=value ... --params-file file.yaml]",
               signals=_SIGNALS, errors=(StartupError,))


if __name__ == "__main__":
    sys.exit(main())
