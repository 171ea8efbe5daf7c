"""The plant's recorded topics, decoded and checked: what the report and the CSV export read.

One reading for both, so they agree on what a recording means and refuse the same things:
a plant topic recorded with another message type, a payload that does not decode, a value that
is not finite, and arrays whose lengths do not describe one train (every vehicle array as long
as the first one, the coupler array one shorter) — each a :class:`BagError` naming the
recording, the topic, the time and the reason, never a sample silently left out.
"""
from __future__ import annotations

import json
import warnings
from typing import Iterator

import numpy as np

from ..recording.cdr import (decode_bool, decode_float64_array, decode_joint_state,
                             decode_string)
from ..recording.reader import BagError, TruncatedBagWarning, read_bag

__all__ = ["ARRAYS", "BRAKE_COMMAND", "DESCRIPTION", "STATES", "STOPS", "plant_samples"]

F64_ARRAY = "std_msgs/msg/Float64MultiArray"
BOOL = "std_msgs/msg/Bool"
STRING = "std_msgs/msg/String"
#: Array topics under the plant's namespace: name -> element ("vehicle" or "coupler").
ARRAYS = {"vehicles/speed": "vehicle", "vehicles/position": "vehicle",
          "vehicles/brake_force": "vehicle", "vehicles/traction_force": "vehicle",
          "couplers/force": "coupler",
          # gauge pressures of a brake model that has a pipe [Pa]; absent otherwise
          "vehicles/brake_pipe_pressure": "vehicle", "vehicles/brake_cylinder_pressure": "vehicle",
          # brake-heat temperatures [K]; NaN for a vehicle without block brakes
          "vehicles/block_temperature": "vehicle", "vehicles/wheel_temperature": "vehicle"}
#: Arrays whose NaN means "not modelled for this vehicle", not a damaged value.
NAN_ALLOWED = ("vehicles/block_temperature", "vehicles/wheel_temperature")
#: The stamped state topics (``sensor_msgs/JointState``): topic -> the arrays it carries as
#: (name, field) pairs; ``header.stamp`` is the simulated time of the state.
STATES = {"vehicles/state": (("vehicles/position", 0), ("vehicles/speed", 1),
                             ("vehicles/brake_force", 2)),
          "couplers/state": (("couplers/force", 2),)}
JOINT_STATE = "sensor_msgs/msg/JointState"
#: The latched train description (JSON) under the plant's namespace.
DESCRIPTION = "train/description"
#: The emergency command topic under the plant's namespace.
BRAKE_COMMAND = "brake_command"
#: The driver's brake valve topic (std_msgs/String); its ``emergency`` position counts as
#: a true :data:`BRAKE_COMMAND`.
DRIVER_BRAKE_VALVE = "driver_brake_valve"
#: The stops' events (``std_msgs/msg/String``, one JSON object each, see
#: :data:`~ltd_brake_ros.recording.plant_topics.STOPS_TOPIC`).
STOPS = "train/stops"


class _Train:
    """The vehicle count the arrays must agree on, set by the first array seen."""

    def __init__(self, source):
        self.source = source
        self.n = None
        self.first = ""

    def check(self, topic: str, element: str, t: float, size: int) -> None:
        n = size + 1 if element == "coupler" else size
        if self.n is None:
            if n < 1:
                raise BagError(self.source, topic, f"empty array at t = {t:.3f} s: the plant "
                                                   "publishes one value per vehicle")
            self.n, self.first = n, f"{topic} at t = {t:.3f} s"
            return
        if n != self.n:
            expected = self.n - 1 if element == "coupler" else self.n
            raise BagError(self.source, topic, f"{size} values at t = {t:.3f} s where {expected} "
                           f"belong ({self.n} vehicles since {self.first}): the arrays do not "
                           "describe one train, so no report of it can be right")


