"""CDR decoding without ROS, against rclpy's serializer."""
from __future__ import annotations

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import Bool, Float64MultiArray, MultiArrayDimension

from ltd_brake_ros.recording.cdr import decode_bool, decode_float64_array


@pytest.mark.parametrize("labels", [[], ["vehicle"], ["ab", "coupler_of_train"], ["xyz"] * 3])
@pytest.mark.parametrize("n", [0, 1, 7])
def test_cdr_decoding_matches_rclpy(labels, n):
    m = Float64MultiArray()
    m.layout.dim = [MultiArrayDimension(label=lab, size=n, stride=1) for lab in labels]
    m.layout.data_offset = 3
    values = np.linspace(-1.5, 2.5, n)
    m.data = values.tolist()
    np.testing.assert_array_equal(decode_float64_array(serialize_message(m)), values)


@pytest.mark.parametrize("value", [True, False])
def test_bool_decoding_matches_rclpy(value):
    assert decode_bool(serialize_message(Bool(data=value))) is value
