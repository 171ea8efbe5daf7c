"""Encoding the payloads the plant publishes as CDR, without ROS (the inverse of :mod:`.cdr`).

The bytes are what ``rclpy.serialization.serialize_message`` writes for the same message: the
4-byte little-endian encapsulation header ``00 01 00 00``, then OMG CDR with each value aligned
to its size, counted from the end of that header; padding bytes are zero.
"""
from __future__ import annotations

import struct

import numpy as np

__all__ = ["Float64ArrayEncoder", "JointStateEncoder", "OdometryEncoder", "TFMessageEncoder",
           "encode_bool", "encode_clock", "encode_float64", "encode_float64_array",
           "encode_joint_state"]

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


def _header(buf: bytearray, frame_id: str) -> int:
    """Append a ``std_msgs/Header`` with a zero stamp; the stamp's offset in ``buf``."""
    _pad(buf, 4)
    offset = len(buf)
    buf += b"\x00" * 8  # stamp: sec, nanosec
    _string(buf, frame_id)
    return offset


def _doubles(buf: bytearray, values) -> int:
    """Append float64 values (aligned); the offset of the first in ``buf``."""
    _pad(buf, 8)
    offset = len(buf)
    buf += struct.pack(f"<{len(values)}d", *values)
    return offset


class TFMessageEncoder:
    """``tf2_msgs/msg/TFMessage`` messages of fixed frames, translated along x only.

    Every transform has the same stamp, a translation (x, 0, 0) and the identity rotation
    (frames along a straight, level track); names are laid out once.

    Parameters
    ----------
    frames : sequence of (str, str)
        ``(header.frame_id, child_frame_id)`` of each transform.
    """

    def __init__(self, frames):
        frames = list(frames)
        self.n = len(frames)
        buf = bytearray(_HEADER)
        buf += struct.pack("<I", self.n)
        stamps, xs = [], []
        for parent, child in frames:
            stamps.append(_header(buf, parent))
            _string(buf, child)
            xs.append(_doubles(buf, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)))
        self._buf = np.frombuffer(bytearray(buf), dtype=np.uint8)
        # CDR aligns from byte 4: every value sits at 4 + its size times k
        self._sec = self._buf[4:].view("<i4")
        self._nsec = self._buf[4:].view("<u4")
        self._stamp = (np.asarray(stamps, dtype=np.int64) - 4) // 4
        self._x = self._buf[4:4 + (len(buf) - 4) // 8 * 8].view("<f8")
        self._xi = (np.asarray(xs, dtype=np.int64) - 4) // 8

    def encode(self, stamp_ns: int, x_m) -> bytes:
        """The message at ``stamp_ns`` [ns] with each transform's translation along x [m].

        Raises
        ------
        ValueError
            ``x_m`` does not hold one value per transform.
        """
        x = np.asarray(x_m, dtype=float)
        if x.shape != (self.n,):
            raise ValueError(f"expected {self.n} values, got {x.size}")
        sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
        self._sec[self._stamp] = sec
        self._nsec[self._stamp + 1] = nanosec
        self._x[self._xi] = x
        return self._buf.tobytes()


class OdometryEncoder:
    """``nav_msgs/msg/Odometry`` messages of a body moving along x of its parent frame.

    Position (x, 0, 0), the identity orientation, a linear velocity (v, 0, 0) in the body's
    frame, no rotation; covariances all zero (the simulated state is exact).

    Parameters
    ----------
    frame_id : str
        ``header.frame_id`` (the fixed frame).
    child_frame_id : str
        The body's frame.
    """

    def __init__(self, frame_id: str, child_frame_id: str):
        buf = bytearray(_HEADER)
        self._stamp = _header(buf, frame_id)
        _string(buf, child_frame_id)
        self._x = _doubles(buf, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0) + (0.0,) * 36)
        self._v = _doubles(buf, (0.0,) * 6 + (0.0,) * 36)
        self._buf = buf

    def encode(self, stamp_ns: int, x_m: float, v_m_s: float) -> bytes:
        """The message at ``stamp_ns`` [ns]: position ``x_m`` [m], speed ``v_m_s`` [m/s]."""
        sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
        struct.pack_into("<iI", self._buf, self._stamp, sec, nanosec)
        struct.pack_into("<d", self._buf, self._x, float(x_m))
        struct.pack_into("<d", self._buf, self._v, float(v_m_s))
        return bytes(self._buf)


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