def plant_samples(path, namespace: str, stamped: bool = False
                  ) -> Iterator[tuple[str, float, int, object]]:
    """The plant's samples of a recording, in log-time order, checked.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file (an unfinished one is read to its last complete chunk).
    namespace : str
        Namespace of the plant's topics (``/train1``; ``""`` for the root).
    stamped : bool, optional
        Take simulated time from the stamped states (:data:`STATES`) instead of the log
        times: for a recording made by another recorder (``ros2 bag record``), whose log times
        are receive times. Positions, speeds, brake and coupler forces then come from the
        states, each at its stamp; every other message at the stamp of the last state
        received before it (the state its command or value follows). Each state topic's
        stamps must increase strictly in the order the messages were logged: anything else
        (a reset of the plant, a second plant on the namespace, messages delivered out of
        order) is refused, since no single run's report can be made of it.

    Yields
    ------
    tuple
        ``(name, t_s, log_time_ns, value)``: ``name`` relative to the namespace (a key of
        :data:`ARRAYS` with an ndarray, :data:`BRAKE_COMMAND` with a bool, or :data:`STOPS`
        with a stop's event as a dict).

    Raises
    ------
    BagError
        The recording cannot be read, or a plant topic holds what the plant never publishes.
    """
    wanted = {f"{namespace}/{name}": (name, element) for name, element in ARRAYS.items()}
    states = {f"{namespace}/{topic}": fields for topic, fields in STATES.items()}
    if stamped:  # these arrays come from the states
        for fields in states.values():
            for name, _ in fields:
                wanted.pop(f"{namespace}/{name}", None)
    else:
        states = {}
    command = f"{namespace}/{BRAKE_COMMAND}"
    valve = f"{namespace}/{DRIVER_BRAKE_VALVE}"
    stops = f"{namespace}/{STOPS}"
    train = _Train(path)
    last_stamp_ns = 0
    stamps: dict[str, tuple[int, int]] = {}  # state topic -> (last stamp, its log time) [ns]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TruncatedBagWarning)
        for topic, msg_type, log_ns, data in read_bag(path):
            if topic == command:
                expected = BOOL
            elif topic in (valve, stops):
                expected = STRING
            elif topic in wanted:
                expected = F64_ARRAY
            elif topic in states:
                expected = JOINT_STATE
            else:
                continue
            t_ns = last_stamp_ns if stamped else log_ns
            t = t_ns / 1e9  # correctly rounded: 300_000_000 ns is 0.3 s as written
            if msg_type != expected:
                raise BagError(path, topic, f"recorded as {msg_type or 'an unnamed type'}, not "
                                            f"{expected}: not the plant's topic")
            try:
                if topic in states:
                    stamp_ns, _names, *values = decode_joint_state(data)
                else:
                    value = decode_bool(data) if topic == command else decode_string(data) \
                        if topic in (valve, stops) else decode_float64_array(data)
                    if topic == stops:
                        value = json.loads(value)
                        if not isinstance(value, dict) or not isinstance(value.get("event"),
                                                                         str):
                            raise ValueError("not a JSON object with an event name")
            except ValueError as exc:
                raise BagError(path, topic, f"message at t = {t:.3f} s does not decode: "
                                            f"{exc}") from None
            if topic in states:
                _check_stamp(path, topic, stamps, stamp_ns, log_ns)
                if topic.endswith("vehicles/state"):
                    last_stamp_ns = stamp_ns
                t = stamp_ns / 1e9
                for name, k in states[topic]:
                    element = ARRAYS[name]
                    value = np.asarray(values[k])
                    if not np.isfinite(value).all():
                        raise BagError(path, topic, f"non-finite value at t = {t:.3f} s")
                    train.check(topic, element, t, value.size)
                    yield name, t, log_ns, value
                continue
            if topic == command:
                yield BRAKE_COMMAND, t, log_ns, value
                continue
            if topic == stops:
                yield STOPS, t, log_ns, value
                continue
            if topic == valve:
                # the valve's emergency position is the same command as brake_command = true
                if value.strip() == "emergency":
                    yield BRAKE_COMMAND, t, log_ns, True
                continue
            name, element = wanted[topic]
            bad = ~np.isfinite(value)
            if name in NAN_ALLOWED:
                bad &= ~np.isnan(value)
            if bad.any():
                raise BagError(path, topic, f"non-finite value at t = {t:.3f} s (index "
                               f"{int(np.flatnonzero(bad)[0])})")
            train.check(topic, element, t, value.size)
            yield name, t, log_ns, value


def _check_stamp(path, topic: str, stamps: dict, stamp_ns: int, log_ns: int) -> None:
    """Refuse a state whose header stamp does not follow the topic's last one strictly."""
    before = stamps.get(topic)
    if before is not None and stamp_ns <= before[0]:
        raise BagError(path, topic, f"header stamps are not strictly increasing: "
                       f"t = {stamp_ns * 1e-9:.3f} s (logged at {log_ns * 1e-9:.3f} s) follows "
                       f"t = {before[0] * 1e-9:.3f} s (logged at {before[1] * 1e-9:.3f} s); "
                       "the recording holds more than one run (a reset, or two plants on one "
                       "namespace) or states out of order, and no one report of it can be "
                       "right: record the plant's own bag (record:=true), or cut the "
                       "recording where a run starts")
    stamps[topic] = (stamp_ns, log_ns)
