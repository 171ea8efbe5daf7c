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
has been published and acknowledged by reliable subscribers (at most 5 s). The playback itself
is :class:`~ltd_brake_ros.recording.player.Player`, which knows nothing of ROS.

A recording that cannot be played (not a recording, a damaged ``metadata.yaml`` or chunk, files
of several runs in one folder, a message type that is not installed) ends the node with one
line naming the file, record or topic, and exit status 1; so do unknown parameters and stray
arguments (:mod:`.program`).
"""
from __future__ import annotations

from .program import install_if_program, run, unknown_parameters

# before the imports below: a signal while they load ends the program cleanly
_SIGNALS = install_if_program("replay_node")

import sys  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import rclpy  # noqa: E402
from rcl_interfaces.msg import SetParametersResult  # noqa: E402
from rclpy.duration import Duration  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from ..plant.settings import MAX_REAL_TIME_FACTOR  # noqa: E402
from ..recording.bag import bag_info, message_class  # noqa: E402
from ..recording.player import Player  # noqa: E402
from ..recording.qos import qos_from_profile  # noqa: E402
from ..recording.reader import BagError, TruncatedBagWarning  # noqa: E402
from .messages import CLOCK_QOS, time_msg  # noqa: E402
from .params import ParamSpec, StartupError, declare_parameters  # noqa: E402

__all__ = ["ReplayNode", "main"]

#: Every parameter of replay_node; ``bag`` defaults to the first non-ROS argument.
PARAMETERS = (
    ParamSpec("bag", "", "recording to play: bag folder or .mcap file"),
    ParamSpec("rate", 1.0, "recorded time x rate = wall time; 0 plays as fast as possible",
              read_only=False, lo=0.0, hi=MAX_REAL_TIME_FACTOR),
    ParamSpec("loop", False, "start again at the end", read_only=False),
    ParamSpec("publish_clock", False, "publish /clock from the recorded time"),
    ParamSpec("start_paused", False, "wait for ~/pause false before playing"),
    ParamSpec("wait_for_subscribers", 0, "start once every topic has this many subscribers",
              lo=0, hi=1000),
)
USAGE = "replay_node BAG [--ros-args -p rate:=2.0 -p loop:=true ...]"
#: Longest wait for reliable subscribers to acknowledge the last messages [s].
ACK_TIMEOUT_S = 5.0


class ReplayNode(Node):
    """Republishes a recording (see the module documentation).

    Parameters
    ----------
    bag : str, optional
        Default of the ``bag`` parameter.
    **kwargs
        Passed to :class:`rclpy.node.Node`.

    Raises
    ------
    StartupError
        No recording was given, a parameter value is unusable, or the node has no such
        parameter.
    BagError
        The recording cannot be played (naming the file, record or topic).
    """

    def __init__(self, bag: str | None = None, **kwargs):
        super().__init__("replay_node", **kwargs)
        self._thread: threading.Thread | None = None
        try:
            self._setup(bag)
        except BaseException:  # a bad parameter or recording, or a signal during start-up
            self.destroy_node()
            raise

    def _setup(self, bag: str | None) -> None:
        specs = [ParamSpec("bag", bag or "", PARAMETERS[0].description), *PARAMETERS[1:]]
        p = declare_parameters(self, specs)
        unknown = unknown_parameters(self, [spec.name for spec in specs])
        if unknown:
            raise StartupError(*unknown)
        if not p["bag"]:
            raise StartupError("bag", "no recording given: pass a bag folder or .mcap file as "
                                      "the first argument or set the 'bag' parameter")
        self.bag = Path(p["bag"])
        self.info = info = bag_info(self.bag)
        if not info.complete:
            self.get_logger().warning(f"{self.bag} was not finished by its recorder: "
                                      "playing up to its last complete chunk")
        clock = p["publish_clock"]
        self._pubs = {}
        for name, topic in info.topics.items():
            if clock and name == "/clock":
                continue
            try:
                msg_class = message_class(topic.msg_type)
            except (LookupError, ValueError) as exc:
                raise BagError(self.bag, name, f"cannot be replayed: {exc}") from None
            qos = qos_from_profile(topic.qos_profiles[0] if topic.qos_profiles else None)
            self._pubs[name] = self.create_publisher(msg_class, name, qos)
        self._clock_pub = self.create_publisher(Clock, "/clock", CLOCK_QOS) if clock else None
        self.player = Player(self.bag, self._publish, rate=p["rate"], loop=p["loop"],
                             clock=self._publish_clock if clock else None,
                             skip_topics=("/clock",) if clock else (),
                             start_paused=p["start_paused"])
        self._wait_for = p["wait_for_subscribers"]
        self.add_on_set_parameters_callback(self._on_parameters)
        self.create_service(SetBool, "~/pause", self._on_pause)
        self.create_service(Trigger, "~/restart", self._on_restart)
        self.finished = False
        #: 1 once playing failed (the recording turned out damaged further in).
        self.exit_status = 0

    def start(self) -> None:
        """Start playing (on a thread of its own)."""
        info = self.info
        self.get_logger().info(
            f"replaying {self.bag}: {info.message_count} messages on {len(self._pubs)} "
            f"topics, {(info.end_ns - info.start_ns) * 1e-9:.1f} s recorded")
        self._thread = threading.Thread(target=self._play, name="replay", daemon=True)
        self._thread.start()

    def running(self) -> bool:
        """False once everything was played (without ``loop``) or playing failed."""
        return not self.finished

    def _publish(self, topic, msg_type, log_ns, data):
        pub = self._pubs.get(topic)
        if pub is not None:
            pub.publish(data)

    def _publish_clock(self, log_ns):
        self._clock_pub.publish(Clock(clock=time_msg(log_ns)))

    def _play(self):
        try:
            while self._wait_for > 0 and rclpy.ok(context=self.context) \
                    and not self.player.stopped:
                if all(p.get_subscription_count() >= self._wait_for
                       for p in self._pubs.values()):
                    break
                time.sleep(0.05)
            n = self.player.run()
            if not self.player.stopped:
                for p in self._pubs.values():
                    p.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))
                self.get_logger().info(f"replay finished: {n} messages published")
        except Exception as exc:  # noqa: BLE001 - one line, then the node exits with status 1
            what = "" if isinstance(exc, BagError) else f"{type(exc).__name__}: "
            self.get_logger().error(f"replay failed after {self.player.published} messages: "
                                    f"{what}{exc}")
            self.exit_status = 1
        finally:
            self.finished = True

    def _on_parameters(self, params):
        for p in params:
            if p.name == "rate":
                if not p.value >= 0.0:
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
        """Stop playing and wait for the playing thread (at most 5 s)."""
        self.player.stop()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    def close(self) -> None:
        """Stop playing and destroy the node."""
        self.stop()
        self.destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``replay_node`` (``ros2 run ltd_brake_ros replay_node``).

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments (default: ``sys.argv``).

    Returns
    -------
    int
        0 once everything was played (or after a signal), 1 when the recording or a parameter
        cannot be used (one line names the file, topic or parameter and the reason).
    """
    # the node says once, at start, that a recording was cut; not again after every pass
    warnings.filterwarnings("ignore", category=TruncatedBagWarning)
    return run("replay_node", args,
               lambda positional: ReplayNode(positional[0] if positional else None),
               usage=USAGE, signals=_SIGNALS, positional=("BAG",), errors=(StartupError,))


if __name__ == "__main__":
    sys.exit(main())
