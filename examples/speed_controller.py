#!/usr/bin/env python3
"""Closed-loop example: a PI speed controller that drives ``sim_node`` in lock-step.

The controller brings the train to ``target_speed_kmh`` and holds it there. The plant
(``sim_node`` started with ``lockstep:=true``) advances only when asked, so the run is
deterministic and as fast as the loop. Every control period the controller

1. calls ``<plant>/step`` (``std_srvs/srv/Trigger``): the plant advances one chunk
   (``chunk_s`` of simulated time) and publishes the new state;
2. reads the head vehicle's speed from ``vehicles/state`` (``sensor_msgs/msg/JointState``,
   velocity [m/s] of ``vehicle_0``, the head), the state whose ``header.stamp`` is the
   simulated time the step reached;
3. publishes ``traction_command`` (``std_msgs/msg/Float64``: -1 full dynamic brake to 1 full
   traction) and ``brake_demand`` (``std_msgs/msg/Float64``: 0 released to 1 full service
   brake), which the plant applies during the next chunk: before a step it takes every
   command that reached it, and the commands travel on reliable readers, so a command
   published before the ``~/step`` call is in that step.

The law (:class:`SpeedLaw`): a PI controller on the speed error commands traction or the
dynamic brake; the service brake helps only while the dynamic brake is saturated and the train
is still far above the target, because the air brake releases slowly.

Topic and service names are relative: start both nodes in the same namespace, e.g.::

    sim_node --ros-args -r __ns:=/train1 -p lockstep:=true -p chunk_s:=0.1 \\
        -p initial_speed_kmh:=80.0
    python examples/speed_controller.py --ros-args -r __ns:=/train1 -p target_speed_kmh:=40.0

``examples/run_speed_control.sh`` starts both and records the run.
"""
from __future__ import annotations

import math
import signal
import sys
import time
from dataclasses import dataclass

import rclpy
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rcl_interfaces.srv import GetParameters
from rclpy.duration import Duration
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

KMH_PER_M_S = 3.6

#: Wall time before a question to the plant is asked again [s] (see SpeedController._query).
QUERY_RETRY_S = 1.0
#: Same QoS as the plant's inputs and state topics: reliable, so nothing is lost in lock-step.
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


class ParameterError(ValueError):
    """A parameter value the controller cannot use (one line names it and why)."""


def _clip(value: float, lo: float, hi: float) -> float:
    return min(max(value, lo), hi)


@dataclass
class SpeedLaw:
    """PI speed law with anti-windup, a traction/brake deadband and service-brake assistance.

    The PI part gives an effort ``u`` in [-1, 1] (traction positive, dynamic brake negative).
    The service brake helps only while the dynamic brake is saturated (``u = -1``) and the
    train is more than ``brake_margin_m_s`` too fast.

    Parameters
    ----------
    target_m_s : float
        Target speed [m/s].
    kp : float
        Proportional gain: effort per m/s of speed error [1/(m/s)].
    ki : float
        Integral gain: effort per m of integrated speed error [1/m].
    deadband : float
        Efforts smaller than this coast (traction and dynamic brake off) [-].
    brake_margin_m_s : float
        Speed excess above the target below which the service brake is released [m/s].
    brake_gain : float
        Service-brake demand per m/s of excess beyond the margin [1/(m/s)].
    max_brake_demand : float
        Largest service-brake demand [-].
    """

    target_m_s: float
    kp: float
    ki: float
    deadband: float
    brake_margin_m_s: float
    brake_gain: float
    max_brake_demand: float
    #: Integral term [-], kept within the effort range.
    integral: float = 0.0

    def update(self, speed_m_s: float, dt_s: float) -> tuple[float, float]:
        """Commands for the next control period.

        Parameters
        ----------
        speed_m_s : float
            Measured speed of the head vehicle [m/s].
        dt_s : float
            Control period [s].

        Returns
        -------
        traction : float
            Traction (> 0) or dynamic-brake (< 0) command, -1 to 1.
        brake_demand : float
            Service-brake demand, 0 to ``max_brake_demand``.
        """
        error = self.target_m_s - speed_m_s
        u = self.kp * error + self.integral
        # anti-windup (conditional integration): no integrating while the effort is saturated
        # and the error pushes it further, so the integral is ready when the error turns
        if not ((u >= 1.0 and error > 0.0) or (u <= -1.0 and error < 0.0)):
            self.integral = _clip(self.integral + self.ki * error * dt_s, -1.0, 1.0)
        u = _clip(self.kp * error + self.integral, -1.0, 1.0)

        # deadband: small efforts coast, so the command cannot flip between traction and
        # dynamic brake on every period near zero; shifted so the effort stays continuous
        if abs(u) <= self.deadband:
            traction = 0.0
        else:
            traction = (u - math.copysign(self.deadband, u)) / (1.0 - self.deadband)

        # the air brake releases slowly (tens of seconds): apply it only while the dynamic
        # brake is not enough, and let it go gradually well before the target so that its
        # release does not carry the train below the target
        brake = 0.0
        if u <= -1.0:
            excess_m_s = -error - self.brake_margin_m_s
            brake = _clip(self.brake_gain * excess_m_s, 0.0, self.max_brake_demand)
        return traction, brake


