"""Occupancy grid, A* planning and path following (pure core, no ROS)."""

from __future__ import annotations

import itertools
import math

import pytest

import robot_models
from sim_bridge.navigation import NoPathError, PathFollower, grid_from_obstacles, plan_path
from sim_bridge.navigation.planner import path_length


@pytest.fixture(scope="module")
def grid():
    return grid_from_obstacles(robot_models.load("g1", "course").obstacles).inflated(0.45)


def test_path_goes_around_the_wall_and_stays_in_free_space(grid):
    path = plan_path(grid, (0.0, 0.0), (3.0, 0.0))
    clearance = grid_from_obstacles(robot_models.load("g1", "course").obstacles).inflated(0.40)
    assert path[0] == (0.0, 0.0) and path[-1] == (3.0, 0.0)
    assert max(abs(y) for _, y in path) > 0.9, "the wall spans y in [-0.9, 0.9]"
    for (x0, y0), (x1, y1) in itertools.pairwise(path):
        for i in range(21):
            s = i / 20
            assert clearance.is_free(x0 + s * (x1 - x0), y0 + s * (y1 - y0)), "at least 0.40 m from every obstacle"
    assert 3.0 < path_length(path) < 6.0


def test_goals_inside_obstacles_or_off_the_map_are_refused(grid):
    with pytest.raises(NoPathError, match="inside an obstacle"):
        plan_path(grid, (0.0, 0.0), (1.6, 0.0))
    with pytest.raises(NoPathError, match="outside the mapped area"):
        plan_path(grid, (0.0, 0.0), (50.0, 0.0))


def test_follower_turns_toward_the_path_then_aligns_and_arrives():
    follower = PathFollower([(0.0, 0.0), (0.0, 2.0)], goal_yaw=math.pi, xy_tolerance=0.1, yaw_tolerance=0.1)
    start = follower.command(0.0, 0.0, 0.0, speed=0.3, max_yaw_rate=0.6)
    assert start.phase == "follow" and start.wz > 0 and start.vx == 0.0, "turn left before walking"
    walking = follower.command(0.0, 1.0, math.pi / 2, speed=0.3, max_yaw_rate=0.6)
    assert walking.vx > 0.2 and abs(walking.wz) < 0.05
    assert walking.distance_remaining == pytest.approx(1.0, abs=1e-6)
    aligning = follower.command(0.0, 1.97, math.pi / 2, speed=0.3, max_yaw_rate=0.6)
    assert aligning.phase == "align" and aligning.vx == 0.0 and aligning.wz > 0
    assert follower.command(0.0, 1.97, math.pi - 0.05, speed=0.3, max_yaw_rate=0.6).phase == "arrived"


def test_follower_swayed_off_the_goal_while_turning_steps_back_instead_of_circling():
    # A robot carrying a load sways its pelvis a few centimetres while it turns at the goal: it must keep
    # turning and step back toward the goal, not pursue a goal point behind it (which turns it in circles).
    follower = PathFollower([(0.0, 0.0), (2.0, 0.0)], goal_yaw=0.0, xy_tolerance=0.05, yaw_tolerance=0.05)
    assert follower.command(1.97, 0.0, -math.pi / 2, speed=0.3, max_yaw_rate=0.6).phase == "align"
    swayed = follower.command(1.90, 0.03, -1.0, speed=0.3, max_yaw_rate=0.6)  # 10.4 cm off, facing -57 deg
    assert swayed.phase == "align" and swayed.wz > 0.5, "keeps turning toward the goal heading"
    # The goal is 10 cm ahead-and-left in the world: in the robot's frame (facing -57 deg) it is ahead and to the left.
    forward = math.cos(-1.0) * 0.10 + math.sin(-1.0) * -0.03
    left = -math.sin(-1.0) * 0.10 + math.cos(-1.0) * -0.03
    assert swayed.vx == pytest.approx(min(0.1, forward), abs=1e-9) and swayed.vy == pytest.approx(min(0.1, left), abs=1e-9)
    near = follower.command(1.93, 0.0, -1.0, speed=0.3, max_yaw_rate=0.6)  # within twice the tolerance: turn only
    assert near.phase == "align" and near.vx == near.vy == 0.0
    assert follower.command(1.99, 0.0, 0.02, speed=0.3, max_yaw_rate=0.6).phase == "arrived"
    pushed = follower.command(1.60, 0.0, -1.0, speed=0.3, max_yaw_rate=0.6)  # 40 cm away: follow the path again
    assert pushed.phase == "follow"
