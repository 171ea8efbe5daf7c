"""The plant's topics as a recording declares them: names, message types, offered QoS, payloads.

The same table as the ``sim_node`` publishers and subscriptions (topic names relative to the
node's namespace, ``/clock`` absolute; QoS as ``ros.messages`` sets it: reliable, volatile,
keep-last 10 for state, 1 for the clock, 1000 for commands; liveliness ``system_default``,
rclpy's default), readable without ROS so an offline run records what the node would.
:class:`StateEncoder` encodes the state messages of a snapshot as CDR, for the node and for
offline recordings alike.

The state goes out twice: as labelled ``Float64MultiArray`` arrays, one quantity per topic
(the plant's original interface), and as stamped ``sensor_msgs/msg/JointState`` messages
(``header.stamp`` = simulated time, one named joint per vehicle or coupler, position,
velocity and effort), which tie every sample to its simulated instant and which Foxglove and
PlotJuggler plot by joint name.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ..inputs.commands import VALVE_FIELDS, VALVE_POSITIONS
from .cdr_encode import (Float64ArrayEncoder, JointStateEncoder, encode_bool, encode_clock,
                         encode_float64, encode_string)
from .qos import qos_profiles_yaml

__all__ = ["ARRAY_TOPICS", "STATE_TOPICS", "CLOCK_TOPIC", "COMMAND_TOPICS", "JOINT_STATE",
           "STOPS_TOPIC", "STOP_EVENTS", "command_messages", "extra_topic", "joint_names",
           "plant_topics", "qualify", "stop_event_json", "StateEncoder"]

#: Published arrays (``std_msgs/msg/Float64MultiArray``): topic, Snapshot attribute,
#: ``layout.dim[0].label``.
ARRAY_TOPICS = (
    ("vehicles/speed", "speed_m_s", "vehicle"),
    ("vehicles/position", "position_m", "vehicle"),
    ("vehicles/brake_force", "brake_force_N", "vehicle"),
    ("vehicles/traction_force", "traction_force_N", "vehicle"),
    ("couplers/force", "coupler_force_N", "coupler"),
)
JOINT_STATE = "sensor_msgs/msg/JointState"
#: Stamped state (``sensor_msgs/msg/JointState``): topic and joint kind. Vehicles
#: ``vehicle_0`` (head) ... : position [m, centre's chainage], velocity [m/s], effort = air-brake
#: force [N, retarding positive]. Couplers ``coupler_1`` (behind the head) ... : position =
#: elongation [m, stretched positive], velocity = its rate [m/s], effort = force [N, draft
#: positive].
STATE_TOPICS = (("vehicles/state", "vehicle"), ("couplers/state", "coupler"))
CLOCK_TOPIC = "/clock"
#: The train description (JSON, :func:`~.metadata.train_description`), latched: published once
#: per run with transient-local durability, so a tool joining late receives it.
DESCRIPTION_TOPIC = "train/description"
#: The stops of a run as they happen (``std_msgs/msg/String``, one JSON object a message:
#: ``event`` -- ``stop_started``, ``stop_abandoned``, ``stopped``, ``settled``, ``drive_off``,
#: ``stop_ended`` --, ``time_s`` and the event's values, :class:`~ltd_brake_ros.simulator.Event`),
#: published and recorded when they happen: a report rebuilds each stop's record from them.
STOPS_TOPIC = "train/stops"
#: The events :data:`STOPS_TOPIC` carries.
STOP_EVENTS = ("stop_started", "stop_abandoned", "stopped", "settled", "drive_off",
               "stop_ended")
DESCRIPTION_TYPE = "std_msgs/msg/String"
#: Command topics: message type and the plant input each one sets. ``driver_brake_valve``
#: carries a position name of the driver's brake valve
#: (:data:`~ltd_brake_ros.inputs.commands.VALVE_POSITIONS`).
COMMAND_TOPICS = {"brake_command": ("std_msgs/msg/Bool", "emergency"),
                  "brake_demand": ("std_msgs/msg/Float64", "brake_demand"),
                  "traction_command": ("std_msgs/msg/Float64", "traction"),
                  "driver_brake_valve": ("std_msgs/msg/String", "driver_brake_valve")}
#: Unit suffixes of :attr:`Snapshot.extras` keys, dropped from their topic names.
UNIT_SUFFIXES = ("_Pa", "_N", "_m_s", "_m", "_s", "_kg", "_K", "_W", "_J")

_F64_ARRAY = "std_msgs/msg/Float64MultiArray"


def qualify(namespace: str, topic: str) -> str:
    """Fully qualified name of a node-relative ``topic`` in ``namespace`` (``/`` or ``/ns``)."""
    if topic.startswith("/"):
        return topic
    return f"{namespace.rstrip('/')}/{topic}"


def extra_topic(key: str) -> str:
    """Topic of a per-vehicle :attr:`Snapshot.extras` quantity: ``vehicles/<key>`` without its
    unit suffix (``brake_pipe_pressure_Pa`` -> ``vehicles/brake_pipe_pressure``)."""
    for suffix in UNIT_SUFFIXES:
        if key.endswith(suffix) and len(key) > len(suffix):
            return f"vehicles/{key[:-len(suffix)]}"
    return f"vehicles/{key}"


def command_messages(change: Mapping[str, Any]) -> list[tuple[str, bytes]]:
    """The command messages that make the input changes of a command script entry.

    Changes made by a driver's brake valve position (the whole entry of
    :data:`~ltd_brake_ros.inputs.commands.VALVE_POSITIONS`) go out as its name on
    ``driver_brake_valve`` (``std_msgs/msg/String``); the others each on its own topic.

    Parameters
    ----------
    change : mapping
        Input name (``emergency``, ``brake_demand``, ``traction``, ``overcharge``) to value.

    Returns
    -------
    list of (str, bytes)
        Node-relative topic and CDR payload of each message, in :data:`COMMAND_TOPICS` order.

    Raises
    ------
    KeyError
        A change no command topic carries (``overcharge`` outside a valve position).
    """
    valve = {name: change[name] for name in VALVE_FIELDS if name in change}
    position = next((name for name, sets in VALVE_POSITIONS.items()
                     if "overcharge" in sets and sets == valve), None)
    out = []
    for topic, (_, name) in COMMAND_TOPICS.items():
        if name == "driver_brake_valve":
            if position is not None:
                out.append((topic, encode_string(position)))
        elif name in change and (position is None or name not in valve):
            value = change[name]
            out.append((topic, encode_bool(value) if name == "emergency" else
                        encode_float64(value)))
    if "overcharge" in change and position is None:
        raise KeyError(f"overcharge={change['overcharge']!r} outside a driver's brake valve "
                       "position: no command topic carries it")
    return out


def stop_event_json(event) -> str:
    """A stop's event as the text of a :data:`STOPS_TOPIC` message: one JSON object, strict
    JSON (a value not a finite number, e.g. no peak yet, is ``null``)."""
    import json
    import math

    def plain(value):
        if isinstance(value, (bool, str)) or value is None:
            return value
        if isinstance(value, dict):
            return {str(k): plain(v) for k, v in value.items()}
        try:
            number = float(value)
        except (TypeError, ValueError):
            return str(value)
        if not math.isfinite(number):
            return None
        return int(number) if float(number).is_integer() and not isinstance(value, float) \
            else number

    return json.dumps(plain({"event": event.kind, "time_s": event.time_s, **event.detail}),
                      allow_nan=False)


def joint_names(kind: str, n_vehicles: int) -> list[str]:
    """Joint names of a :data:`STATE_TOPICS` kind: ``vehicle_0 ...`` or ``coupler_1 ...``."""
    if kind == "vehicle":
        return [f"vehicle_{i}" for i in range(n_vehicles)]
    return [f"coupler_{j}" for j in range(1, n_vehicles)]


def plant_topics(namespace: str = "/", extras=(), clock: bool = True
                 ) -> list[tuple[str, str, str]]:
    """Every topic a plant recording declares, as :class:`~..plant.recorder.Recorder` takes them.

    Parameters
    ----------
    namespace : str, optional
        The node's namespace.
    extras : iterable of str, optional
        The brake model's :attr:`Snapshot.extras` keys (see :func:`extra_topic`).
    clock : bool, optional
        Whether the plant publishes ``/clock``.

    Returns
    -------
    list of (str, str, str)
        Fully qualified name, message type, ``offered_qos_profiles`` text: the description,
        the stops, the arrays, the stamped state, the extras, ``/clock``, then the command
        topics.
    """
    def qos(depth: int) -> str:
        return qos_profiles_yaml(depth=depth, liveliness="system_default")

    latched = qos_profiles_yaml(depth=1, durability="transient_local",
                                liveliness="system_default")
    return ([(qualify(namespace, DESCRIPTION_TOPIC), DESCRIPTION_TYPE, latched),
             (qualify(namespace, STOPS_TOPIC), DESCRIPTION_TYPE, qos(100))]
            + [(qualify(namespace, t), _F64_ARRAY, qos(10)) for t, _, _ in ARRAY_TOPICS]
            + [(qualify(namespace, t), JOINT_STATE, qos(10)) for t, _ in STATE_TOPICS]
            + [(qualify(namespace, extra_topic(k)), _F64_ARRAY, qos(10)) for k in extras]
            + ([(CLOCK_TOPIC, "rosgraph_msgs/msg/Clock", qos(1))] if clock else [])
            + [(qualify(namespace, t), msg_type, qos(1000))
               for t, (msg_type, _) in COMMAND_TOPICS.items()])


class StateEncoder:
    """CDR payloads of every state message of a snapshot, in :func:`plant_topics` order.

    Parameters
    ----------
    n_vehicles : int
        Vehicles of the train.
    centre_offset_m : ndarray, optional
        Each vehicle's centre behind the head's front at rest [m] (the simulator's
        ``model.train.centre_offset_m``): coupler elongations are published from it, else 0.
    extras : iterable of str, optional
        :attr:`Snapshot.extras` keys published (per vehicle).
    clock : bool, optional
        Also encode ``/clock``.
    description : str, optional
        The train description (:func:`~.metadata.train_description`), encoded before the
        first state.
    """

    def __init__(self, n_vehicles: int, centre_offset_m=None, extras=(), clock: bool = True,
                 description: str | None = None):
        self._description = description
        n, nc = n_vehicles, n_vehicles - 1
        self.extras = tuple(extras)
        self._arrays = [(t, attribute, Float64ArrayEncoder(label, n if label == "vehicle"
                                                           else nc))
                        for t, attribute, label in ARRAY_TOPICS]
        (self._vehicles_topic, _), (self._couplers_topic, _) = STATE_TOPICS
        self._vehicles = JointStateEncoder(joint_names("vehicle", n))
        self._couplers = JointStateEncoder(joint_names("coupler", n))
        self._extras = [(extra_topic(k), k, Float64ArrayEncoder("vehicle", n))
                        for k in self.extras]
        # elongation_j = x_j - x_(j+1) with displacement x = position - start + offset:
        # the centres' spacing less their spacing at rest, offset_(j+1) - offset_j
        self._rest_gap_m = None if centre_offset_m is None else \
            np.diff(np.asarray(centre_offset_m, dtype=float))
        self._zeros = np.zeros(nc)
        self._clock = clock

    @staticmethod
    def encode_events(events) -> list[tuple[str, bytes]]:
        """The :data:`STOPS_TOPIC` messages of ``events`` (the others are not published)."""
        return [(STOPS_TOPIC, encode_string(stop_event_json(e))) for e in events
                if e.kind in STOP_EVENTS]

    def encode(self, snap, stamp_ns: int) -> list[tuple[str, bytes]]:
        """``(topic, payload)`` of every state message of ``snap`` (node-relative topics,
        ``/clock`` absolute), stamped ``stamp_ns`` [ns]."""
        out = []
        if self._description is not None:  # once, before the first state
            out.append((DESCRIPTION_TOPIC, encode_string(self._description)))
            self._description = None
        out += self.encode_events(snap.events)
        out += [(t, enc.encode(getattr(snap, attribute))) for t, attribute, enc in self._arrays]
        x, v = snap.position_m, snap.speed_m_s
        out.append((self._vehicles_topic,
                    self._vehicles.encode(stamp_ns, x, v, snap.brake_force_N)))
        elongation = self._zeros if self._rest_gap_m is None else \
            (x[:-1] - x[1:]) - self._rest_gap_m
        out.append((self._couplers_topic,
                    self._couplers.encode(stamp_ns, elongation, v[:-1] - v[1:],
                                          snap.coupler_force_N)))
        for t, key, enc in self._extras:
            out.append((t, enc.encode(snap.extras[key])))
        if self._clock:
            out.append((CLOCK_TOPIC, encode_clock(stamp_ns)))
        return out
