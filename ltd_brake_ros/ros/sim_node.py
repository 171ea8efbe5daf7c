"""``sim_node``: the train simulator served as a live ROS 2 plant.

An adapter: parameters (:mod:`.params`) -> run spec -> :class:`~ltd_brake_ros.simulator.Simulator`
-> :class:`~ltd_brake_ros.plant.runner.PlantRunner` (the plant thread: chunks paced by a
real-time factor, jobs, lock-step, run policy, recorder lifecycle), wired to ROS here. Topic names
are relative (``-r __ns:=/train1`` moves them); SI units; vehicle 0 is the head, coupler 1 the
one behind it:

* publishes once per chunk (or every ``publish_every``-th) ``vehicles/speed`` [m/s, forward
  positive], ``vehicles/position`` [m, each vehicle's centre], ``vehicles/brake_force`` [N,
  retarding positive], ``vehicles/traction_force`` [N, dynamic brake negative] and
  ``couplers/force`` [N, draft positive, buff negative] (``std_msgs/Float64MultiArray``,
  ``layout.dim[0]`` labelled ``vehicle`` or ``coupler``); the same state stamped with the
  simulated time as ``sensor_msgs/JointState`` on ``vehicles/state`` (``vehicle_<i>``: position,
  velocity, effort = brake force) and ``couplers/state`` (``coupler_<j>``: elongation [m],
  its rate [m/s], force); the brake model's further per-vehicle quantities on
  ``vehicles/<quantity>``; ``/clock`` when it is the clock source; ``/diagnostics`` about
  once per wall second;
* ``clock``: ``auto`` publishes ``/clock`` unless another node already does, then follows it;
  ``follow`` advances to the ``/clock`` of another plant (several trains, one simulated time);
  a second ``/clock`` publisher is warned about, naming it;
* subscribes ``brake_command`` (``std_msgs/Bool``: emergency brake from the next chunk on,
  false releases), ``brake_demand`` (``std_msgs/Float64``, 0-1, service brake) and
  ``traction_command`` (``std_msgs/Float64``, -1 full dynamic brake to 1 full traction); a
  NaN, infinite or out-of-range value is rejected and logged;
* records every message it publishes and receives with ``record:=true`` (rosbag2 MCAP folder);
* serves ``~/reset`` (``std_srvs/Trigger``: the run-defining parameters set since take effect
  then, or the reset is refused with the reason), ``~/step`` (``std_srvs/Trigger``; a step
  advances ``steps_per_call`` chunks in lock-step mode or paused, with every command message
  that reached the node before the request) and ``~/pause`` (``std_srvs/SetBool``).

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
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Bool, Float64MultiArray  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from ..plant.diagnostics import PlantStatus, format_fixed  # noqa: E402
from ..plant.recorder import Recorder  # noqa: E402
from ..plant.runner import PlantRunner  # noqa: E402
from ..recording.bag import message_class, type_name  # noqa: E402
from ..recording.metadata import run_metadata  # noqa: E402
from ..recording.plant_topics import (ARRAY_TOPICS, CLOCK_TOPIC, COMMAND_TOPICS,  # noqa: E402
                                      STATE_TOPICS, StateEncoder, extra_topic)
from ..recording.qos import qos_profiles_yaml  # noqa: E402
from ..simulator import Simulator, Snapshot  # noqa: E402
from .messages import (CLOCK_QOS, COMMAND_QOS, DIAGNOSTICS_QOS, STATE_QOS,  # noqa: E402
                       diagnostics_msg)
from .params import (PARAMETERS, RESET_PARAMETERS, StartupError,  # noqa: E402
                     build_simulator, check_run_time_change, declare_parameters,
                     load_plant_inputs, plant_settings)

NODE_NAME = "sim_node"
DIAGNOSTICS_TOPIC = "/diagnostics"
#: Input topics: message class and the plant input each one sets (the one table of
#: :mod:`~ltd_brake_ros.recording.plant_topics`, which the published topics come from too).
INPUT_TOPICS = {topic: (message_class(msg_type), name)
                for topic, (msg_type, name) in COMMAND_TOPICS.items()}
#: Wall time between two looks for other ``/clock`` publishers while publishing it [s].
CLOCK_WATCH_PERIOD_S = 1.0
#: ``clock:=auto`` looks for another ``/clock`` publisher until this long after the node was
#: created, and at least CLOCK_DISCOVERY_MIN_S (DDS discovery of the other processes'
#: endpoints takes a moment, seconds on a busy machine) [s].
CLOCK_DISCOVERY_S = 3.0
CLOCK_DISCOVERY_MIN_S = 1.0
#: Wall time between two looks during that wait [s].
CLOCK_DISCOVERY_POLL_S = 0.05

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
        self._created = time.monotonic()
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
        if p["clock"] == "follow" and p["lockstep"]:
            raise StartupError("clock", "follow cannot be combined with lockstep:=true: the "
                               "plant publishing /clock steps this one")
        self._params = p
        self._run_values = {name: p[name] for name in RESET_PARAMETERS}
        spec, self.simulator = self._build_run(p)
        self.inputs = spec
        self._taps: list[Tap] = []
        log = self.get_logger()
        # after the kernel is loaded, while discovery finds the other nodes
        self.clock_mode = self._resolve_clock(p["clock"], p["lockstep"])
        self._outputs = {topic: self.create_publisher(Float64MultiArray, topic, STATE_QOS)
                         for topic, _, _ in ARRAY_TOPICS}
        self._outputs.update({topic: self.create_publisher(JointState, topic, STATE_QOS)
                              for topic, _ in STATE_TOPICS})
        self._add_extra_publishers(self.simulator)
        if self.clock_mode == "publish":
            self._outputs[CLOCK_TOPIC] = self.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
            self._clock_warned: set[str] = set()
            self.create_timer(CLOCK_WATCH_PERIOD_S, self._watch_clock)
        elif self.clock_mode == "follow":
            self.create_subscription(
                Clock, CLOCK_TOPIC,
                lambda msg: self.runner.follow(msg.clock.sec * 1_000_000_000
                                               + msg.clock.nanosec), CLOCK_QOS)
        self._outputs[DIAGNOSTICS_TOPIC] = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self._inputs = {name: self.create_subscription(msg_type, topic, self._receiver(name),
                                                       COMMAND_QOS)
                        for topic, (msg_type, name) in INPUT_TOPICS.items()}
        self._encoder: StateEncoder | None = None
        self._encoded_sim: Simulator | None = None
        recorder = None
        if p["record"]:
            recorder = Recorder(
                p["record_dir"] or time.strftime("runs/run_%Y%m%d-%H%M%S"),
                self._recorded_topics(), log, metadata=self._metadata(spec, self.simulator, p))
            recorder.check()
        self.runner = PlantRunner(
            self.simulator, plant_settings(p, self.clock_mode == "follow"),
            publish_state=self._publish_state, publish_status=self._publish_status,
            input_handled=self._input_handled, log=log, recorder=recorder,
            host_ok=self.context.ok,
            labels={name: sub.topic_name for name, sub in self._inputs.items()})
        self.create_service(Trigger, "~/reset", self._reset_service)
        self.create_service(SetBool, "~/pause",
                            lambda q, r: self._reply(self.runner.pause(q.data), r))
        self.create_service(Trigger, "~/step", self._step_service)
        self.add_on_set_parameters_callback(
            lambda params: check_run_time_change(params, self.runner.real_time_factor))
        self.add_post_set_parameters_callback(self._apply_parameters)
        s = self.runner.settings
        mode = "following /clock" if s.follow_clock else "lock-step" if s.lockstep else \
            f"real_time_factor {s.real_time_factor:g}"
        clock = {"publish": "publishes /clock", "follow": "", "none": "no /clock"}[self.clock_mode]
        log.info(f"{self._describe(spec)}; chunk {s.chunk_s:g} s, {mode}"
                 + (f", {clock}" if clock else ""))

    @staticmethod
    def _build_run(p: dict) -> tuple[Any, Simulator]:
        """The run the parameters ``p`` describe: its inputs and simulator (StartupError)."""
        spec = load_plant_inputs(p["consist"], p["initial_speed_kmh"], p["brake_params_file"],
                                 p["coupler_lut_file"], p["track_file"], p["start_chainage_m"])
        return spec, build_simulator(spec, p["chunk_s"], p["tolerance_m_s"])

    @staticmethod
    def _describe(spec) -> str:
        c = spec.consist
        return (f"{c.name}: {c.n} vehicles, {c.length_m:.0f} m, {c.mass_kg / 1e3:.0f} t "
                f"({spec.origin}) at {spec.speed_kmh:g} km/h")

    def _metadata(self, spec, sim: Simulator, p: dict) -> dict:
        return run_metadata(sim, scenario=spec.origin, parameters=dict(p),
                            brake_params=str(spec.params.source),
                            coupler_lut=str(spec.lut.source), track=str(spec.track.source))

    def _recorded_topics(self) -> list[tuple[str, str, str]]:
        endpoints = [*self._outputs.values(), *self._inputs.values()]
        return [(e.topic_name, type_name(e.msg_type), qos_profiles_yaml(e.qos_profile))
                for e in endpoints]

    def _add_extra_publishers(self, sim: Simulator) -> None:
        """Publishers of the brake model's further per-vehicle quantities of ``sim``."""
        for key in sim.snapshot().extras:
            topic = extra_topic(key)
            if topic not in self._outputs:
                self._outputs[topic] = self.create_publisher(Float64MultiArray, topic,
                                                             STATE_QOS)

    # ------------------------------------------------------------------ clock

    def _other_clock_publishers(self) -> list[str]:
        """Fully qualified names of the other nodes publishing this node's ``/clock``."""
        me = (self.get_namespace(), self.get_name())
        found = []
        for info in self.get_publishers_info_by_topic(self.resolve_topic_name(CLOCK_TOPIC)):
            if (info.node_namespace, info.node_name) == me:
                continue
            if "_UNKNOWN_" in info.node_name:  # endpoint seen before its node's name
                found.append("another node")
            else:
                found.append(f"{info.node_namespace.rstrip('/')}/{info.node_name}")
        return sorted(set(found))

    def _resolve_clock(self, mode: str, lockstep: bool) -> str:
        """``publish``, ``follow`` or ``off`` for the ``clock`` parameter (``auto`` resolved)."""
        if mode != "auto":
            return mode
        deadline = max(self._created + CLOCK_DISCOVERY_S,
                       time.monotonic() + CLOCK_DISCOVERY_MIN_S)
        while not (others := self._other_clock_publishers()) and time.monotonic() < deadline:
            time.sleep(CLOCK_DISCOVERY_POLL_S)
        if not others:
            return "publish"
        named = time.monotonic() + CLOCK_DISCOVERY_MIN_S  # its node's name follows shortly
        while others == ["another node"] and time.monotonic() < named:
            time.sleep(CLOCK_DISCOVERY_POLL_S)
            others = self._other_clock_publishers() or others
        clock = self.resolve_topic_name(CLOCK_TOPIC)
        self.get_logger().info(
            f"{clock} is published by {', '.join(others)}: following it, one simulated time "
            f"for both{' (lockstep ignored: that clock steps this train)' if lockstep else ''}; "
            "clock:=publish would publish a second clock")
        return "follow"

    def _watch_clock(self) -> None:
        """Warn once about each other node that publishes ``/clock`` too."""
        new = [name for name in self._other_clock_publishers()
               if name not in self._clock_warned and name != "another node"]
        if new:
            self._clock_warned.update(new)
            self.get_logger().warning(
                f"{', '.join(new)} also publish(es) {self.resolve_topic_name(CLOCK_TOPIC)}: "
                "time jumps back and forth for every node using it; start one plant with "
                "clock:=publish and the others with clock:=follow")

    # ------------------------------------------------------------------ services, parameters

    def _receiver(self, name: str) -> Callable[[Any], None]:
        def receive(msg):
            self.runner.receive(name, msg.data, msg)
            self.runner.yield_to_plant()
        return receive

    def _drain_inputs(self) -> None:
        """Hand the plant every command message waiting in the readers (before a step)."""
        for name, sub in self._inputs.items():
            while True:
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is None:
                    break
                self.runner.receive(name, taken[0].data, taken[0])

    def _reply(self, job, response):
        response.success, response.message = self.runner.result(job)
        return response

    def _step_service(self, request, response):
        # a command published before the request is in the step: on this one thread, what
        # waits in the readers goes to the plant ahead of the step
        self._drain_inputs()
        return self._reply(self.runner.step(), response)

    def _reset_service(self, request, response):
        values = {name: self.get_parameter(name).value for name in RESET_PARAMETERS}
        if values == self._run_values:
            return self._reply(self.runner.reset(), response)
        p = self._params | values
        try:
            spec, sim = self._build_run(p)
        except StartupError as exc:
            response.success = False
            response.message = (f"not reset: parameter {exc.parameter}: {exc.reason}; the "
                                "run goes on as it was")
            self.get_logger().error(response.message)
            return response
        self._add_extra_publishers(sim)
        recording = None if self.runner.recorder is None else \
            (self._recorded_topics(), self._metadata(spec, sim, p))
        job = self.runner.reset((sim, plant_settings(p, self.clock_mode == "follow")), recording)
        response.success, response.message = self.runner.result(job)
        if response.success:
            self.inputs, self.simulator, self._params, self._run_values = spec, sim, p, values
            self.get_logger().info(f"new run: {self._describe(spec)}")
            response.message += f"; new run: {self._describe(spec)}"
        return response

    def _apply_parameters(self, params) -> None:
        for p in params:
            if p.name == "real_time_factor":
                self.runner.set_real_time_factor(p.value)
            elif p.name == "steps_per_call":
                self.runner.steps_per_call = p.value
            elif p.name in RESET_PARAMETERS:
                self.get_logger().info(f"{p.name} set to {p.value!r}: takes effect at the "
                                       "next ~/reset")

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
        runner, logger = self.runner, self.get_logger().name  # keeps the namespace
        runner.close()
        self.destroy_node()
        if runner.stats.chunks or runner.stamp_ns:
            rclpy.logging.get_logger(logger).info(
                f"stopped at t = {format_fixed(runner.sim_time_s)} s after "
                f"{runner.stats.chunks} chunks")

    # ------------------------------------------------------------------ the one way out and in

    def _emit(self, topic: str, msg: Any) -> None:
        """Publish ``msg`` (a message, or its serialized bytes) on ``topic`` (a key of
        ``self._outputs``), record it, show it to taps."""
        publisher, runner = self._outputs[topic], self.runner
        recorder = runner.recorder
        if isinstance(msg, bytes):
            data = msg
            publisher.publish(data)
            if self._taps:
                msg = deserialize_message(data, publisher.msg_type)
        elif recorder is not None and recorder.active:
            # serialise once: the recording holds exactly the bytes sent
            data = serialize_message(msg)
            publisher.publish(data)
        else:
            data = None
            publisher.publish(msg)
        if recorder is not None and recorder.active:
            recorder.write(publisher.topic_name, data, runner.stamp_ns)
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
        sim = self.runner.sim
        if sim is not self._encoded_sim:  # the first state of a run: its train's layout
            self._encoded_sim = sim
            self._encoder = StateEncoder(sim.n, sim.model.train.centre_offset_m,
                                         extras=snap.extras,
                                         clock=CLOCK_TOPIC in self._outputs)
        for topic, data in self._encoder.encode(snap, self.runner.stamp_ns):
            self._emit(topic, data)

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
