"""``sim_node``: the train simulator served as a live ROS 2 plant.

The node is a thin adapter around :class:`~ltd_brake_ros.simulator.Simulator`: it advances the
simulator in fixed chunks of simulated time, paced by a real-time factor, and publishes the state
of the train once per chunk. It contains no physics.

Interface (topic names are relative, so ``--ros-args -r __ns:=/train1`` moves them; SI units;
vehicle 0 is the head, coupler 1 is the one behind it):

* publishes ``vehicles/speed`` [m/s, forward positive], ``vehicles/position`` [m, chainage of
  each vehicle's centre, the head's front starts at 0], ``vehicles/brake_force`` [N, retarding
  force positive] and ``couplers/force`` [N, draft/tension positive, buff negative], all
  ``std_msgs/msg/Float64MultiArray`` with ``layout.dim[0]`` labelled ``vehicle`` or ``coupler``;
  ``/clock`` (``rosgraph_msgs/msg/Clock``) after every chunk when ``publish_clock`` is true;
  ``/diagnostics`` (``diagnostic_msgs/msg/DiagnosticArray``) about once per wall second;
* publishes ``vehicles/traction_force`` [N, traction positive, dynamic brake negative];
* subscribes ``brake_command`` (``std_msgs/msg/Bool``): true applies the emergency brake at the
  start of the next chunk, false releases it (exponential decay with the brake parameters'
  ``t_release_s``); a repeated true does not restart the application;
* subscribes ``brake_demand`` (``std_msgs/msg/Float64``, 0-1: service brake, not validated
  against measurements) and ``traction_command`` (``std_msgs/msg/Float64``, -1-1: dynamic
  brake to full traction); a NaN, infinite or out-of-range value is rejected and logged;
* records, with ``record:=true``, every message it publishes and receives to an MCAP bag
  folder (rosbag2 layout, see :mod:`ltd_brake_ros.bag`);
* services ``~/reset`` (``std_srvs/srv/Trigger``), ``~/pause`` (``std_srvs/srv/SetBool``) and
  ``~/step`` (``std_srvs/srv/Trigger``, advances ``steps_per_call`` chunks when in lock-step
  mode or paused).

Threading: one plant thread owns the simulator and does every advance and every publication;
the executor thread only turns ROS callbacks (commands, services, parameter changes) into jobs
that the plant thread runs between two chunks. So a chunk is always advanced and published in
one place, lock-step runs are deterministic, and everything the node publishes or receives passes
through :meth:`SimNode._emit` or :meth:`SimNode._on_input` on that one thread, where
:meth:`SimNode.add_tap` observers (a recorder, a test) see it in order.
"""
from __future__ import annotations

import array
import math
import queue
import signal
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64, Float64MultiArray, MultiArrayDimension
from std_srvs.srv import SetBool, Trigger

from ..recording.bag import BagWriter, qos_profiles_yaml, type_name
from ..inputs import InputError
from ..run_spec import RunSpec, RunSpecError, resolve_run_spec
from ..simulator import Commands, SimulationError, Simulator, Snapshot

NODE_NAME = "sim_node"

#: State topics: lossless for a subscriber that keeps up, never latched.
STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: Only the newest time matters; a reliable writer also serves best-effort readers
#: (rclpy's and rclcpp's time sources subscribe best-effort).
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: Commands are precious: a deep reader queue keeps a burst (a controller catching up, a script)
#: while the executor is busy; only a sustained flood beyond what rclpy takes is dropped.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
DIAGNOSTICS_QOS = STATE_QOS

#: Published arrays: topic, Snapshot attribute, ``layout.dim[0].label``.
ARRAY_TOPICS = (
    ("vehicles/speed", "speed_m_s", "vehicle"),
    ("vehicles/position", "position_m", "vehicle"),
    ("vehicles/brake_force", "brake_force_N", "vehicle"),
    ("vehicles/traction_force", "traction_force_N", "vehicle"),
    ("couplers/force", "coupler_force_N", "coupler"),
)
CLOCK_TOPIC = "/clock"
DIAGNOSTICS_TOPIC = "/diagnostics"
BRAKE_COMMAND_TOPIC = "brake_command"
BRAKE_DEMAND_TOPIC = "brake_demand"
TRACTION_TOPIC = "traction_command"
#: Numeric input topics: accepted range of ``std_msgs/Float64.data``.
NUMERIC_INPUTS = {BRAKE_DEMAND_TOPIC: (0.0, 1.0), TRACTION_TOPIC: (-1.0, 1.0)}
#: Wall time between two warnings about rejected inputs on one topic [s].
REJECT_LOG_PERIOD_S = 2.0