#: The node's parameters: name -> (default, description, accepted range or None).
PARAMETERS = {
    "target_speed_kmh": (40.0, "Speed to reach and hold [km/h]", (0.0, 400.0)),
    "kp": (2.0, "Proportional gain: effort per m/s of speed error [1/(m/s)]", (0.0, 100.0)),
    "ki": (0.05, "Integral gain: effort per m of integrated speed error [1/m]", (0.0, 100.0)),
    "deadband": (0.05, "Efforts below this coast, so that the command does not flip between "
                       "traction and dynamic brake [-]", (0.0, 0.5)),
    "brake_margin_kmh": (16.0, "The service brake is released once the train is less than this "
                               "above the target [km/h]", (0.0, 400.0)),
    "brake_gain": (0.1, "Service-brake demand per m/s above target + margin [1/(m/s)]",
                   (0.0, 100.0)),
    "max_brake_demand": (0.3, "Largest service-brake demand [-]", (0.0, 1.0)),
    "duration_s": (180.0, "Simulated time to run, then exit; 0 = until interrupted [s]",
                   (0.0, 1e7)),
    "real_time_factor": (0.0, "Simulated seconds per wall second: a step is asked for no "
                              "earlier than its time on this pace; 0 = as fast as the plant "
                              "answers", (0.0, 1e6)),
    "timeout_s": (10.0, "Wall time allowed for each exchange with the plant [s]", (0.1, 3600.0)),
    "connect_timeout_s": (60.0, "Wall time allowed to find the plant at start-up (discovery "
                                "can take seconds on a busy machine) [s]", (0.1, 3600.0)),
    "plant": ("sim_node", "Name of the plant node, relative to this node's namespace", None),
}


def speed_law(p: dict) -> SpeedLaw:
    """The control law for the node's parameter values.

    Parameters
    ----------
    p : dict
        Parameter values by name (see :data:`PARAMETERS`).

    Returns
    -------
    SpeedLaw
    """
    return SpeedLaw(target_m_s=p["target_speed_kmh"] / KMH_PER_M_S, kp=p["kp"], ki=p["ki"],
                    deadband=p["deadband"], brake_margin_m_s=p["brake_margin_kmh"] / KMH_PER_M_S,
                    brake_gain=p["brake_gain"], max_brake_demand=p["max_brake_demand"])


