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


# --------------------------------------------------------------------------- frames


@pytest.mark.parametrize("prefix", ["", "t/", "train12/"])
@pytest.mark.parametrize("t_ns", [0, 1_020_000_000, 123_456_789_012])
def test_tf_and_odometry_read_back_in_rclpy_as_the_messages(prefix, t_ns):
    nav_msgs = pytest.importorskip("nav_msgs.msg")
    tf2_msgs = pytest.importorskip("tf2_msgs.msg", reason="./dev.sh builds it")
    from geometry_msgs.msg import TransformStamped

    from ltd_brake_ros.recording.cdr_encode import OdometryEncoder, TFMessageEncoder

    frames = [("map", f"{prefix}base_link")] + [(f"{prefix}base_link", f"{prefix}vehicle_{i}")
                                                 for i in range(12)]
    x = np.concatenate([[1234.5], -np.arange(12) * 16.03])
    stamp = Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9)
    msg = tf2_msgs.TFMessage()
    for (parent, child), xi in zip(frames, x):
        t = TransformStamped(child_frame_id=child)
        t.header.frame_id, t.header.stamp = parent, stamp
        t.transform.translation.x = float(xi)
        msg.transforms.append(t)
    encoder = TFMessageEncoder(frames)
    # (rclpy leaves padding bytes uninitialised: the messages are compared, not the bytes)
    assert deserialize_message(encoder.encode(t_ns, x), tf2_msgs.TFMessage) == msg
    data = encoder.encode(t_ns, x)  # reused
    assert deserialize_message(data, tf2_msgs.TFMessage) == msg
    assert len(data) == len(serialize_message(msg))
    with pytest.raises(ValueError, match="expected 13 values"):
        encoder.encode(t_ns, x[:5])
    odom = nav_msgs.Odometry(child_frame_id=f"{prefix}base_link")
    odom.header.frame_id, odom.header.stamp = "map", stamp
    odom.pose.pose.position.x, odom.twist.twist.linear.x = 1234.5, -3.25
    data = OdometryEncoder("map", f"{prefix}base_link").encode(t_ns, 1234.5, -3.25)
    assert deserialize_message(data, nav_msgs.Odometry) == odom
    assert len(data) == len(serialize_message(odom))


def test_vehicle_frames_go_out_at_their_rate_of_simulated_time():
    from ltd_brake_ros.recording.frames import ODOM_TOPIC, TF_TOPIC, FramesEncoder

    x, v = np.array([100.0, 84.0, 70.0]), np.array([20.0, 20.0, 20.0])

    def sent(encoder, chunks, chunk_s=0.02):
        out = []
        for k in range(chunks + 1):
            topics = [t for t, _ in encoder.encode(k * chunk_s, x, v, 0)]
            assert topics[:2] == [ODOM_TOPIC, TF_TOPIC]  # odometry and the head every chunk
            if encoder.vehicles_sent:
                assert topics == [ODOM_TOPIC, TF_TOPIC, TF_TOPIC]
                out.append(k)
        return out

    assert sent(FramesEncoder("", 3, 10.0), 50) == list(range(0, 51, 5))  # every 0.1 s
    assert sent(FramesEncoder("", 3, 1.0), 120, 0.03) == [0, 34, 67, 100]  # 0, 1.02, 2.01, 3 s
    assert sent(FramesEncoder("", 3, 0.0), 50) == []
    odom_only = FramesEncoder("", 3, 10.0, tf=False)
    assert [t for t, _ in odom_only.encode(0.0, x, v, 0)] == [ODOM_TOPIC]