#: Wall time between two diagnostics messages [s].
DIAGNOSTICS_PERIOD_S = 1.0
#: Largest accepted real-time factor [-].
MAX_REAL_TIME_FACTOR = 1000.0
#: Tolerance when comparing simulated times built from summed chunks [s].
TIME_EPS_S = 1e-9
#: Pacing lateness samples kept for statistics (bounded: memory stays flat on long runs).
LATENESS_SAMPLES = 10_000
#: A command flood keeps the executor thread busy. From this long before a chunk is due until
#: the plant has published it, a receiving callback steps aside (sleeps: frees the GIL and
#: the CPU) so the plant keeps its deadline on a loaded machine [s]; checked every
#: YIELD_POLL_S, for at most YIELD_MAX_S per message.
YIELD_LEAD_S = 0.002
YIELD_POLL_S = 0.0005
YIELD_MAX_S = 0.01


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class ParamSpec:
    """Declaration of one node parameter.

    Attributes
    ----------
    name : str
        Parameter name.
    default : bool, int, float or str
        Default value; its Python type is the parameter type.
    description : str
        Shown by ``ros2 param describe`` (units in brackets).
    read_only : bool
        Structural: fixed once the node runs.
    lo, hi : float or None
        Accepted range (inclusive), for numbers.
    """

    name: str
    default: Any
    description: str
    read_only: bool = True
    lo: float | None = None
    hi: float | None = None

    def descriptor(self) -> ParameterDescriptor:
        """The ROS parameter descriptor (type, description, range, read-only flag)."""
        types = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
                 float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING}
        d = ParameterDescriptor(name=self.name, type=types[type(self.default)],
                                description=self.description, read_only=self.read_only)
        if isinstance(self.default, float) and self.lo is not None:
            d.floating_point_range = [FloatingPointRange(from_value=float(self.lo),
                                                         to_value=float(self.hi), step=0.0)]
        elif isinstance(self.default, int) and not isinstance(self.default, bool) \
                and self.lo is not None:
            d.integer_range = [IntegerRange(from_value=int(self.lo), to_value=int(self.hi),
                                            step=1)]
        return d


#: Every parameter of the node, with its default (mirrored in ``config/sim_node.yaml``).
PARAMETERS = (
    ParamSpec("consist", "scenario_6",
              "Consist YAML file, or a scenario of config/scenarios.yaml given as text "
              "(scenario_6 or '6'; default: the paper's scenario 6)"),
    ParamSpec("initial_speed_kmh", -1.0,
              "Initial speed of every vehicle [km/h]; -1 = the scenario's speed "
              "(a value is required when consist is a file)", lo=-1.0, hi=400.0),
    ParamSpec("brake_params_file", "",
              "Brake-parameter YAML file; empty = the shipped brake_params/paper.yaml"),
    ParamSpec("coupler_lut_file", "",
              "Coupler look-up-table YAML file; empty = the shipped couplers/buffer_hook_pugi.yaml"),
    ParamSpec("chunk_s", 0.02,
              "Simulated time advanced and published per chunk [s]", lo=0.001, hi=10.0),
    ParamSpec("real_time_factor", 1.0,
              "Simulated seconds per wall second: 1 = wall-clock pace, 2 = twice as fast, "
              "0 = as fast as possible; not used in lock-step mode; changeable at run time",
              read_only=False, lo=0.0, hi=MAX_REAL_TIME_FACTOR),
    ParamSpec("lockstep", False,
              "Advance only when ~/step is called (steps_per_call chunks per call)"),
    ParamSpec("steps_per_call", 1,
              "Chunks advanced and published per ~/step call", read_only=False, lo=1, hi=100_000),
    ParamSpec("publish_clock", True,
              "Publish /clock after every chunk, so controllers can use use_sim_time:=true"),
    ParamSpec("auto_brake_at_s", -1.0,
              "Apply the emergency brake by itself at the first chunk boundary at or after "
              "this simulated time [s]; -1 = never", lo=-1.0, hi=1e6),
    ParamSpec("max_sim_time_s", -1.0,
              "Shut down cleanly once the simulated time reaches this [s]; -1 = run until "
              "signalled", lo=-1.0, hi=1e7),
    ParamSpec("shutdown_after_stop_s", -1.0,
              "Shut down cleanly this long after the train has stopped [s simulated]; "
              "-1 = keep running", lo=-1.0, hi=1e6),
    ParamSpec("track_file", "",
              "Track profile (YAML or CSV: chainage -> gradient [per mille], curve radius [m]); "
              "empty = level straight track"),
    ParamSpec("start_chainage_m", 0.0,
              "Chainage of the head's front at t = 0 [m] (overrides the track file's)",
              lo=-1e7, hi=1e7),
    ParamSpec("record", False,
              "Record every published and received message to an MCAP bag folder"),
    ParamSpec("record_dir", "",
              "Bag folder for record:=true; empty = runs/run_<date>-<time> in the working "
              "directory; after ~/reset a new folder <record_dir>_2, _3, ... is started"),
)

_TYPE_WORDS = {bool: "true or false", int: "a whole number", float: "a number with a decimal "
               "point (e.g. 80.0)", str: "text (quote numbers, e.g. consist:=scenario_6)"}


class StartupError(Exception):
    """A parameter value the node cannot start with.

    Parameters
    ----------
    parameter : str
        Name of the offending parameter.
    reason : str
        What is wrong, in words a user can act on.
    """

    def __init__(self, parameter: str, reason: str):
        self.parameter, self.reason = parameter, reason
        super().__init__(f"parameter {parameter}: {reason}")


#: Node parameter of each run-spec input, for error messages.
RUN_SPEC_PARAMETERS = {"consist": "consist", "speed_kmh": "initial_speed_kmh",
                       "brake_params": "brake_params_file", "coupler_lut": "coupler_lut_file",
                       "track": "track_file"}


