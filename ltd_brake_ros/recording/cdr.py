"""Decoding the recorded CDR payloads the analysis reads, without ROS.

The payloads are as ``rclpy.serialization.serialize_message`` writes them: a 4-byte
encapsulation header (byte 1 odd: little endian), then OMG CDR with each value aligned to its
size, counted from the end of that header.
"""
from __future__ import annotations

import struct

import numpy as np

__all__ = ["decode_float64_array", "decode_bool", "decode_joint_state"]


def _align(pos: int, n: int) -> int:
    # CDR aligns relative to the end of the 4-byte encapsulation header
    return 4 + ((pos - 4 + n - 1) & ~(n - 1))


def decode_float64_array(data: bytes) -> np.ndarray:
    """Values of a CDR-serialized ``std_msgs/msg/Float64MultiArray``, without ROS.

    Parameters
    ----------
    data : bytes
        The message as serialized by rclpy (4-byte encapsulation header, then CDR).

    Returns
    -------
    ndarray
        A read-only view of ``data`` (float64).

    Raises
    ------
    ValueError
        ``data`` is not such a message (too short for what it states).
    """
    n_bytes = len(data)
    if n_bytes < 8:
        raise ValueError(f"{n_bytes} bytes is too short for a Float64MultiArray")
    end = "<" if data[1] & 1 else ">"
    u32 = struct.Struct(end + "I").unpack_from

    def need(pos: int, what: str) -> None:
        if pos > n_bytes:
            raise ValueError(f"{what} runs past the end of the {n_bytes}-byte message")

    (ndim,) = u32(data, 4)
    pos = 8
    for _ in range(ndim):
        pos = _align(pos, 4)
        need(pos + 4, "a dimension")
        (slen,) = u32(data, pos)
        pos = _align(pos + 4 + slen, 4) + 8  # label, then size and stride
        need(pos, "a dimension")
    pos = _align(pos, 4) + 4  # data_offset
    pos = _align(pos, 4)
    need(pos + 4, "the data length")
    (n,) = u32(data, pos)
    pos = _align(pos + 4, 8)
    need(pos + 8 * n, f"the data ({n} values)")
    return np.frombuffer(data, dtype=end + "f8", count=n, offset=pos)


def decode_bool(data: bytes) -> bool:
    """Value of a CDR-serialized ``std_msgs/msg/Bool``.

    Parameters
    ----------
    data : bytes

    Returns
    -------
    bool

    Raises
    ------
    ValueError
        ``data`` is not such a message.
    """
    if len(data) < 5:
        raise ValueError(f"{len(data)} bytes is too short for a Bool")
    return data[4] != 0


def decode_string(data: bytes) -> str:
    """Value of a CDR-serialized ``std_msgs/msg/String``.

    Parameters
    ----------
    data : bytes

    Returns
    -------
    str

    Raises
    ------
    ValueError
        ``data`` is not such a message.
    """
    if len(data) < 8:
        raise ValueError(f"{len(data)} bytes is too short for a String")
    end = "<" if data[1] & 1 else ">"
    (length,) = struct.unpack_from(end + "I", data, 4)
    if length < 1 or 8 + length > len(data):
        raise ValueError(f"a String of {length} bytes does not fit in {len(data)} bytes")
    return bytes(data[8:7 + length]).decode(errors="replace")  # without the NUL


def decode_joint_state(data: bytes) -> tuple[int, list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Stamp, names and values of a CDR-serialized ``sensor_msgs/msg/JointState``.

    Parameters
    ----------
    data : bytes

    Returns
    -------
    stamp_ns : int
        ``header.stamp`` [ns].
    names : list of str
    position, velocity, effort : ndarray
        Read-only views of ``data`` (float64).

    Raises
    ------
    ValueError
        ``data`` is not such a message (too short for what it states).
    """
    n_bytes = len(data)
    end = "<" if n_bytes > 1 and data[1] & 1 else ">"
    u32 = struct.Struct(end + "I").unpack_from

    def need(pos: int, what: str) -> None:
        if pos > n_bytes:
            raise ValueError(f"{what} runs past the end of the {n_bytes}-byte JointState")

    def string(pos: int, what: str) -> tuple[str, int]:
        pos = _align(pos, 4)
        need(pos + 4, what)
        (length,) = u32(data, pos)
        need(pos + 4 + length, what)
        return bytes(data[pos + 4:pos + 3 + length]).decode(errors="replace"), pos + 4 + length

    need(12, "the header")
    sec, nanosec = struct.unpack_from(end + "iI", data, 4)
    _, pos = string(12, "header.frame_id")
    pos = _align(pos, 4)
    need(pos + 4, "the names")
    (count,) = u32(data, pos)
    pos += 4
    names = []
    for _ in range(count):
        name, pos = string(pos, "a name")
        names.append(name)
    arrays = []
    for what in ("position", "velocity", "effort"):
        pos = _align(pos, 4)
        need(pos + 4, what)
        (n,) = u32(data, pos)
        pos = _align(pos + 4, 8)
        need(pos + 8 * n, f"{what} ({n} values)")
        arrays.append(np.frombuffer(data, dtype=end + "f8", count=n, offset=pos))
        pos += 8 * n
    return sec * 1_000_000_000 + nanosec, names, *arrays
