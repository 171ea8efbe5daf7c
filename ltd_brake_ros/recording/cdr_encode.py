"""Encoding the payloads the plant publishes as CDR, without ROS (the inverse of :mod:`.cdr`).

The bytes are what ``rclpy.serialization.serialize_message`` writes for the same message: the
4-byte little-endian encapsulation header ``00 01 00 00``, then OMG CDR with each value aligned
to its size, counted from the end of that header; padding bytes are zero.
"""
from __future__ import annotations

import struct

import numpy as np

__all__ = ["encode_bool", "encode_clock", "encode_float64", "encode_float64_array"]

#: CDR encapsulation header: plain CDR, little endian.
_HEADER = b"\x00\x01\x00\x00"


def _pad(buf: bytearray, n: int) -> None:
    # CDR aligns relative to the end of the 4-byte encapsulation header
    buf += b"\x00" * (-(len(buf) - 4) % n)


def encode_float64_array(label: str, values) -> bytes:
    """A one-dimensional ``std_msgs/msg/Float64MultiArray`` as the plant fills it.

    ``layout.dim`` holds one dimension labelled ``label`` with size and stride the number of
    values; ``layout.data_offset`` is 0.

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
    n = int(data.size)
    text = label.encode() + b"\x00"
    buf = bytearray(_HEADER)
    buf += struct.pack("<II", 1, len(text))
    buf += text
    _pad(buf, 4)
    buf += struct.pack("<III", n, n, 0)  # size, stride, then layout.data_offset
    buf += struct.pack("<I", n)
    _pad(buf, 8)
    buf += data.tobytes()
    return bytes(buf)


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