class SpeedController(Node):
    """Drives a lock-step ``sim_node`` with :class:`SpeedLaw` (see the module docstring).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ...).
    """

    def __init__(self, **kwargs):
        super().__init__("speed_controller", **kwargs)
        p = self._declare_parameters()
        self.law = speed_law(p)
        self.duration_s = p["duration_s"]
        self.timeout_s = p["timeout_s"]
        self.real_time_factor = p["real_time_factor"]
        self.connect_timeout_s = p["connect_timeout_s"]
        self._plant = p["plant"]
        self._traction_pub = self.create_publisher(Float64, "traction_command", RELIABLE)
        self._brake_pub = self.create_publisher(Float64, "brake_demand", RELIABLE)
        self._state_sub = self.create_subscription(JointState, "vehicles/state",
                                                   self._on_state, RELIABLE)
        self._step_client = self.create_client(Trigger, f"{self._plant}/step")
        self._param_client = self.create_client(GetParameters, f"{self._plant}/get_parameters")
        self._speeds: dict[int, float] = {}  # head speed [m/s] by simulated time [ns]
        self._head_speed_m_s = math.nan
        self._spinner = SingleThreadedExecutor(context=self.context)
        self._spinner.add_node(self)

    def _declare_parameters(self) -> dict:
        values = {}
        for name, (default, text, limits) in PARAMETERS.items():
            descriptor = ParameterDescriptor(description=text)
            if limits is not None:
                descriptor.floating_point_range = [
                    FloatingPointRange(from_value=limits[0], to_value=limits[1], step=0.0)]
            try:
                values[name] = self.declare_parameter(name, default, descriptor).value
            except InvalidParameterValueException:
                given = self._given(name)
                raise ParameterError(f"parameter {name}: {given!r} is out of range, expected "
                                     f"{limits[0]:g} to {limits[1]:g}") from None
            except InvalidParameterTypeException:
                given = self._given(name)
                kind = "text" if isinstance(default, str) else \
                    f"a number with a decimal point (e.g. {default!r})"
                raise ParameterError(f"parameter {name}: {given!r} is not {kind}") from None
        return values

    def _given(self, name: str):
        """The value given for ``name`` on the command line or in a parameter file."""
        override = self._parameter_overrides.get(name)
        return None if override is None else override.value

    def _on_state(self, msg: JointState) -> None:
        # a state is known by its simulated time, however late it arrives
        stamp = msg.header.stamp
        self._speeds[stamp.sec * 1_000_000_000 + stamp.nanosec] = msg.velocity[0]

    # ------------------------------------------------------------------ talking to the plant

    def _spin_until(self, done, what: str, timeout_s: float | None = None) -> None:
        """Process callbacks until ``done()``; raise TimeoutError naming ``what``."""
        timeout_s = timeout_s or self.timeout_s
        deadline = time.monotonic() + timeout_s
        while not done():
            if time.monotonic() > deadline:
                raise TimeoutError(f"no {what} within {timeout_s:g} s")
            self._spinner.spin_once(timeout_sec=0.05)

    def _query(self, client, request, what: str):
        """Ask a question without side effects (get_parameters) until it is answered.

        An answer the plant sends before it has matched this node's reader is lost (right
        after start-up the service can look ready a moment before that); asking again is
        harmless. A step is never repeated: its state is its acknowledgement (:meth:`_step`).
        """
        deadline = time.monotonic() + self.timeout_s
        while True:
            future = client.call_async(request)
            wait_s = min(QUERY_RETRY_S, max(deadline - time.monotonic(), 0.05))
            try:
                self._spin_until(future.done, f"answer from {what}", wait_s)
                return future.result()
            except TimeoutError:
                client.remove_pending_request(future)
                if time.monotonic() >= deadline:
                    raise TimeoutError(f"no answer from {what} within "
                                       f"{self.timeout_s:g} s") from None

    def _connect(self) -> float:
        """Wait for the plant, check it is in lock-step and return its chunk length [s]."""
        self._spin_until(lambda: self._step_client.service_is_ready()
                         and self._param_client.service_is_ready(), f"plant {self._plant}",
                         self.connect_timeout_s)
        names = ["lockstep", "chunk_s", "steps_per_call"]
        reply = self._query(self._param_client, GetParameters.Request(names=names),
                           f"{self._plant}/get_parameters")
        lockstep, chunk_s, steps = (parameter_value_to_python(v) for v in reply.values)
        if lockstep is not True or steps != 1:
            raise RuntimeError(f"{self._plant} must run with lockstep:=true and "
                               f"steps_per_call:=1 (got {lockstep}, {steps})")
        self._spin_until(lambda: self._traction_pub.get_subscription_count() > 0
                         and self._brake_pub.get_subscription_count() > 0
                         and self._state_sub.get_publisher_count() > 0,
                         "match with the plant's topics", self.connect_timeout_s)
        return float(chunk_s)

    def _step(self, after_ns: int) -> None:
        """Advance the plant one chunk and take the state it published then, the first one
        stamped after ``after_ns`` [ns] (half a chunk before the time the step reaches).

        The plant publishes that state before it answers, on another reader; whichever comes
        first, the step is done once both are in. A refusal comes as the answer.
        """
        future = self._step_client.call_async(Trigger.Request())

        def newest() -> int:
            return max(self._speeds, default=-1)

        self._spin_until(lambda: future.done() and (newest() > after_ns
                                                    or not future.result().success),
                         f"the state after {self._plant}/step")
        if not future.result().success:
            raise RuntimeError(f"{self._plant}/step refused: {future.result().message}")
        self._head_speed_m_s = self._speeds[newest()]
        self._speeds.clear()

    def _send(self, traction: float, brake_demand: float) -> None:
        """Publish the commands; the plant applies them in the next step."""
        self._traction_pub.publish(Float64(data=traction))
        self._brake_pub.publish(Float64(data=brake_demand))

    # ------------------------------------------------------------------ the loop

    def run(self) -> None:
        """Control the plant until ``duration_s`` of simulated time has passed."""
        dt_s = self._connect()
        log = self.get_logger()
        log.info(f"driving {self._plant} in lock-step every {dt_s:g} s to "
                 f"{self.law.target_m_s * KMH_PER_M_S:g} km/h")
        steps, report_every = 0, max(1, round(10.0 / dt_s))
        rtf, start = self.real_time_factor, time.monotonic()
        # the first step runs with the plant's initial inputs (traction and brake off)
        while self.duration_s <= 0.0 or steps * dt_s < self.duration_s - 1e-9:
            if rtf > 0.0:  # paced: step k is due k dt / rtf after the start
                wait = start + steps * dt_s / rtf - time.monotonic()
                if wait > 0.0:
                    time.sleep(wait)
            steps += 1
            self._step(round((steps - 0.5) * dt_s * 1e9))
            traction, brake = self.law.update(self._head_speed_m_s, dt_s)
            self._send(traction, brake)
            if steps % report_every == 0:
                log.info(f"t = {steps * dt_s:6.1f} s: {self._head_speed_m_s * KMH_PER_M_S:5.1f}"
                         f" km/h, traction {traction:+.2f}, brake demand {brake:.2f}")
        # the last commands are for a step that is not asked for; they reach the plant (and
        # its recording) before this node goes away
        for pub in (self._traction_pub, self._brake_pub):
            pub.wait_for_all_acked(Duration(seconds=self.timeout_s))
        log.info(f"done after {steps} steps ({steps * dt_s:g} s simulated)")

    def close(self) -> None:
        """Release the executor and destroy the node."""
        self._spinner.shutdown()
        self.destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the controller; 0 after ``duration_s`` or Ctrl-C, 1 when the plant fails us.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments (default: ``sys.argv``).

    Returns
    -------
    int
        Exit status.
    """
    rclpy.init(args=args)
    node = None
    try:
        node = SpeedController()
        node.run()
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except (RuntimeError, TimeoutError, ParameterError) as exc:
        rclpy.logging.get_logger("speed_controller").error(str(exc))
        return 1
    finally:
        # Ctrl-C under ros2 launch arrives twice (the terminal's and the launch's): the second
        # must not cut the clean-up short
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if node is not None:
            node.close()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
