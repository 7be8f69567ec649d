"""The scene's entities (sim_bridge.entities): names, ground-truth states, moving them, bounding boxes."""

from __future__ import annotations

import numpy as np
import pytest

import robot_models
from robot_models import panda_constants
from sim_bridge import Pose, Simulation, UnknownNameError
from sim_bridge.entities import (
    EntityKind,
    EntityStateError,
    FixedEntityError,
    InvalidPoseError,
    SceneEntities,
    box_overlaps_sphere,
    boxes_overlap,
)

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture
def panda():
    sim = Simulation(robot_models.load("panda"))
    return sim, SceneEntities(sim)


def test_the_panda_scene_has_the_robot_the_boxes_and_the_table(panda):
    _, entities = panda
    assert entities.names == ("panda", *panda_constants.BOX_NAMES, "table")
    assert [e.kind for e in entities.entities] == [EntityKind.ROBOT, *[EntityKind.OBJECT] * 3, EntityKind.OBSTACLE]
    assert [e.movable for e in entities.entities] == [False, True, True, True, False]
    assert [e.name for e in entities.matching("box_[02]")] == ["box_0", "box_2"]
    with pytest.raises(UnknownNameError, match="box_0, box_1, box_2"):
        entities.get("box_7")
    with pytest.raises(EntityStateError, match="regular expression"):
        entities.matching("box_[")


def test_a_box_is_moved_and_spun_in_world_axes(panda):
    sim, entities = panda
    target = np.array([0.4, 0.2, 0.05])
    yawed = np.array([np.cos(0.25), 0.0, 0.0, np.sin(0.25)])  # 0.5 rad about z
    entities.set_state("box_1", Pose(target, yawed), np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, 1.5]))
    state = entities.state("box_1")
    np.testing.assert_allclose(state.pose.position, target, atol=1e-12)
    np.testing.assert_allclose(state.pose.orientation_wxyz, yawed, atol=1e-12)
    np.testing.assert_allclose(state.linear_velocity, [0.1, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(state.angular_velocity, [0.0, 0.0, 1.5], atol=1e-12)  # world axes, whatever the yaw
    sim.step_physics(1)
    assert entities.state("box_1").pose.position[0] > target[0], "it moves on with the velocity it was given"


def test_a_refused_state_changes_nothing(panda):
    sim, entities = panda
    before = sim.data.qpos.copy(), sim.data.qvel.copy()
    with pytest.raises(InvalidPoseError, match="unit quaternion"):
        entities.set_state("box_0", Pose(np.zeros(3), np.array([0.5, 0.0, 0.0, 0.0])), np.ones(3))
    with pytest.raises(InvalidPoseError, match="outside the world"):
        entities.set_state("box_0", Pose(np.array([0.0, 5000.0, 0.0]), IDENTITY))
    with pytest.raises(EntityStateError, match="too large"):
        entities.set_state("box_0", Pose(np.zeros(3), IDENTITY), np.array([1e3, 0.0, 0.0]))
    with pytest.raises(FixedEntityError, match="fixed to the world"):
        entities.set_state("panda", Pose(np.zeros(3), IDENTITY))
    with pytest.raises(FixedEntityError, match="movable entities: box_0, box_1, box_2"):
        entities.set_state("table", None, np.zeros(3))
    np.testing.assert_array_equal(sim.data.qpos, before[0])
    np.testing.assert_array_equal(sim.data.qvel, before[1])


def test_bounding_boxes_in_world_and_in_the_entity_frame(panda):
    _, entities = panda
    x, y, z = panda_constants.BOX_HOME_POSITIONS[2]
    lower, upper = entities.world_box("box_2")
    np.testing.assert_allclose(lower, [x - 0.02, y - 0.02, z - 0.02], atol=1e-6)
    np.testing.assert_allclose(upper, [x + 0.02, y + 0.02, z + 0.02], atol=1e-6)
    np.testing.assert_allclose(entities.local_box("box_2")[1], [0.02, 0.02, 0.02], atol=1e-6)
    assert box_overlaps_sphere(lower, upper, np.array([x, y, z + 0.05]), 0.031)
    assert not box_overlaps_sphere(lower, upper, np.array([x, y, z + 0.05]), 0.029)
    assert boxes_overlap(lower, upper, upper, upper + 1.0) and not boxes_overlap(lower, upper, upper + 0.01, upper + 1.0)


def test_the_g1_is_a_movable_robot_and_the_course_obstacles_are_static():
    sim = Simulation(robot_models.load("g1", "course"))
    entities = SceneEntities(sim)
    assert entities.names == ("g1", "obstacle_wall", "obstacle_block", "obstacle_pillar")
    assert entities.get("g1").movable and not entities.get("obstacle_wall").movable
    np.testing.assert_allclose(entities.state("obstacle_wall").pose.position, [1.6, 0.0, 0.4], atol=1e-9)
    start = entities.state("g1").pose
    moved = start.position + np.array([1.0, 0.0, 0.0])
    entities.set_state("g1", Pose(moved, start.orientation_wxyz))
    np.testing.assert_allclose(entities.state("g1").pose.position, moved, atol=1e-12)
    np.testing.assert_allclose(sim.base_state().pose.position, moved, atol=1e-12)
