"""CDR encoding without ROS, against rclpy's serializer and the decoders."""
from __future__ import annotations

import array

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64, Float64MultiArray, MultiArrayDimension

from ltd_brake_ros.recording.cdr import decode_bool, decode_float64_array, decode_joint_state
from ltd_brake_ros.recording.cdr_encode import (Float64ArrayEncoder, JointStateEncoder,
                                                encode_bool, encode_clock, encode_float64,
                                                encode_float64_array, encode_joint_state)


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


@pytest.mark.parametrize("names", [[], ["vehicle_0"], ["coupler_1", "coupler_2", "coupler_10"],
                                   [f"vehicle_{i}" for i in range(33)]])
@pytest.mark.parametrize("t_ns", [0, 1_234_567_891])
def test_joint_state_reads_back_in_rclpy_and_in_our_decoder(names, t_ns):
    from sensor_msgs.msg import JointState

    n = len(names)
    rng = np.random.default_rng(n)
    position, velocity, effort = (rng.normal(0.0, 1e5, n) for _ in range(3))
    data = encode_joint_state(t_ns, names, position, velocity, effort)
    msg = deserialize_message(data, JointState)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == divmod(t_ns, 10**9)
    assert msg.header.frame_id == "" and list(msg.name) == names
    for got, want in zip((msg.position, msg.velocity, msg.effort), (position, velocity, effort)):
        np.testing.assert_array_equal(np.array(got), want)
    # the same message serialized by rclpy has the same length and reads the same
    ref = JointState(name=names, position=position.tolist(), velocity=velocity.tolist(),
                     effort=effort.tolist())
    ref.header.stamp = Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9)
    assert len(serialize_message(ref)) == len(data)
    stamp, got_names, *arrays = decode_joint_state(data)
    assert stamp == t_ns and got_names == names
    for got, want in zip(arrays, (position, velocity, effort)):
        np.testing.assert_array_equal(got, want)


def test_an_encoder_is_reused_message_after_message_and_checks_lengths():
    enc = JointStateEncoder(["a", "b"])
    first = enc.encode(1, [1.0, 2.0], [3.0, 4.0], [5.0, 6.0])
    second = enc.encode(2, [7.0, 8.0], [9.0, 10.0], [11.0, 12.0])
    assert decode_joint_state(first)[2].tolist() == [1.0, 2.0]  # not overwritten by the next
    assert decode_joint_state(second)[0] == 2
    with pytest.raises(ValueError):
        enc.encode(3, [1.0], [1.0, 2.0], [1.0, 2.0])
    with pytest.raises(ValueError, match="expected 3 values, got 2"):
        Float64ArrayEncoder("vehicle", 3).encode([1.0, 2.0])


def test_a_truncated_joint_state_is_refused():
    data = encode_joint_state(5, ["vehicle_0"], [1.0], [2.0], [3.0])
    for cut in (3, 11, 20, len(data) - 1):
        with pytest.raises(ValueError, match="runs past the end"):
            decode_joint_state(data[:cut])
