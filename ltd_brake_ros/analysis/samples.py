"""The plant's recorded topics, decoded and checked: what the report and the CSV export read.

One reading for both, so they agree on what a recording means and refuse the same things:
a plant topic recorded with another message type, a payload that does not decode, a value that
is not finite, and arrays whose lengths do not describe one train (every vehicle array as long
as the first one, the coupler array one shorter) — each a :class:`BagError` naming the
recording, the topic, the time and the reason, never a sample silently left out.
"""
from __future__ import annotations

import warnings
from typing import Iterator

import numpy as np

from ..recording.cdr import decode_bool, decode_float64_array, decode_string
from ..recording.reader import BagError, TruncatedBagWarning, read_bag

__all__ = ["ARRAYS", "BRAKE_COMMAND", "plant_samples"]

F64_ARRAY = "std_msgs/msg/Float64MultiArray"
BOOL = "std_msgs/msg/Bool"
STRING = "std_msgs/msg/String"
#: Array topics under the plant's namespace: name -> element ("vehicle" or "coupler").
ARRAYS = {"vehicles/speed": "vehicle", "vehicles/position": "vehicle",
          "vehicles/brake_force": "vehicle", "vehicles/traction_force": "vehicle",
          "couplers/force": "coupler",
          # gauge pressures of a brake model that has a pipe [Pa]; absent otherwise
          "vehicles/brake_pipe_pressure": "vehicle", "vehicles/brake_cylinder_pressure": "vehicle"}
#: The emergency command topic under the plant's namespace.
BRAKE_COMMAND = "brake_command"
#: The driver's brake valve topic (std_msgs/String); its ``emergency`` position counts as
#: a true :data:`BRAKE_COMMAND`.
DRIVER_BRAKE_VALVE = "driver_brake_valve"


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


def plant_samples(path, namespace: str) -> Iterator[tuple[str, float, int, object]]:
    """The plant's samples of a recording, in log-time order, checked.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file (an unfinished one is read to its last complete chunk).
    namespace : str
        Namespace of the plant's topics (``/train1``; ``""`` for the root).

    Yields
    ------
    tuple
        ``(name, t_s, log_time_ns, value)``: ``name`` relative to the namespace (a key of
        :data:`ARRAYS` with an ndarray, or :data:`BRAKE_COMMAND` with a bool).

    Raises
    ------
    BagError
        The recording cannot be read, or a plant topic holds what the plant never publishes.
    """
    wanted = {f"{namespace}/{name}": (name, element) for name, element in ARRAYS.items()}
    command = f"{namespace}/{BRAKE_COMMAND}"
    valve = f"{namespace}/{DRIVER_BRAKE_VALVE}"
    train = _Train(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TruncatedBagWarning)
        for topic, msg_type, log_ns, data in read_bag(path):
            if topic == command:
                expected = BOOL
            elif topic == valve:
                expected = STRING
            elif topic in wanted:
                expected = F64_ARRAY
            else:
                continue
            t = log_ns * 1e-9
            if msg_type != expected:
                raise BagError(path, topic, f"recorded as {msg_type or 'an unnamed type'}, not "
                                            f"{expected}: not the plant's topic")
            try:
                value = decode_bool(data) if topic == command else decode_string(data) \
                    if topic == valve else decode_float64_array(data)
            except ValueError as exc:
                raise BagError(path, topic, f"message at t = {t:.3f} s does not decode: "
                                            f"{exc}") from None
            if topic == command:
                yield BRAKE_COMMAND, t, log_ns, value
                continue
            if topic == valve:
                # the valve's emergency position is the same command as brake_command = true
                if value.strip() == "emergency":
                    yield BRAKE_COMMAND, t, log_ns, True
                continue
            name, element = wanted[topic]
            if not np.isfinite(value).all():
                raise BagError(path, topic, f"non-finite value at t = {t:.3f} s (index "
                               f"{int(np.flatnonzero(~np.isfinite(value))[0])})")
            train.check(topic, element, t, value.size)
            yield name, t, log_ns, value
