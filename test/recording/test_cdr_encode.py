"""CDR encoding without ROS, against rclpy's serializer and the decoder."""
from __future__ import annotations

import array

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64, Float64MultiArray, MultiArrayDimension

from ltd_brake_ros.recording.cdr import decode_bool, decode_float64_array
from ltd_brake_ros.recording.cdr_encode import (encode_bool, encode_clock, encode_float64,
                                                encode_float64_array)


@pytest.mark.parametrize("label", ["vehicle", "coupler", "", "ab", "abcdefghi"])
@pytest.mark.parametrize("n", [0, 1, 7])
def test_array_reads_back_in_rclpy(label, n):
    values = np.linspace(-3.5e5, 2.5, n)
    m = Float64MultiArray()
    m.layout.dim = [MultiArrayDimension(label=label, size=n, stride=n)]
    m.data = array.array("d", values.tobytes())
    data = encode_float64_array(label, values)
    ours = deserialize_message(data, Float64MultiArray)
    assert [(d.label, d.size, d.stride) for d in ours.layout.dim] == [(label, n, n)]
    assert ours.layout.data_offset == 0
    np.testing.assert_array_equal(np.array(ours.data), values)
    np.testing.assert_array_equal(decode_float64_array(data), values)
    if label in ("vehicle", "coupler"):
        # the plant's labels leave no padding, whose bytes rclpy leaves uninitialised
        assert data == serialize_message(m)


@pytest.mark.parametrize("t_ns", [0, 999_999_999, 1_000_000_000, 123_456_789_012])
def test_clock_bytes_equal_rclpy(t_ns):
    msg = Clock(clock=Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9))
    assert encode_clock(t_ns) == serialize_message(msg)


@pytest.mark.parametrize("value", [True, False])
def test_bool_reads_back_in_rclpy(value):
    data = encode_bool(value)
    # rclpy leaves its padding bytes uninitialised: compare the length and the value
    assert len(data) == len(serialize_message(Bool(data=value)))
    assert deserialize_message(data, Bool).data is value and decode_bool(data) is value


@pytest.mark.parametrize("value", [0.0, 0.35, -1.0])
def test_float64_bytes_equal_rclpy(value):
    assert encode_float64(value) == serialize_message(Float64(data=value))
