"""The pre-serialized /joint_states and /clock templates give the same bytes' meaning as rclpy's own path."""

from __future__ import annotations

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

import robot_models
from nodes.serialized import ClockTemplate, JointStateTemplate


@pytest.mark.parametrize("robot", robot_models.ROBOT_NAMES)
def test_joint_state_template_round_trips_every_field(robot):
    names = list(robot_models.load(robot).actuated_joints)
    template = JointStateTemplate(names)
    rng = np.random.default_rng(3)
    for stamp in (0.0, 1.5, 12345.000000001):
        values = [rng.normal(size=len(names)) * 10 for _ in range(3)]
        msg = deserialize_message(template.serialize(stamp, *values), JointState)
        assert list(msg.name) == names
        assert msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 == pytest.approx(stamp, abs=1e-9)
        for got, want in zip((msg.position, msg.velocity, msg.effort), values, strict=False):
            np.testing.assert_array_equal(np.asarray(got), want)


def test_joint_state_template_bytes_equal_rclpy_serialization():
    names = ["a", "bb", "ccc"]
    values = [np.array([1.0, -2.0, 3.5]), np.array([0.1, 0.2, 0.3]), np.array([-9.0, 0.0, 9.0])]
    reference = JointState(name=names, position=values[0].tolist(), velocity=values[1].tolist(), effort=values[2].tolist())
    reference.header.stamp.sec, reference.header.stamp.nanosec = 3, 250_000_000
    assert JointStateTemplate(names).serialize(3.25, *values) == serialize_message(reference)


def test_clock_template_bytes_equal_rclpy_serialization():
    reference = Clock()
    reference.clock.sec, reference.clock.nanosec = 42, 7
    assert ClockTemplate().serialize(42.000000007) == serialize_message(reference)
