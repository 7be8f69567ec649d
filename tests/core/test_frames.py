"""Frames a goal may name: the /tf frames, resolved from the simulation's state."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import robot_models
from robot_models import panda_constants
from sim_bridge import Simulation
from sim_bridge.arm.pick_place import place_problem
from sim_bridge.errors import InvalidGoalError
from sim_bridge.frames import check_frame, frame_names, to_world
from sim_bridge.state import Pose


def test_the_frames_are_the_world_the_links_and_the_objects():
    panda = robot_models.load("panda")
    names = frame_names(panda)
    assert names[:3] == ("world", "map", "odom")
    assert {"panda_link0", "panda_hand", *panda_constants.BOX_NAMES} <= set(names)
    assert "table" not in names  # not on /tf
    g1 = frame_names(robot_models.load("g1"))
    assert "pelvis" in g1 and "torso_link" in g1


def test_an_unknown_frame_is_refused_with_the_known_ones():
    panda = robot_models.load("panda")
    with pytest.raises(InvalidGoalError, match=r"known frames.*panda_link0"):
        check_frame("kitchen", panda, "target")
    check_frame("", panda)
    check_frame("panda_hand", panda)


def test_a_pose_in_a_body_frame_is_expressed_in_the_world():
    sim = Simulation(robot_models.load("panda"))
    box = sim.body_pose("box_0")
    local = Pose(np.array([0.0, 0.1, 0.2]), np.array([1.0, 0.0, 0.0, 0.0]))
    world = to_world(sim.model, sim.data, "box_0", local)
    rotation = np.empty(9)
    mujoco.mju_quat2Mat(rotation, box.orientation_wxyz)
    assert np.allclose(world.position, box.position + rotation.reshape(3, 3) @ local.position)
    assert np.allclose(to_world(sim.model, sim.data, "world", local).position, local.position)


def test_a_place_must_be_on_the_table_at_a_height_it_can_honour():
    scene = robot_models.load("panda").arm_scene
    half = scene.object_half_size
    assert place_problem(scene, (0.4, 0.3, 0.0)) == ""
    assert place_problem(scene, (0.4, 0.3, half)) == ""
    assert "cannot be honoured" in place_problem(scene, (0.4, 0.3, 2.0))
    assert "cannot be honoured" in place_problem(scene, (0.4, 0.3, -0.5))
    assert "off the table" in place_problem(scene, (-0.8, 0.0, 0.0))
    assert "finite" in place_problem(scene, (float("nan"), 0.0, 0.0))


def test_the_weakest_grip_holds_the_box_four_times_over():
    from sim_bridge.arm.pick_place import GRIP_SAFETY, min_grip_force_n

    model = robot_models.load("panda").model
    box = model.body("box_1")
    needed = min_grip_force_n(model, "box_1")
    assert 2 * 1.0 * needed == pytest.approx(GRIP_SAFETY * float(box.mass[0]) * 9.81, rel=1e-3)  # friction 1.0
