"""NavigateToPose around the obstacles of the G1 course, from a client in another process."""

from __future__ import annotations

import math

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from nav_msgs.msg import OccupancyGrid

from sim_interfaces.action import NavigateToPose
from tests.ros.actions import nav_goal, ready_client, result, send
from tests.ros.processes import running

pytestmark = pytest.mark.slow


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
    client.wait_for(lambda: grid.count > 0, 90.0, "/map")  # latched: comes at discovery, slow on a loaded machine
    occupied = sum(1 for v in grid.latest.data if v > 50)
    assert occupied > 100 and grid.latest.info.resolution == pytest.approx(0.05)


def test_navigate_to_a_goal_behind_the_wall(client, navigate):
    from nav_msgs.msg import Path
    from visualization_msgs.msg import Marker, MarkerArray

    from sim_ros.names import LATCHED

    plans = client.record(Path, "/plan", qos=LATCHED)
    markers = client.record(MarkerArray, "/goal_markers", qos=LATCHED)
    sent = send(client, navigate, nav_goal(3.0, 0.0))
    assert sent.handle.accepted
    outcome = result(client, sent, timeout=400.0)
    # the plan, as Nav2 publishes it: around the wall to the goal, then cleared when the goal ended
    client.wait_for(lambda: plans.count >= 2 and not plans.latest.poses, 60.0, "/plan cleared after the goal")
    planned = [p for p in plans.messages() if p.poses]
    assert planned and planned[0].header.frame_id == "world"
    points = [(q.pose.position.x, q.pose.position.y) for q in planned[0].poses]
    assert math.dist(points[-1], (3.0, 0.0)) < 0.1 and max(abs(y) for _, y in points) > 0.9, points
    client.wait_for(lambda: markers.count >= 2 and len(markers.latest.markers) == 1, 60.0, "/goal_markers cleared")
    shown = [m for array in markers.messages() for m in array.markers]
    arrows = [m for m in shown if m.type == Marker.ARROW and m.action == Marker.ADD]
    assert arrows and math.dist((arrows[0].pose.position.x, arrows[0].pose.position.y), (3.0, 0.0)) < 1e-6
    assert any(m.type == Marker.LINE_STRIP and len(m.points) == len(points) for m in shown)
    steps = [p for m in shown if m.ns.endswith("/footsteps") for p in m.points]
    assert len(steps) >= 2 and all(abs(p.y) < 2.0 for p in steps), "the planned footsteps, near the path"
    keep_out = [m for m in shown if m.ns.endswith("/keep_out")]
    assert keep_out and len(keep_out[0].points) > 100, "the obstacles grown by their clearance"
    assert markers.latest.markers[0].action == Marker.DELETEALL
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


def test_a_goal_in_the_robots_own_frame_is_resolved_where_it_stands(client, navigate):
    """NavigateToPose in ``pelvis`` (any /tf frame): 0.8 m straight ahead of where the robot stands now."""
    from nav_msgs.msg import Odometry

    from sim_ros.conversions import yaw_of

    odom = client.record(Odometry, "/odom", keep=10)
    client.wait_for(lambda: odom.count > 0, 30.0, "/odom")
    start = odom.latest.pose.pose
    o = start.orientation
    yaw = yaw_of(np.array([o.w, o.x, o.y, o.z]))
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = "pelvis"
    goal.pose.pose.position.x = 0.8
    goal.pose.pose.orientation.w = 1.0
    outcome = result(client, send(client, navigate, goal), timeout=300.0)
    assert outcome.status == GoalStatus.STATUS_SUCCEEDED, outcome.result.error_msg
    final = outcome.result.final_pose.pose.position
    expected = (start.position.x + 0.8 * math.cos(yaw), start.position.y + 0.8 * math.sin(yaw))
    assert math.dist((final.x, final.y), expected) <= 0.2, (final, expected)


def test_a_goal_in_an_unknown_frame_is_rejected_with_the_known_frames(client, navigate):
    goal = nav_goal(1.0, 0.0)
    goal.pose.header.frame_id = "base_footprint_of_another_robot"
    assert not send(client, navigate, goal).handle.accepted
