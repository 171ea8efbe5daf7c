"""Replay a recording into ROS: every topic with its recorded type and QoS, paced by time.

Usage::

    ros2 run ltd_brake_ros replay_node runs/run_2025_01_01-12_00_00 --ros-args -p rate:=2.0
    replay_node run.mcap --ros-args -p loop:=true -p publish_clock:=true

Parameters: ``bag`` (folder or ``.mcap``; the first non-ROS argument also works), ``rate``
(recorded time x rate; 0 = as fast as possible), ``loop``, ``publish_clock`` (``/clock`` from
the recorded time, replacing a recorded ``/clock``), ``start_paused`` and
``wait_for_subscribers`` (start only once every publisher has that many subscribers).
Services: ``~/pause`` (std_srvs/SetBool: true pauses, false resumes) and ``~/restart``
(std_srvs/Trigger: from the beginning).

Payloads are published as the recorded serialized bytes (``Publisher.publish(bytes)``), so a
subscriber receives exactly what was recorded. Without ``loop`` the node exits once everything
has been published and acknowledged by reliable subscribers (at most 5 s).
"""
from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

from ..recording.bag import bag_info, message_class, read_bag
from ..recording.qos import qos_from_profile

__all__ = ["Player", "qos_from_profile", "main"]



class Player:
    """Publishes recorded messages paced to the wall clock; knows nothing of ROS.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file.
    publish : callable
        ``publish(topic, msg_type, log_time_ns, data)`` for every message, in recorded order.
    rate : float, optional
        Recorded time advances ``rate`` times faster than wall time; 0 = no waiting.
    loop : bool, optional
        Start again at the end.
    clock : callable, optional
        ``clock(log_time_ns)`` before the first message of every new recorded time.
    skip_topics : collection of str, optional
        Topics not replayed.
    start_paused : bool, optional
    monotonic : callable, optional
        Wall clock [s] (tests may pass their own).
    """

    def __init__(self, path, publish, *, rate: float = 1.0, loop: bool = False, clock=None,
                 skip_topics=(), start_paused: bool = False, monotonic=time.monotonic):
        if not rate >= 0.0:
            raise ValueError(f"rate must be >= 0, got {rate}")
        self.path = path
        self._publish = publish
        self._clock = clock
        self._skip = frozenset(skip_topics)
        self.loop = bool(loop)
        self._now = monotonic
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._rate = float(rate)
        self._base_wall = monotonic()
        self._base_log = 0
        self._paused_since = self._base_wall if start_paused else None
        self._restart = False
        self._stop = False
        #: Messages published since the start (all passes).
        self.published = 0
        #: Completed passes through the recording.
        self.passes = 0

    # ----------------------------------------------------------------- control (any thread)

    @property
    def paused(self) -> bool:
        return self._paused_since is not None

    @property
    def rate(self) -> float:
        return self._rate

    def pause(self, paused: bool) -> None:
        """Pause (True) or resume (False); recorded time stands still while paused."""
        with self._lock:
            now = self._now()
            if paused and self._paused_since is None:
                self._paused_since = now
            elif not paused and self._paused_since is not None:
                self._base_wall += now - self._paused_since
                self._paused_since = None
        self._wake.set()

    def set_rate(self, rate: float) -> None:
        """Change the rate from the current playback position on."""
        if not rate >= 0.0:
            raise ValueError(f"rate must be >= 0, got {rate}")
        with self._lock:
            now = self._paused_since if self._paused_since is not None else self._now()
            self._base_log = self._position(now)
            self._base_wall = now
            self._rate = float(rate)
        self._wake.set()

    def restart(self) -> None:
        """Go back to the first message (the pause state is kept)."""
        with self._lock:
            self._restart = True
        self._wake.set()

    def stop(self) -> None:
        """End :meth:`run` as soon as possible."""
        self._stop = True
        self._wake.set()

    # ----------------------------------------------------------------- playback

    def _position(self, now: float) -> float:
        # recorded time [ns] that the playback has reached at wall time ``now``
        return self._base_log + (now - self._base_wall) * 1e9 * self._rate

    def _wait_until(self, log_ns: int) -> bool:
        """Block until ``log_ns`` is due; False if stopped or restarted meanwhile."""
        while True:
            if self._stop or self._restart:
                return False
            with self._lock:
                paused = self._paused_since is not None
                rate = self._rate
                lag = log_ns - self._position(self._now())
            if paused:
                timeout = 0.2
            elif rate <= 0.0 or lag <= 0.0:
                return True
            else:
                timeout = min(lag / (1e9 * rate), 0.2)
            self._wake.wait(timeout)
            self._wake.clear()

    def run(self) -> int:
        """Play until the end (or forever with ``loop``) or :meth:`stop`.

        Returns
        -------
        int
            Messages published.
        """
        while not self._stop:
            with self._lock:
                self._restart = False
            first = True
            last_clock = None
            messages = read_bag(self.path)
            try:
                for topic, msg_type, log_ns, data in messages:
                    if first:
                        with self._lock:
                            now = self._now()
                            self._base_log, self._base_wall = log_ns, now
                            if self._paused_since is not None:
                                self._paused_since = now
                        first = False
                    if not self._wait_until(log_ns):
                        break
                    if topic in self._skip:
                        continue
                    if self._clock is not None and log_ns != last_clock:
                        self._clock(log_ns)
                        last_clock = log_ns
                    self._publish(topic, msg_type, log_ns, data)
                    self.published += 1
                else:
                    self.passes += 1
                    if not self.loop:
                        return self.published
            finally:
                messages.close()
        return self.published


