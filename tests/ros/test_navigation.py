"""NavigateToPose around the obstacles of the G1 course, from a client in another process."""

from __future__ import annotations

import math

import pytest
from action_msgs.msg import GoalStatus
from nav_msgs.msg import OccupancyGrid

from sim_interfaces.action import NavigateToPose
from tests.ros.actions import ready_client, result, send
from tests.ros.processes import running

pytestmark = pytest.mark.slow


def nav_goal(x: float, y: float, yaw: float = 0.0) -> NavigateToPose.Goal:
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = "world"
    goal.pose.pose.position.x, goal.pose.pose.position.y = x, y
    goal.pose.pose.orientation.z, goal.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return goal


@pytest.fixture(scope="module")
def course(client):
    with running(["bringup", "--robot", "g1", "--scene", "course", "--rtf", "2.0"]) as process:
        yield process


@pytest.fixture(scope="module")
def navigate(client, course):
    return ready_client(client, NavigateToPose, "/navigate_to_pose", timeout=90.0)


def test_the_course_is_published_as_a_map(client, course):
    from rclpy.qos import DurabilityPolicy, QoSProfile

    grid = client.record(OccupancyGrid, "/map", QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    client.wait_for(lambda: grid.count > 0, 30.0, "/map")
    occupied = sum(1 for v in grid.latest.data if v > 50)
    assert occupied > 100 and grid.latest.info.resolution == pytest.approx(0.05)


def test_navigate_to_a_goal_behind_the_wall(client, navigate):
    sent = send(client, navigate, nav_goal(3.0, 0.0))
    assert sent.handle.accepted
    outcome = result(client, sent, timeout=400.0)
    assert outcome.status == GoalStatus.STATUS_SUCCEEDED, outcome.result.error_msg
    final = outcome.result.final_pose.pose.position
    assert math.dist((final.x, final.y), (3.0, 0.0)) <= 0.2
    sideways = max(abs(f.current_pose.pose.position.y) for f in sent.feedback)
    assert sideways > 0.9, "the robot walked around the wall (it spans y in [-0.9, 0.9])"
    remaining = [f.distance_remaining for f in sent.feedback]
    assert remaining[0] > 3.0 and remaining[-1] < 0.5
    assert final.z > 0.6


def test_a_goal_inside_an_obstacle_is_aborted_with_a_reason(client, navigate):
    outcome = result(client, send(client, navigate, nav_goal(1.6, 0.0)))
    assert outcome.status == GoalStatus.STATUS_ABORTED
    assert outcome.result.error_code == NavigateToPose.Result.GOAL_IN_OBSTACLE
    assert "obstacle" in outcome.result.error_msg