def load_plant_inputs(consist: str, initial_speed_kmh: float, brake_params_file: str = "",
                      coupler_lut_file: str = "", track_file: str = "",
                      start_chainage_m: float = 0.0) -> RunSpec:
    """Resolve and validate the node's input parameters (see :func:`resolve_run_spec`).

    Parameters
    ----------
    consist : str
        Consist YAML file, or scenario name/number (``scenario_6``, ``6``).
    initial_speed_kmh : float
        Initial speed [km/h]; negative takes the scenario's speed.
    brake_params_file, coupler_lut_file, track_file : str
        Files; empty strings take the shipped defaults (level straight track).
    start_chainage_m : float
        Chainage of the head's front at t = 0 [m].

    Returns
    -------
    RunSpec

    Raises
    ------
    StartupError
        Naming the parameter and the reason.
    """
    try:
        return resolve_run_spec(consist, speed_kmh=initial_speed_kmh,
                                params_file=brake_params_file, lut_file=coupler_lut_file,
                                track_file=track_file, start_chainage_m=start_chainage_m)
    except RunSpecError as exc:
        raise StartupError(RUN_SPEC_PARAMETERS[exc.input_name], exc.detail) from None


# --------------------------------------------------------------------------- messages


def time_msg(time_ns: int) -> Time:
    """``builtin_interfaces/Time`` for a simulated time in nanoseconds."""
    return Time(sec=time_ns // 1_000_000_000, nanosec=time_ns % 1_000_000_000)


def array_msg(label: str, values: np.ndarray) -> Float64MultiArray:
    """A one-dimensional ``Float64MultiArray`` with a labelled layout.

    Parameters
    ----------
    label : str
        ``layout.dim[0].label`` (``vehicle`` or ``coupler``).
    values : ndarray
        The data (SI units).

    Returns
    -------
    Float64MultiArray
    """
    n = int(values.size)
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=n, stride=n)]
    msg.layout.data_offset = 0
    # an array('d') skips rclpy's per-element Python checks
    msg.data = array.array("d", np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return msg


# --------------------------------------------------------------------------- the node


@dataclass
class PacingStats:
    """What pacing cost since start-up (read by diagnostics and the benchmark).

    Attributes
    ----------
    chunks : int
        Chunks advanced and published.
    overruns : int
        Times the plant was still busy when the next chunk was due (schedule restarted then).
    lateness_s : deque of float
        Publication time minus deadline of the most recent paced chunks [s].
    """

    chunks: int = 0
    overruns: int = 0
    lateness_s: deque = field(default_factory=lambda: deque(maxlen=LATENESS_SAMPLES))


class _Job:
    """Work for the plant thread; the executor thread may wait for its result."""

    __slots__ = ("fn", "done", "result")

    def __init__(self, fn: Callable[[], Any]):
        self.fn, self.done, self.result = fn, threading.Event(), None


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
        A parameter value is unusable; the node is destroyed again.
    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        try:
            self._setup()
        except BaseException:
            # e.g. SIGINT during start-up: a bag already opened is finished, not left cut
            if getattr(self, "_recorder", None) is not None:
                self._close_recording()
            self.destroy_node()
            raise

    # ------------------------------------------------------------------ set-up

    def _setup(self) -> None:
        p = self._declare_parameters()
        self.inputs = load_plant_inputs(p["consist"], p["initial_speed_kmh"],
                                        p["brake_params_file"], p["coupler_lut_file"],
                                        p["track_file"], p["start_chainage_m"])
        self._sim = self._build_simulator(self.inputs, p["chunk_s"])
        self._chunk_s = p["chunk_s"]
        self._rtf = p["real_time_factor"]
        self._lockstep = p["lockstep"]
        self._steps_per_call = p["steps_per_call"]
        self._auto_brake_at_s = p["auto_brake_at_s"]
        self._max_sim_time_s = p["max_sim_time_s"]
        self._shutdown_after_stop_s = p["shutdown_after_stop_s"]
        self._init_plant_state()
        self._create_interfaces(p["publish_clock"])
        self._param_values = p
        if p["record"]:
            base = p["record_dir"] or time.strftime("runs/run_%Y%m%d-%H%M%S")
            self._record_base = base
            self._open_recording(base)
        c = self.inputs.consist
        mode = "lock-step" if self._lockstep else f"real_time_factor {self._rtf:g}"
        self.get_logger().info(
            f"{c.name}: {c.n} vehicles, {c.length_m:.0f} m, {c.mass_kg / 1e3:.0f} t "
            f"({self.inputs.origin}) at {self.inputs.speed_kmh:g} km/h; chunk "
            f"{self._chunk_s:g} s, {mode}")

    @staticmethod
    def _build_simulator(inputs: RunSpec, chunk_s: float) -> Simulator:
        try:
            sim = Simulator(inputs.consist, inputs.speed_kmh, inputs.params, inputs.lut,
                            inputs.track)
        except InputError as exc:
            name = "initial_speed_kmh" if exc.source == "speed_kmh" else "consist"
            raise StartupError(name, str(exc)) from None
        # load the compiled kernel now rather than late for the first deadline
        try:
            sim.advance(chunk_s)
        except SimulationError:
            pass  # the run meets it again and reports it
        sim.reset()
        return sim

    def _init_plant_state(self) -> None:
        self.stats = PacingStats()
        #: Set when the node should shut down (max_sim_time_s reached, or the plant thread died).
        self.finished = threading.Event()
        #: Exit status for ``main``: 1 once the plant thread died of an unexpected error.
        self.exit_status = 0
        self._taps: list[Tap] = []
        self._jobs: queue.SimpleQueue[_Job] = queue.SimpleQueue()
        self._wake = threading.Event()
        self._quit = threading.Event()
        self._thread = threading.Thread(target=self._plant_loop, name="plant", daemon=True)
        self._emergency = False
        self._brake_demand = 0.0
        self._traction = 0.0
        self._recorder: BagWriter | None = None
        self._recording_error: str | None = None
        self._record_base = ""
        self._record_runs = 0
        self._rejected: dict[str, int] = {}
        self._next_reject_log: dict[str, float] = {}
        #: Input messages handled (received or self-issued), accepted or rejected; each one is
        #: recorded, so with recording on the bag holds exactly this many input messages.
        self._handled = 0
        self._finish_reason = ""
        self._auto_brake_done = False
        self._lut_warned = False
        self._paused = False
        self._failure: str | None = None
        self._stamp_ns = 0
        self._origin_wall = time.monotonic()
        self._next_index = 1
        self._next_diag_wall = 0.0
        self._diag_wall, self._diag_sim_s, self._diag_overruns = time.monotonic(), 0.0, 0

    def _create_interfaces(self, publish_clock: bool) -> None:
        self._outputs = {topic: self.create_publisher(Float64MultiArray, topic, STATE_QOS)
                         for topic, _, _ in ARRAY_TOPICS}
        if publish_clock:
            self._outputs[CLOCK_TOPIC] = self.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
        self._outputs[DIAGNOSTICS_TOPIC] = self.create_publisher(
            DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        # input topics: a handler and a subscription each
        self._input_handlers = {BRAKE_COMMAND_TOPIC: self._apply_brake_command,
                                BRAKE_DEMAND_TOPIC: self._apply_brake_demand,
                                TRACTION_TOPIC: self._apply_traction}
        types = {BRAKE_COMMAND_TOPIC: Bool, BRAKE_DEMAND_TOPIC: Float64, TRACTION_TOPIC: Float64}
        self._input_subscriptions = {
            topic: self.create_subscription(types[topic], topic, self._receiver(topic),
                                            COMMAND_QOS)
            for topic in self._input_handlers}
        self.create_service(Trigger, "~/reset", self._srv_reset)
        self.create_service(SetBool, "~/pause", self._srv_pause)
        self.create_service(Trigger, "~/step", self._srv_step)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

    def _declare_parameters(self) -> dict[str, Any]:
        values = {}
        for spec in PARAMETERS:
            try:
                values[spec.name] = self.declare_parameter(
                    spec.name, spec.default, spec.descriptor()).value
            except InvalidParameterTypeException:
                raise StartupError(spec.name, f"wrong type, expected "
                                   f"{_TYPE_WORDS[type(spec.default)]}") from None
            except ParameterException as exc:
                reason = str(exc).split("Reason: ", 1)[-1].removesuffix(f": {spec.name}")
                raise StartupError(spec.name, reason) from None
        return values

    def _receiver(self, topic: str) -> Callable[[Any], None]:
        def receive(msg):
            self._submit(lambda: self._on_input(topic, msg))
            self._yield_to_plant()
        return receive

    def _yield_to_plant(self) -> None:
        """On the executor thread: wait while a paced chunk is due (see YIELD_LEAD_S).

        Reads the plant's schedule without a lock: a torn read costs at most one needless
        or missed pause, never a wrong chunk. The commands themselves are never dropped here;
        under a flood DDS drops what the subscription queue (KEEP_LAST 1000) cannot hold.
        """
        if self._rtf <= 0.0 or not self._free_running():
            return
        end = time.monotonic() + YIELD_MAX_S
        while True:
            now = time.monotonic()
            if now < self._due() - YIELD_LEAD_S or now >= end:
                return
            time.sleep(YIELD_POLL_S)

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
        """Start the plant thread (publishes the initial state, then runs)."""
        self._thread.start()

    def close(self) -> None:
        """Stop the plant thread and destroy the node."""
        self._quit.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(timeout=10.0)
        self._close_recording()
        self.destroy_node()

    @property
    def sim_time_s(self) -> float:
        """Simulated time of the last published state [s]."""
        return self._stamp_ns / 1e9

    @property
    def failure(self) -> str | None:
        """Why the simulator stopped advancing (None while it works; ``~/reset`` clears it)."""
        return self._failure

    # ------------------------------------------------------------------ the one way out and in

    def _emit(self, topic: str, msg: Any) -> None:
        """Publish ``msg`` on ``topic`` (a key of ``self._outputs``), record it, show it to taps."""
        publisher = self._outputs[topic]
        if self._recorder is not None:
            # serialise once: the recording holds exactly the bytes sent
            data = serialize_message(msg)
            publisher.publish(data)
            self._record(publisher.topic_name, data)
        else:
            publisher.publish(msg)
        for tap in self._taps:
            tap(publisher.topic_name, msg, self._stamp_ns, False)

    def _on_input(self, topic: str, msg: Any) -> None:
        """Handle a received (or self-issued) input message on the plant thread."""
        name = self._input_subscriptions[topic].topic_name
        self._handled += 1
        if self._recorder is not None:
            self._record(name, serialize_message(msg))
        for tap in self._taps:
            tap(name, msg, self._stamp_ns, True)
        self._input_handlers[topic](msg)

    def _apply_brake_command(self, msg: Bool) -> None:
        # held until changed; the simulator ignores a repeated true
        self._emergency = bool(msg.data)

    def _checked_value(self, topic: str, value: float) -> float | None:
        lo, hi = NUMERIC_INPUTS[topic]
        if math.isfinite(value) and lo <= value <= hi:
            return float(value)
        # rejected: counted, logged at most every REJECT_LOG_PERIOD_S, the old value kept
        self._rejected[topic] = self._rejected.get(topic, 0) + 1
        now = time.monotonic()
        if now >= self._next_reject_log.get(topic, 0.0):
            self._next_reject_log[topic] = now + REJECT_LOG_PERIOD_S
            self.get_logger().warn(
                f"{self._input_subscriptions[topic].topic_name}: rejected {value!r}, expected a "
                f"finite number from {lo:g} to {hi:g}; keeping the previous value "
                f"({self._rejected[topic]} rejected so far)")
        return None

    def _apply_brake_demand(self, msg: Float64) -> None:
        value = self._checked_value(BRAKE_DEMAND_TOPIC, msg.data)
        if value is not None:
            self._brake_demand = value

    def _apply_traction(self, msg: Float64) -> None:
        value = self._checked_value(TRACTION_TOPIC, msg.data)
        if value is not None:
            self._traction = value

    # ------------------------------------------------------------------ recording

    def _open_recording(self, base: str) -> None:
        self._record_runs += 1
        folder = base if self._record_runs == 1 else f"{base}_{self._record_runs}"
        from ..recording.metadata import run_metadata

        meta = run_metadata(self._sim, scenario=self.inputs.origin,
                            parameters=dict(self._param_values),
                            brake_params=str(self.inputs.params.source),
                            coupler_lut=str(self.inputs.lut.source),
                            track=str(self.inputs.track.source))
        rec = None
        try:
            rec = BagWriter(folder, metadata=meta)
            for publisher in self._outputs.values():
                rec.add_topic(publisher.topic_name, type_name(publisher.msg_type),
                              qos_profiles_yaml(publisher.qos_profile))
            for sub in self._input_subscriptions.values():
                rec.add_topic(sub.topic_name, type_name(sub.msg_type),
                              qos_profiles_yaml(sub.qos_profile))
        except BaseException as exc:
            # a half-opened bag (disk full, SIGINT at start-up) is closed: no writer thread
            # or open file is left behind, and the folder holds no unfinished file if it can
            # be helped
            if rec is not None:
                try:
                    rec.close()
                except OSError:
                    pass
            if isinstance(exc, (OSError, ValueError)):
                raise StartupError("record_dir", f"cannot record to {folder}: {exc}") from None
            raise
        self._recorder = rec
        self._recording_error = None
        self.get_logger().info(f"recording to {rec.folder}")

    def _record(self, topic: str, data: bytes) -> None:
        try:
            self._recorder.write(topic, data, self._stamp_ns)
        except OSError as exc:
            self._recording_failed(exc)

    def _recording_failed(self, exc: BaseException) -> None:
        # e.g. a full disk: stop recording, keep the plant running; complete chunks already on
        # disk stay readable (ltd-brake recover rewrites the file)
        rec, self._recorder = self._recorder, None
        self._recording_error = f"{type(exc).__name__}: {exc}"
        self.get_logger().error(
            f"recording to {rec.folder} stopped: {self._recording_error}; the plant keeps "
            f"running; {rec.messages_on_disk} messages are on disk (ltd-brake recover "
            f"{rec.folder} makes it a complete bag)")
        # release the writer thread and the file; after a write error close() writes nothing
        # more, so the complete chunks stay exactly as they are
        try:
            rec.close()
        except OSError:
            pass

    def _flush_recording(self) -> None:
        if self._recorder is not None:
            try:
                self._recorder.flush_if_due()
            except OSError as exc:
                self._recording_failed(exc)

    def _close_recording(self) -> None:
        rec, self._recorder = self._recorder, None
        if rec is None:
            return
        try:
            rec.close()
            self.get_logger().info(f"recording finished: {rec.message_count} messages in "
                                   f"{rec.folder}")
        except OSError as exc:
            self._recorder = rec
            self._recording_failed(exc)
            self._recorder = None

    # ------------------------------------------------------------------ plant thread

    def _submit(self, fn: Callable[[], Any]) -> _Job:
        job = _Job(fn)
        self._jobs.put(job)
        self._wake.set()
        return job

    def _call_in_plant(self, fn: Callable[[], tuple[bool, str]]) -> tuple[bool, str]:
        job = self._submit(fn)
        while not job.done.wait(0.5):
            if not self._thread.is_alive():
                return False, "the plant is not running (shutting down)"
        return job.result

    def _run_jobs(self) -> None:
        # only the jobs queued so far: a flood of commands must not starve the chunks
        for _ in range(self._jobs.qsize()):
            try:
                job = self._jobs.get_nowait()
            except queue.Empty:
                return
            try:
                job.result = job.fn()
            except Exception as exc:  # noqa: BLE001 - a bad job must not stop the plant
                if self.context.ok():  # else: shutting down, publishers are gone
                    self.get_logger().error(f"{type(exc).__name__}: {exc}")
                job.result = (False, f"{type(exc).__name__}: {exc}")
            finally:
                job.done.set()

    def _free_running(self) -> bool:
        return not (self._lockstep or self._paused or self._failure or self.finished.is_set())

    def _period_s(self) -> float:
        return self._chunk_s / self._rtf if self._rtf > 0.0 else 0.0

    def _due(self) -> float:
        """Wall deadline of the next chunk (monotonic clock) [s]."""
        return self._origin_wall + self._next_index * self._period_s()

    def _restart_schedule(self, now: float, first_due_now: bool = False) -> None:
        # the next chunk is due one period from now (or at once), later ones follow at the period
        self._origin_wall = now
        self._next_index = 0 if first_due_now else 1

    def _plant_loop(self) -> None:
        try:
            now = time.monotonic()
            self._publish_state(self._sim.snapshot())
            self._restart_schedule(now)
            self._diag_wall, self._next_diag_wall = now, now + DIAGNOSTICS_PERIOD_S
            while not self._quit.is_set():
                self._wake.clear()
                self._run_jobs()
                self._flush_recording()
                now = self._maybe_diagnostics()
                timeout = self._next_diag_wall - now
                if self._free_running():
                    due = self._due()
                    if due <= now:
                        self._paced_chunk(due)
                        continue
                    timeout = min(timeout, due - now)
                if self._recorder is not None:
                    # idle (paused, lock-step, slow pace): still flush within the interval
                    timeout = min(timeout, self._recorder.seconds_until_flush())
                self._wake.wait(max(timeout, 0.0))
        except Exception as exc:  # noqa: BLE001
            if self.context.ok() and not self._quit.is_set():
                self.get_logger().fatal(f"plant thread stopped: {type(exc).__name__}: {exc}")
                self.exit_status = 1
                self.finished.set()
            # else: the context was shut down under us (SIGINT/SIGTERM); main cleans up

    def _paced_chunk(self, due: float) -> None:
        self._run_chunk()
        if self._rtf <= 0.0:
            time.sleep(0)  # let the executor thread take the GIL between chunks
            return
        done = time.monotonic()
        self.stats.lateness_s.append(done - due)
        self._next_index += 1
        if done > self._due():
            # behind schedule: count it and restart the schedule instead of catching up
            self.stats.overruns += 1
            self._restart_schedule(done, first_due_now=True)

    def _run_chunk(self) -> bool:
        """Advance one chunk and publish the state; False if the simulator failed."""
        sim = self._sim
        if 0.0 <= self._auto_brake_at_s <= sim.time_s + TIME_EPS_S and not self._auto_brake_done:
            self._auto_brake_done = True
            self._on_input(BRAKE_COMMAND_TOPIC, Bool(data=True))
        try:
            snap = sim.advance(self._chunk_s, Commands(emergency=self._emergency,
                                                       brake_demand=self._brake_demand,
                                                       traction=self._traction))
        except SimulationError as exc:
            self._fail(str(exc))
            return False
        except Exception as exc:  # noqa: BLE001 - any simulator fault stops the plant, not the node
            self._fail(f"{type(exc).__name__}: {exc}")
            return False
        self.stats.chunks += 1
        self._publish_state(snap)
        log = self.get_logger()
        for event in snap.events:
            if event.kind != "coupler_out_of_lut":
                log.info(event.describe())
            elif self._lut_warned:
                log.debug(event.describe())
            else:
                # long trains push dozens of couplers past the table: warn once per run
                self._lut_warned = True
                log.warn(f"{event.describe()}; further couplers are logged at debug level and "
                         "counted in diagnostics")
        if 0.0 <= self._max_sim_time_s <= snap.time_s + TIME_EPS_S:
            log.info(f"max_sim_time_s = {self._max_sim_time_s:g} s reached; shutting down")
            self._finish_reason = "max_sim_time_s reached"
            self.finished.set()
        if sim.stop_time_s is not None and \
                0.0 <= self._shutdown_after_stop_s <= snap.time_s - sim.stop_time_s + TIME_EPS_S:
            log.info(f"{self._shutdown_after_stop_s:g} s after the stop; shutting down")
            self._finish_reason = "shutdown_after_stop_s reached"
            self.finished.set()
        return True

    def _publish_state(self, snap: Snapshot) -> None:
        self._stamp_ns = round(snap.time_s * 1e9)
        for topic, attribute, label in ARRAY_TOPICS:
            self._emit(topic, array_msg(label, getattr(snap, attribute)))
        if CLOCK_TOPIC in self._outputs:
            self._emit(CLOCK_TOPIC, Clock(clock=time_msg(self._stamp_ns)))

    def _fail(self, reason: str) -> None:
        self._failure = reason
        self.get_logger().error(f"simulation failed at t = {self._sim.time_s:.3f} s: {reason}; "
                                "the plant stopped advancing, call ~/reset to recover")
        self._publish_diagnostics(time.monotonic())
        # the run is over: finish its bag (ending with the ERROR above) so that it is complete
        # and readable now, not only once the node exits; ~/reset starts the next one
        self._close_recording()

    # ------------------------------------------------------------------ diagnostics

    def _maybe_diagnostics(self) -> float:
        now = time.monotonic()
        if now >= self._next_diag_wall:
            self._publish_diagnostics(now)
        return now

    def _publish_diagnostics(self, now: float) -> None:
        sim, stats = self._sim, self.stats
        wall = now - self._diag_wall
        achieved = (sim.time_s - self._diag_sim_s) / wall if wall > 0.0 else 0.0
        overruns = stats.overruns - self._diag_overruns
        self._diag_wall, self._diag_sim_s, self._diag_overruns = now, sim.time_s, stats.overruns
        self._next_diag_wall = now + DIAGNOSTICS_PERIOD_S

        if self._failure:
            level, state, message = DiagnosticStatus.ERROR, "failed", self._failure
        elif self.finished.is_set():
            level, state, message = DiagnosticStatus.OK, "finished", self._finish_reason
        else:
            state = "lockstep" if self._lockstep else "paused" if self._paused else "running"
            level, message = DiagnosticStatus.OK, state
            if overruns:
                level, message = DiagnosticStatus.WARN, \
                    f"{overruns} chunk overrun(s) in the last {wall:.1f} s"
        draft, buff = sim.peak_draft_N, sim.peak_buff_N
        values = {
            "state": state,
            "sim_time_s": f"{sim.time_s:.3f}",
            "real_time_factor": f"{self._rtf:g}",
            "achieved_real_time_factor": f"{achieved:.3f}",
            "chunks": str(stats.chunks),
            "chunk_overruns": str(stats.overruns),
            "emergency_command": "true" if self._emergency else "false",
            "brake_command_time_s": "none" if sim.command_time_s is None
            else f"{sim.command_time_s:.3f}",
            "head_speed_kmh": f"{float(sim.snapshot().speed_m_s[0]) * 3.6:.3f}",
            "peak_draft_kN": f"{float(draft.max(initial=0.0)) / 1e3:.3f}",
            "peak_draft_coupler": str(int(np.argmax(draft)) + 1 if draft.size else 0),
            "peak_buff_kN": f"{float(buff.min(initial=0.0)) / 1e3:.3f}",
            "peak_buff_coupler": str(int(np.argmin(buff)) + 1 if buff.size else 0),
            "couplers_beyond_lut": str(int(np.count_nonzero(sim.lut_excursion_m))),
            "brake_demand": f"{self._brake_demand:g}",
            "traction_command": f"{self._traction:g}",
            "rejected_inputs": str(sum(self._rejected.values())),
            "inputs_handled": str(self._handled),
            "recording": self._recording_state(),
        }
        if self._recording_error:
            values["recording_error"] = self._recording_error
            if level == DiagnosticStatus.OK:
                level, message = DiagnosticStatus.WARN, "recording stopped"
        if sim.stopping_distance_m is not None:
            values["stopping_distance_m"] = f"{sim.stopping_distance_m:.3f}"
            values["stop_time_s"] = f"{sim.stop_time_s - (sim.command_time_s or 0.0):.3f}"
        if self._failure:
            values["error"] = self._failure
        status = DiagnosticStatus(
            level=level, name=f"{self.get_fully_qualified_name()}: train plant", message=message,
            hardware_id=self.inputs.consist.name,
            values=[KeyValue(key=k, value=v) for k, v in values.items()])
        diag = DiagnosticArray(status=[status])
        diag.header.stamp = time_msg(self._stamp_ns)
        self._emit(DIAGNOSTICS_TOPIC, diag)

    def _recording_state(self) -> str:
        if self._recorder is not None:
            return str(self._recorder.folder)
        if self._recording_error:
            return "failed"
        # a bag finished after a simulator failure: the next one starts with ~/reset
        return "finished" if self._record_base else "off"

    # ------------------------------------------------------------------ services

    def _srv_reset(self, request: Trigger.Request, response: Trigger.Response):
        response.success, response.message = self._call_in_plant(self._reset)
        return response

    def _srv_pause(self, request: SetBool.Request, response: SetBool.Response):
        response.success, response.message = self._call_in_plant(
            lambda: self._pause(bool(request.data)))
        return response

    def _srv_step(self, request: Trigger.Request, response: Trigger.Response):
        chunks = self._steps_per_call
        response.success, response.message = self._call_in_plant(lambda: self._step(chunks))
        return response

    def _reset(self) -> tuple[bool, str]:
        snap = self._sim.reset()
        if self._record_base:
            # one run per bag (the report assumes it): finish the current one, unless a
            # simulator failure or a write error already ended it, and start <record_dir>_2, ...
            self._close_recording()
            try:
                self._open_recording(self._record_base)
            except StartupError as exc:  # e.g. the disk is still full: run without recording
                self._recording_error = exc.reason
                self.get_logger().error(f"{exc}; the plant runs on without recording")
        self._emergency = False
        self._brake_demand = 0.0
        self._traction = 0.0
        self._auto_brake_done = False
        self._lut_warned = False
        self._failure = None
        self._publish_state(snap)
        now = time.monotonic()
        self._restart_schedule(now)
        self._diag_wall, self._diag_sim_s = now, 0.0
        self.get_logger().info("reset: initial state, brake released, t = 0 s")
        return True, "reset to the initial state (brake released, t = 0 s)"

    def _pause(self, pause: bool) -> tuple[bool, str]:
        if self._paused and not pause:
            self._restart_schedule(time.monotonic())
        self._paused = pause
        text = f"{'paused' if pause else 'running'} at t = {self._sim.time_s:.3f} s"
        if self._lockstep:
            text += " (lock-step mode: the plant advances only on ~/step)"
        return True, text

    def _step(self, chunks: int) -> tuple[bool, str]:
        if not (self._lockstep or self._paused):
            return False, "the plant is free-running: pause it (~/pause) or start it with " \
                          "lockstep:=true to step it"
        if self._failure:
            return False, f"simulation failed: {self._failure}; call ~/reset"
        if self.finished.is_set():
            return False, "max_sim_time_s reached; the node is shutting down"
        done = 0
        while done < chunks and not self.finished.is_set():
            if not self._run_chunk():
                return False, f"simulation failed: {self._failure}; call ~/reset"
            done += 1
            self._maybe_diagnostics()
        # the inputs the chunks ran with, so a controller can check its last command arrived
        return True, (f"advanced {done} chunk(s) to t = {self._sim.time_s:.3f} s with "
                      f"emergency={str(self._emergency).lower()} "
                      f"brake_demand={self._brake_demand:g} traction={self._traction:g} "
                      f"(inputs handled: {self._handled})")

    # ------------------------------------------------------------------ parameters

    def _validate_parameters(self, params) -> SetParametersResult:
        for p in params:
            if p.name == "real_time_factor":
                v = p.value
                if not (isinstance(v, float) and math.isfinite(v)
                        and 0.0 <= v <= MAX_REAL_TIME_FACTOR):
                    return SetParametersResult(
                        successful=False,
                        reason=f"real_time_factor must be a number from 0 (as fast as possible) "
                               f"to {MAX_REAL_TIME_FACTOR:g}, got {v!r}; keeping {self._rtf:g}")
            elif p.name == "steps_per_call" and not (isinstance(p.value, int) and p.value >= 1):
                return SetParametersResult(
                    successful=False,
                    reason=f"steps_per_call must be a whole number >= 1, got {p.value!r}")
        return SetParametersResult(successful=True)

    def _apply_parameters(self, params) -> None:
        for p in params:
            if p.name == "real_time_factor":
                self._submit(lambda value=p.value: self._set_real_time_factor(value))
            elif p.name == "steps_per_call":
                self._steps_per_call = p.value

    def _set_real_time_factor(self, value: float) -> None:
        self._rtf = float(value)
        self._restart_schedule(time.monotonic())
        self.get_logger().info(f"real_time_factor set to {value:g}")


def main(args: list[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM or ``max_sim_time_s``.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments (default: ``sys.argv``), e.g. ``--ros-args -p chunk_s:=0.05``.

    Returns
    -------
    int
        Exit status: 0 after a clean shutdown, 1 when a parameter value is unusable or the
        plant thread died of an unexpected error.
    """
    rclpy.init(args=args)
    node = None
    try:
        node = SimNode()
        node.start()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while rclpy.ok() and not node.finished.is_set():
            executor.spin_once(timeout_sec=0.2)
        return node.exit_status
    except StartupError as exc:
        rclpy.logging.get_logger(NODE_NAME).fatal(f"cannot start: {exc}")
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        _finish_despite_signals()
        if node is not None:
            node.close()
            rclpy.logging.get_logger(NODE_NAME).info(
                f"stopped at t = {node.sim_time_s:.3f} s after {node.stats.chunks} chunks")
        rclpy.try_shutdown()
        _finish_despite_signals()  # shutting rclpy down may have put its handlers back


def _finish_despite_signals() -> None:
    """Let a further SIGINT or SIGTERM only log, so that it cannot cut the recording short.

    Without this, a second Ctrl-C (or a SIGINT after a SIGTERM) that arrives while the bag is
    being closed raises KeyboardInterrupt inside the closing and leaves the file without its
    summary. SIGKILL still ends the process at once.
    """
    def note(signum, _frame):
        text = (f"{signal.Signals(signum).name} ignored: finishing the recording and shutting "
                "down (SIGKILL aborts)")
        try:
            rclpy.logging.get_logger(NODE_NAME).warn(text)
        except Exception:  # noqa: BLE001 - logging already shut down: never fail here
            print(f"[WARN] [{NODE_NAME}]: {text}", file=sys.stderr)
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            signal.signal(sig, note)
        except ValueError:  # not the main thread (node embedded elsewhere): nothing to guard
            pass


if __name__ == "__main__":
    sys.exit(main())
