"""``sim_node``: the train simulator served as a live ROS 2 plant.

A thin adapter, rclpy wiring only: parameters (:mod:`.params`) -> a run
(:class:`~ltd_brake_ros.plant.run.PlantRun`: inputs, simulator, settings; rebuilt at a reset)
-> :class:`~ltd_brake_ros.plant.runner.PlantRunner` (the plant thread: chunks paced by a
real-time factor, inputs, jobs, lock-step, run policy, recorder lifecycle), the ``/clock`` policy
in :mod:`~ltd_brake_ros.plant.clock_policy`. Topic names
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
  once per wall second; ``train/description`` (``std_msgs/String``, JSON: the run, every
  vehicle and coupler with its joint name, units and signs) once per run, latched
  (transient-local) for tools that join late; ``odom`` (``nav_msgs/Odometry`` of the head) and
  ``/tf`` (``map`` -> ``<prefix>base_link``, the head, with every published chunk;
  ``<prefix>vehicle_<i>`` at ``tf_vehicle_rate_hz``; see :mod:`~ltd_brake_ros.recording.frames`;
  ``/tf`` only where ``tf2_msgs`` is installed); ``train/markers``
  (``visualization_msgs/MarkerArray`` in the head's frame: a box per vehicle coloured by its
  brake, a box per coupler coloured by its force against its strength, labels; about 10 per
  wall second while subscribed, and at ``tf_vehicle_rate_hz`` of simulated time when
  ``record_frames`` records them);
* ``clock``: ``auto`` publishes ``/clock`` unless another node already does, then follows it;
  ``follow`` advances to the ``/clock`` of another plant (several trains, one simulated time);
  a second ``/clock`` publisher is warned about, naming it;
* subscribes ``brake_command`` (``std_msgs/Bool``: emergency brake from the next chunk on,
  false releases), ``brake_demand`` (``std_msgs/Float64``, 0-1, service brake) and
  ``traction_command`` (``std_msgs/Float64``, -1 full dynamic brake to 1 full traction) and
  ``driver_brake_valve`` (``std_msgs/String``: a position of the driver's brake valve,
  :data:`~ltd_brake_ros.inputs.commands.VALVE_POSITIONS`); a NaN, infinite or out-of-range
  value or an unknown position is rejected and logged;
* records every message it publishes and receives with ``record:=true`` (rosbag2 MCAP folder;
  ``/tf``, ``odom`` and the markers with ``record_frames:=true``);
* serves ``~/reset`` (``std_srvs/Trigger``: the run-defining parameters set since take effect
  then, or the reset is refused with the reason), ``~/step`` (``std_srvs/Trigger``; a step
  advances ``steps_per_call`` chunks in lock-step mode or paused, with every command message
  that reached the node before the request) and ``~/pause`` (``std_srvs/SetBool``); and the
  ``simulation_interfaces`` services (:mod:`.sim_control`) where that package is installed.
  Pause, parameter and state requests are served during a step of any length (the node runs
  on several threads; commands, steps and resets share one group, so a step still runs with
  the commands that reached the node before it).

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
import threading  # noqa: E402
import time  # noqa: E402
from typing import Any, Callable  # noqa: E402

import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.callback_groups import (MutuallyExclusiveCallbackGroup,  # noqa: E402
                                   ReentrantCallbackGroup)
from rclpy.node import Node  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Bool, Float64MultiArray, String  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from ..plant.clock_policy import (CLOCK_WATCH_PERIOD_S, ClockWatch,  # noqa: E402
                                  other_publishers, resolve_clock)
from ..plant.diagnostics import PlantStatus, format_fixed  # noqa: E402
from ..plant.markers import train_markers  # noqa: E402
from ..plant.recorder import Recorder  # noqa: E402
from ..plant.run import (RUN_INPUT_PARAMETERS, PlantRun, check_run_inputs,  # noqa: E402
                         reset_run)
from .._version import __version__  # noqa: E402
from ..plant.runner import PlantRunner  # noqa: E402
from ..recording.bag import message_class, type_name  # noqa: E402
from ..recording.frames import (FIXED_FRAME, MARKERS_TOPIC, ODOM_TOPIC, TF_TOPIC,  # noqa: E402
                                FramesEncoder, frame_prefix)
from ..recording.metadata import model_warnings, train_description  # noqa: E402
from ..recording.plant_topics import (ARRAY_TOPICS, CLOCK_TOPIC, COMMAND_TOPICS,  # noqa: E402
                                      DESCRIPTION_TOPIC, STATE_TOPICS, STOPS_TOPIC,
                                      StateEncoder)
from ..recording.qos import qos_profiles_yaml  # noqa: E402
from ..simulator import Simulator, Snapshot  # noqa: E402
from . import sim_control  # noqa: E402
from .messages import (CLOCK_QOS, COMMAND_QOS, DESCRIPTION_QOS, DIAGNOSTICS_QOS,  # noqa: E402
                       MARKERS_QOS, STATE_QOS, STOPS_QOS, TF_QOS, clear_markers_msg,
                       diagnostics_msg, marker_array_msg)
from .params import (PARAMETERS, RESET_PARAMETERS, StartupError,  # noqa: E402
                     check_run_time_change, declare_parameters)

NODE_NAME = "sim_node"
#: Executor threads: one may wait for a long step while the others serve pause, parameter and
#: state requests.
EXECUTOR_THREADS = 3
#: Wall time between two marker pictures of a train of up to 100 vehicles [s].
MARKER_PERIOD_S = 0.1
DIAGNOSTICS_TOPIC = "/diagnostics"
#: Input topics: message class and the plant input each one sets (the one table of
#: :mod:`~ltd_brake_ros.recording.plant_topics`, which the published topics come from too).
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
        log = self.get_logger()
        self.plant_run = PlantRun.build(p, say=log.info)  # says so if its kernels compile
        self._taps: list[Tap] = []
        # after the kernel is loaded, while discovery finds the other nodes
        clock_topic = self.resolve_topic_name(CLOCK_TOPIC)
        self.clock_mode, line = resolve_clock(p["clock"], p["lockstep"], self._other_clocks,
                                              self._created, clock_topic)
        if line:
            log.info(line)
        # commands, steps and resets in one group (a step runs with the commands that came
        # before it); pause, state and parameter requests apart, served during a step
        self._plant_group = MutuallyExclusiveCallbackGroup()
        self._control_group = ReentrantCallbackGroup()
        #: output key -> its resolved topic name
        self._output_names: dict[str, str] = {}
        self._outputs = {DESCRIPTION_TOPIC: self.create_publisher(String, DESCRIPTION_TOPIC,
                                                                  DESCRIPTION_QOS),
                         STOPS_TOPIC: self.create_publisher(String, STOPS_TOPIC, STOPS_QOS)}
        self._outputs.update({topic: self.create_publisher(Float64MultiArray, topic, STATE_QOS)
                              for topic, _, _ in ARRAY_TOPICS})
        self._outputs.update({topic: self.create_publisher(JointState, topic, STATE_QOS)
                              for topic, _ in STATE_TOPICS})
        self._add_extra_publishers(self.plant_run)
        # where the train is: odometry, /tf, markers; recorded with record_frames only
        self._prefix = frame_prefix(self.get_namespace())
        self._vehicle_rate_hz = p["tf_vehicle_rate_hz"]
        self._record_frames = p["record_frames"]
        self._frames: FramesEncoder | None = None
        self._outputs[ODOM_TOPIC] = self.create_publisher(Odometry, ODOM_TOPIC, STATE_QOS)
        tf_type = _tf_message()
        if tf_type is None:
            log.warning("tf2_msgs is not installed: /tf is not published and the markers are "
                        f"drawn in {FIXED_FRAME} (./dev.sh builds tf2_msgs; a ROS "
                        "installation has it)")
        else:
            self._outputs[TF_TOPIC] = self.create_publisher(tf_type, TF_TOPIC, TF_QOS)
        self._markers = self._outputs[MARKERS_TOPIC] = self.create_publisher(
            MarkerArray, MARKERS_TOPIC, MARKERS_QOS)
        self._unrecorded = set() if self._record_frames else {
            self._outputs[t].topic_name for t in (ODOM_TOPIC, TF_TOPIC, MARKERS_TOPIC)
            if t in self._outputs}
        self._next_markers_wall = 0.0
        if self.clock_mode == "publish":
            self._outputs[CLOCK_TOPIC] = self.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
            watch = ClockWatch(clock_topic)
            self.create_timer(CLOCK_WATCH_PERIOD_S, lambda: self._warn(
                watch.check(self._other_clocks())))
        elif self.clock_mode == "follow":
            self.create_subscription(
                Clock, CLOCK_TOPIC,
                lambda msg: self.runner.follow(msg.clock.sec * 1_000_000_000
                                               + msg.clock.nanosec), CLOCK_QOS,
                callback_group=self._control_group)
        self._outputs[DIAGNOSTICS_TOPIC] = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self._inputs = {name: self.create_subscription(msg_type, topic, self._receiver(name),
                                                       COMMAND_QOS,
                                                       callback_group=self._plant_group)
                        for topic, (msg_type, name) in INPUT_TOPICS.items()}
        self._encoder: StateEncoder | None = None
        self._encoded_sim: Simulator | None = None
        recorder = None
        if p["record"]:
            recorder = Recorder(p["record_dir"] or time.strftime("runs/run_%Y%m%d-%H%M%S"),
                                self._recorded_topics(), log, metadata=self.plant_run.metadata())
            recorder.check()
        self.runner = PlantRunner(
            self.plant_run.sim, self.plant_run.settings(self.clock_mode == "follow"),
            publish_state=self._publish_state, publish_status=self._publish_status,
            input_handled=self._input_handled, log=log, recorder=recorder,
            host_ok=self.context.ok, publish_end=self._publish_end,
            labels={name: sub.topic_name for name, sub in self._inputs.items()})
        self._reset_lock = threading.Lock()
        self.create_service(Trigger, "~/reset", self._reset_service,
                            callback_group=self._plant_group)
        self.create_service(SetBool, "~/pause",
                            lambda q, r: self._reply(self.runner.pause(q.data), r),
                            callback_group=self._control_group)
        self.create_service(Trigger, "~/step", self._step_service,
                            callback_group=self._plant_group)
        if sim_control.available():
            sim_control.serve(self, lambda: self.runner, self._step, self._reset,
                              f"ltd_brake_ros {__version__}: a train plant; a step is one chunk "
                              "(parameter chunk_s); reset and stop start the run again with "
                              "the run parameters set since", plant_group=self._plant_group,
                              control_group=self._control_group)
        else:
            log.info("simulation_interfaces is not installed: serving ~/step, ~/reset and "
                     "~/pause only")
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        log.info(self.plant_run.start_line(self.runner.settings, self.clock_mode))
        for line in model_warnings(self.plant_run.sim):
            log.warning(line)

    @property
    def simulator(self) -> Simulator:
        """The simulator of the run in force."""
        return self.plant_run.sim

    def _recorded_topics(self) -> list[tuple[str, str, str]]:
        endpoints = [*self._outputs.values(), *self._inputs.values()]
        return [(e.topic_name, type_name(e.msg_type), qos_profiles_yaml(e.qos_profile))
                for e in endpoints if e.topic_name not in self._unrecorded]

    def _add_extra_publishers(self, run: PlantRun) -> None:
        """Publishers of the brake model's further per-vehicle quantities of ``run``."""
        for topic in run.extra_topics():
            if topic not in self._outputs:
                self._outputs[topic] = self.create_publisher(Float64MultiArray, topic,
                                                             STATE_QOS)

    def _other_clocks(self) -> list[str]:
        """The other nodes publishing this node's ``/clock``."""
        return other_publishers(
            (self.get_namespace(), self.get_name()),
            [(i.node_namespace, i.node_name) for i in
             self.get_publishers_info_by_topic(self.resolve_topic_name(CLOCK_TOPIC))])

    def _warn(self, line: str | None) -> None:
        if line:
            self.get_logger().warning(line)

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

    def _step(self, chunks: int | None = None) -> tuple[bool, str]:
        # a command published before the request is in the step: in the commands' group,
        # what waits in the readers goes to the plant ahead of the step
        self._drain_inputs()
        return self.runner.result(self.runner.step(chunks))

    def _step_service(self, request, response):
        response.success, response.message = self._step()
        return response

    def _reset(self, hold: bool = False) -> tuple[bool, str]:
        def prepare(run: PlantRun) -> list:
            self._add_extra_publishers(run)
            return self._recorded_topics()

        with self._reset_lock:
            values = {name: self.get_parameter(name).value for name in RESET_PARAMETERS}
            ok, text, self.plant_run = reset_run(self.runner, self.plant_run, values, prepare,
                                                 self.get_logger(), hold)
        return ok, text

    def _reset_service(self, request, response):
        response.success, response.message = self._reset()
        return response

    def _check_parameters(self, params):
        """Refuse at ``param set`` what a reset could not use, with the reason."""
        result = check_run_time_change(params, self.runner.real_time_factor)
        changed = {p.name: p.value for p in params if p.name in RUN_INPUT_PARAMETERS}
        if result.successful and changed:
            values = {name: self.get_parameter(name).value for name in RUN_INPUT_PARAMETERS}
            problem = check_run_inputs(values | changed)
            if problem:
                result.successful = False
                result.reason = f"{problem}; not set, the values in force stay"
        return result

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
        name = self._output_names.get(topic)
        if name is None:  # rclpy asks rcl for it at every call: about 10 us
            name = self._output_names[topic] = publisher.topic_name
        if name in self._unrecorded:
            recorder = None
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
            recorder.write(name, data, runner.stamp_ns)
        for tap in self._taps:
            tap(name, msg, runner.stamp_ns, False)

    def _publish_end(self, events) -> None:
        """The run's end on the stops topic: recorded first (the host may be shutting down and
        refuse to publish), then published."""
        publisher, runner = self._outputs[STOPS_TOPIC], self.runner
        for _topic, data in StateEncoder.encode_events(events):
            if runner.recorder is not None and runner.recorder.active:
                runner.recorder.write(publisher.topic_name, data, runner.stamp_ns)
            if self.context.ok():
                publisher.publish(data)

    def _input_handled(self, name: str, value: Any, msg: Any) -> None:
        """Record and show a received (or the plant's own) input, on the plant thread."""
        topic, runner = self._inputs[name].topic_name, self.runner
        msg = msg if msg is not None else Bool(data=bool(value))
        if runner.recorder is not None and runner.recorder.active:
            runner.recorder.write(topic, serialize_message(msg), runner.stamp_ns)
        for tap in self._taps:
            tap(topic, msg, runner.stamp_ns, True)

    def _publish_state(self, snap: Snapshot) -> None:
        sim, stamp_ns = self.runner.sim, self.runner.stamp_ns
        if sim is not self._encoded_sim:  # the first state of a run: its train's layout
            self._encoded_sim = sim
            self._encoder = StateEncoder(sim.n, sim.model.train.centre_offset_m,
                                         extras=snap.extras,
                                         clock=CLOCK_TOPIC in self._outputs,
                                         description=train_description(
                                             sim, self.plant_run.metadata()))
            self._frames = FramesEncoder(self._prefix, sim.n, self._vehicle_rate_hz,
                                         tf=TF_TOPIC in self._outputs)
            self._next_markers_wall = 0.0
            if self._markers.get_subscription_count():  # the last run's train goes
                self._markers.publish(clear_markers_msg(self._marker_frame()))
        for topic, data in self._encoder.encode(snap, stamp_ns):
            self._emit(topic, data)
        for topic, data in self._frames.encode(snap.time_s, snap.position_m, snap.speed_m_s,
                                               stamp_ns):
            self._emit(topic, data)
        now = time.monotonic()
        live = now >= self._next_markers_wall and self._markers.get_subscription_count()
        if live or (self._record_frames and self._frames.vehicles_sent
                    and self.runner.recorder is not None and self.runner.recorder.active):
            if live:  # at most every MARKER_PERIOD_S of wall time, longer for long trains
                self._next_markers_wall = now + MARKER_PERIOD_S * max(1.0, sim.n / 100.0)
            c, lim = sim.consist, sim.limits
            x = snap.position_m
            if TF_TOPIC in self._outputs:  # drawn in the head's frame, which /tf moves
                x = x - x[0]
            self._emit(MARKERS_TOPIC, marker_array_msg(train_markers(
                x, sim.length_m, snap.block_force_N, sim.max_block_force_N,
                snap.coupler_force_N, lim.draft_strength_N,
                lim.buff_strength_N, [v.name for v in c.vehicles]), self._marker_frame(),
                stamp_ns, self._prefix))

    def _marker_frame(self) -> str:
        """The frame the markers are drawn in: the head's, or the fixed one without /tf."""
        return self._frames.head_frame if TF_TOPIC in self._outputs else FIXED_FRAME

    def _publish_status(self, status: PlantStatus) -> None:
        self._emit(DIAGNOSTICS_TOPIC, diagnostics_msg(
            status, f"{self.get_fully_qualified_name()}: train plant",
            self.plant_run.spec.consist.name, self.runner.stamp_ns))


def _tf_message():
    """``tf2_msgs/msg/TFMessage``, or None where tf2_msgs is not installed."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        return None
    return TFMessage


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
               signals=_SIGNALS, errors=(StartupError,), threads=EXECUTOR_THREADS)


if __name__ == "__main__":
    sys.exit(main())
