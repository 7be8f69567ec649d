"""MoveArm on a G1 arm while the robot keeps standing, from a client in another process."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from nav_msgs.msg import Odometry

import robot_models
from sim_interfaces.action import MoveArm
from sim_ros.conversions import set_pose
from tests.ros.actions import ready_client, result, send
from tests.ros.processes import running

pytestmark = pytest.mark.slow


def test_g1_right_arm_reaches_a_pose_while_the_robot_stands(client):
    with running(["bringup", "--robot", "g1", "--rtf", "2.0"]):  # judged in sim time
        move_arm = ready_client(client, MoveArm, "/move_arm", timeout=90.0)
        odom = client.record(Odometry, "/odom", keep=10_000)
        client.wait_for(lambda: odom.count, 30.0, "/odom")
        start_height = odom.latest.pose.pose.position.z
        goal = MoveArm.Goal(end_effector="right_arm", position_tolerance=0.001, orientation_tolerance=0.01,
                            max_velocity_scaling=0.3)
        goal.target.header.frame_id = "world"
        set_pose(goal.target.pose, *_right_hand_at_the_keyframe())  # the robot stands at its keyframe
        goal.target.pose.position.x += 0.15
        goal.target.pose.position.y += 0.05
        goal.target.pose.position.z += 0.15
        outcome = result(client, send(client, move_arm, goal))
        assert outcome.status == GoalStatus.STATUS_SUCCEEDED, outcome.result.error_msg
        assert outcome.result.final_position_error <= 0.001
        heights = [m.pose.pose.position.z for m in odom.messages()]
        assert max(abs(h - start_height) for h in heights) < 0.01, "the pelvis kept its height: still standing"
        q = odom.latest.pose.pose.orientation
        tilt = math.degrees(2 * math.asin(min(1.0, math.hypot(q.x, q.y))))
        assert tilt < 3.0

        bad = MoveArm.Goal(end_effector="tail", position_tolerance=0.001)
        bad.target.pose.orientation.w = 1.0
        assert not send(client, move_arm, bad).handle.accepted


def _right_hand_at_the_keyframe() -> tuple:
    """World position and orientation (w, x, y, z) of the G1's right tool point in its standing keyframe."""
    robot = robot_models.load("g1")
    data = mujoco.MjData(robot.model)
    mujoco.mj_resetDataKeyframe(robot.model, data, robot.model.key(robot.default_keyframe).id)
    mujoco.mj_forward(robot.model, data)
    site = data.site(robot.end_effector_sites["right_arm"])
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, site.xmat)
    return site.xpos.copy(), quat
