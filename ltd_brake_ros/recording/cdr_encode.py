"""Encoding the payloads the plant publishes as CDR, without ROS (the inverse of :mod:`.cdr`).

The bytes are what ``rclpy.serialization.serialize_message`` writes for the same message: the
4-byte little-endian encapsulation header ``00 01 00 00``, then OMG CDR with each value aligned
to its size, counted from the end of that header; padding bytes are zero.
"""
from __future__ import annotations

import struct

import numpy as np

__all__ = ["Float64ArrayEncoder", "JointStateEncoder", "encode_bool", "encode_clock",
           "encode_float64", "encode_float64_array", "encode_joint_state"]

#: CDR encapsulation header: plain CDR, little endian.
_HEADER = b"\x00\x01\x00\x00"


def _pad(buf: bytearray, n: int) -> None:
    # CDR aligns relative to the end of the 4-byte encapsulation header
    buf += b"\x00" * (-(len(buf) - 4) % n)


def _string(buf: bytearray, text: str) -> None:
    # a CDR string: aligned length including the terminating NUL, the bytes, the NUL
    raw = text.encode() + b"\x00"
    _pad(buf, 4)
    buf += struct.pack("<I", len(raw))
    buf += raw


class Float64ArrayEncoder:
    """One-dimensional ``std_msgs/msg/Float64MultiArray`` messages of a fixed length.

    ``layout.dim`` holds one dimension labelled ``label`` with size and stride ``n``;
    ``layout.data_offset`` is 0. Everything before the data is encoded once.

    Parameters
    ----------
    label : str
        ``layout.dim[0].label`` (``vehicle`` or ``coupler``).
    n : int
        Number of values.
    """

    def __init__(self, label: str, n: int):
        buf = bytearray(_HEADER)
        buf += struct.pack("<I", 1)
        _string(buf, label)
        _pad(buf, 4)
        buf += struct.pack("<III", n, n, 0)  # size, stride, then layout.data_offset
        buf += struct.pack("<I", n)
        _pad(buf, 8)
        self.n, self._prefix = n, bytes(buf)

    def encode(self, values) -> bytes:
        """The message holding ``values`` (``n`` floats, SI units).

        Raises
        ------
        ValueError
            ``values`` does not hold ``n`` values.
        """
        data = np.ascontiguousarray(values, dtype="<f8")
        if data.size != self.n:
            raise ValueError(f"expected {self.n} values, got {data.size}")
        return self._prefix + data.tobytes()


def encode_float64_array(label: str, values) -> bytes:
    """A one-dimensional ``std_msgs/msg/Float64MultiArray`` as the plant fills it.

    Parameters
    ----------
    label : str
        ``layout.dim[0].label`` (``vehicle`` or ``coupler``).
    values : array_like
        The data (float64, SI units).

    Returns
    -------
    bytes
    """
    data = np.ascontiguousarray(values, dtype="<f8").ravel()
    return Float64ArrayEncoder(label, int(data.size)).encode(data)


class JointStateEncoder:
    """``sensor_msgs/msg/JointState`` messages with fixed joint names.

    The header (``stamp``, ``frame_id``) and the names are laid out once; each message then
    writes the stamp and the three value arrays into that layout.

    Parameters
    ----------
    names : sequence of str
        Joint names (``vehicle_0``, ...).
    frame_id : str, optional
        ``header.frame_id``.
    """

    def __init__(self, names, frame_id: str = ""):
        names = list(names)
        n = self.n = len(names)
        buf = bytearray(_HEADER)
        buf += b"\x00" * 8  # header.stamp: sec, nanosec
        _string(buf, frame_id)
        _pad(buf, 4)
        buf += struct.pack("<I", n)
        for name in names:
            _string(buf, name)
        self._offsets = []
        for _ in range(3):  # position, velocity, effort
            _pad(buf, 4)
            buf += struct.pack("<I", n)
            _pad(buf, 8)  # as rclpy writes it, even for no values
            self._offsets.append(len(buf))
            buf += b"\x00" * (8 * n)
        self._buf = buf
        self._views = [np.frombuffer(buf, dtype="<f8", count=n, offset=o)
                       for o in self._offsets]

    def encode(self, stamp_ns: int, position, velocity, effort) -> bytes:
        """The message at simulated time ``stamp_ns`` [ns] with ``n`` values per array.

        Raises
        ------
        ValueError
            An array does not hold ``n`` values.
        """
        sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
        for view, values in zip(self._views, (position, velocity, effort)):
            if len(values) != self.n:
                raise ValueError(f"expected {self.n} values, got {len(values)}")
            view[:] = values
        struct.pack_into("<iI", self._buf, 4, sec, nanosec)
        return bytes(self._buf)


def encode_joint_state(stamp_ns: int, names, position, velocity, effort,
                       frame_id: str = "") -> bytes:
    """A ``sensor_msgs/msg/JointState`` (see :class:`JointStateEncoder`).

    Parameters
    ----------
    stamp_ns : int
        ``header.stamp`` [ns].
    names : sequence of str
    position, velocity, effort : array_like
        One value per name.
    frame_id : str, optional

    Returns
    -------
    bytes
    """
    return JointStateEncoder(names, frame_id).encode(stamp_ns, position, velocity, effort)


def encode_bool(value: bool) -> bytes:
    """A ``std_msgs/msg/Bool``.

    Parameters
    ----------
    value : bool

    Returns
    -------
    bytes
    """
    return _HEADER + (b"\x01" if value else b"\x00") + b"\x00\x00\x00"


def encode_float64(value: float) -> bytes:
    """A ``std_msgs/msg/Float64``.

    Parameters
    ----------
    value : float

    Returns
    -------
    bytes
    """
    return _HEADER + struct.pack("<d", float(value))


def encode_string(text: str) -> bytes:
    """A ``std_msgs/msg/String``.

    Parameters
    ----------
    text : str

    Returns
    -------
    bytes
    """
    buf = bytearray(_HEADER)
    _string(buf, text)
    return bytes(buf)


def encode_clock(time_ns: int) -> bytes:
    """A ``rosgraph_msgs/msg/Clock`` holding a simulated time.

    Parameters
    ----------
    time_ns : int
        Time [ns], non-negative.

    Returns
    -------
    bytes
    """
    sec, nanosec = divmod(int(time_ns), 1_000_000_000)
    return _HEADER + struct.pack("<iI", sec, nanosec)