def _make_node(cli_bag):
    import rclpy
    from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from std_srvs.srv import SetBool, Trigger

    class ReplayNode(Node):
        """Republishes a recording (see the module documentation)."""

        def __init__(self):
            super().__init__("replay_node")
            P = ParameterDescriptor
            self.declare_parameter("bag", cli_bag or "", P(
                description="recording to play: bag folder or .mcap file", read_only=True))
            self.declare_parameter("rate", 1.0, P(
                description="recorded time x rate = wall time; 0 plays as fast as possible"))
            self.declare_parameter("loop", False, P(description="start again at the end"))
            self.declare_parameter("publish_clock", False, P(
                description="publish /clock from the recorded time", read_only=True))
            self.declare_parameter("start_paused", False, P(
                description="wait for ~/pause false before playing", read_only=True))
            self.declare_parameter("wait_for_subscribers", 0, P(
                description="start once every topic has this many subscribers",
                read_only=True))
            path = self.get_parameter("bag").value
            if not path:
                raise ValueError("no recording given: pass a bag folder or .mcap file as the "
                                 "first argument or set the 'bag' parameter")
            self.bag = Path(path)
            info = bag_info(self.bag)
            if not info.complete:
                self.get_logger().warning(f"{self.bag} was not finished by its recorder: "
                                          "playing up to its last complete chunk")
            clock = self.get_parameter("publish_clock").value
            self._pubs = {}
            for name, topic in info.topics.items():
                if clock and name == "/clock":
                    continue
                qos = qos_from_profile(topic.qos_profiles[0] if topic.qos_profiles else None)
                self._pubs[name] = self.create_publisher(message_class(topic.msg_type), name,
                                                         qos)
            self._clock_pub = None
            if clock:
                # reliable, depth 1: matches rclpy's best-effort /clock subscription and
                # reliable ones alike
                self._clock_pub = self.create_publisher(
                    Clock, "/clock", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
                self._clock_msg = Clock()
            self.player = Player(self.bag, self._publish, rate=self.get_parameter("rate").value,
                                 loop=self.get_parameter("loop").value,
                                 clock=self._publish_clock if clock else None,
                                 skip_topics=("/clock",) if clock else (),
                                 start_paused=self.get_parameter("start_paused").value)
            self.add_on_set_parameters_callback(self._on_parameters)
            self.create_service(SetBool, "~/pause", self._on_pause)
            self.create_service(Trigger, "~/restart", self._on_restart)
            self.finished = False
            self._thread = threading.Thread(target=self._play, name="replay", daemon=True)
            self._thread.start()
            self.get_logger().info(
                f"replaying {self.bag}: {info.message_count} messages on {len(self._pubs)} "
                f"topics, {(info.end_ns - info.start_ns) * 1e-9:.1f} s recorded")

        def _publish(self, topic, msg_type, log_ns, data):
            pub = self._pubs.get(topic)
            if pub is not None:
                pub.publish(data)

        def _publish_clock(self, log_ns):
            self._clock_msg.clock.sec = log_ns // 1_000_000_000
            self._clock_msg.clock.nanosec = log_ns % 1_000_000_000
            self._clock_pub.publish(self._clock_msg)

        def _play(self):
            try:
                want = self.get_parameter("wait_for_subscribers").value
                while want > 0 and rclpy.ok(context=self.context) and not self.player._stop:
                    if all(p.get_subscription_count() >= want for p in self._pubs.values()):
                        break
                    time.sleep(0.05)
                n = self.player.run()
                if not self.player._stop:
                    from rclpy.duration import Duration

                    for p in self._pubs.values():
                        p.wait_for_all_acked(Duration(seconds=5))
                    self.get_logger().info(f"replay finished: {n} messages published")
            except Exception as exc:  # noqa: BLE001 - reported, then the node exits
                self.get_logger().error(f"replay failed: {exc}")
            finally:
                self.finished = True

        def _on_parameters(self, params):
            for p in params:
                if p.name == "rate":
                    if not isinstance(p.value, (int, float)) or p.value < 0:
                        return SetParametersResult(successful=False,
                                                   reason="rate must be a number >= 0")
                    self.player.set_rate(float(p.value))
                elif p.name == "loop":
                    self.player.loop = bool(p.value)
            return SetParametersResult(successful=True)

        def _on_pause(self, request, response):
            self.player.pause(request.data)
            response.success = True
            response.message = "paused" if request.data else "playing"
            return response

        def _on_restart(self, request, response):
            self.player.restart()
            response.success = True
            response.message = "restarted from the first message"
            return response

        def stop(self):
            self.player.stop()
            self._thread.join(timeout=5.0)

    return ReplayNode()


def main(args=None):
    """Entry point of ``replay_node`` (``ros2 run ltd_brake_ros replay_node``)."""
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.utilities import remove_ros_args

    argv = list(sys.argv if args is None else args)
    rclpy.init(args=argv)
    rest = remove_ros_args(argv)[1:]
    node = None
    status = 0
    try:
        node = _make_node(rest[0] if rest else None)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while rclpy.ok() and not node.finished:
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ValueError, FileNotFoundError) as exc:
        print(f"replay_node: {exc}", file=sys.stderr)
        status = 2
    finally:
        if node is not None:
            node.stop()
            node.destroy_node()
        rclpy.try_shutdown()
    return status


if __name__ == "__main__":
    sys.exit(main())
