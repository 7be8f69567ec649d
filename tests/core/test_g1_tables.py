"""The G1's ``tables`` scene: tables that are obstacles, objects that rest on the first one and are entities."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import robot_models
import robot_models.g1_constants as names
from robot_models import g1_tables
from sim_bridge import Pose, Simulation
from sim_bridge.arm import ArmController
from sim_bridge.controller import Slot
from sim_bridge.entities import EntityKind, FixedEntityError, SceneEntities
from sim_bridge.locomotion import LocomotionMode, WalkingController
from sim_bridge.navigation import grid_from_obstacles, plan_path

SETTLE_SECONDS = 2.0
MAX_OBJECT_DRIFT_M = 0.002


@pytest.fixture(scope="module")
def robot() -> robot_models.RobotSpec:
    return robot_models.load(robot_models.G1, "tables")


def test_the_scene_is_registered_and_built(robot):
    robot_models.check_scene(robot_models.G1, "tables")
    assert robot.scene == "tables"
    assert robot.objects == ("box", "cube", "can")
    assert [o.name for o in robot.obstacles] == ["table_0", "table_1"]
    model = robot.model
    for item in g1_tables.OBJECTS:
        assert float(model.body(item.name).mass[0]) == pytest.approx(item.mass_kg)
        geom = model.geom(item.name)
        assert int(geom.condim[0]) == 4 and float(geom.friction[0]) == pytest.approx(1.0)
    box = g1_tables.BOX
    assert 2 * box.half_size[1] == pytest.approx(0.25) and 0.5 <= box.mass_kg <= 1.0, "a box for both hands"
    assert 2 * g1_tables.CUBE.half_size[0] == pytest.approx(0.055)
    assert g1_tables.CAN.shape is g1_tables.Shape.CYLINDER
    np.testing.assert_allclose(model.geom("can").size[:2], [0.033, 0.06])
    first, second = g1_tables.TABLES
    assert 0.7 <= first.top_z <= 0.8 and 2.0 <= np.linalg.norm(np.subtract(first.center_xy, second.center_xy)) <= 4.0


def test_the_tables_are_map_obstacles_that_the_robot_body_and_soles_touch(robot):
    model = robot.model
    shell = model.geom("pelvis_shell")
    sole = model.geom(robot.sensors.feet[0].geom)
    for table, obstacle in zip(g1_tables.TABLES, robot.obstacles, strict=True):
        assert obstacle.height == table.top_z and obstacle.center_xy == table.center_xy
        assert obstacle.geom_names == (table.name, *table.leg_names)
        for name in obstacle.geom_names:
            geom = model.geom(name)
            assert int(geom.bodyid[0]) == 0, "static: a geom of the world body"
            assert geom.contype & sole.conaffinity and geom.conaffinity & shell.contype and geom.conaffinity & sole.contype
    grid = grid_from_obstacles(robot.obstacles)
    for table in g1_tables.TABLES:
        assert not grid.is_free(*table.center_xy)
    assert grid.is_free(0.0, 0.0)
    path = plan_path(grid.inflated(0.45), (0.0, 0.0), (2.2, 0.0))  # behind the first table
    x_min, x_max, y_min, y_max = g1_tables.PICK_TABLE.xy_bounds
    assert not any(x_min <= x <= x_max and y_min <= y <= y_max for x, y in path)


def test_the_objects_rest_on_the_first_table_while_the_robot_stands(robot):
    sim = Simulation(robot)
    key = robot.model.keyframe(robot.default_keyframe)
    x_min, x_max, y_min, y_max = g1_tables.OBJECTS_TABLE.xy_bounds
    start = {}
    for item in g1_tables.OBJECTS:
        adr = int(robot.model.joint(item.name).qposadr[0])
        np.testing.assert_allclose(key.qpos[adr : adr + 7], [*g1_tables.object_rest_position(item), 1, 0, 0, 0])
        x, y, _ = start[item.name] = sim.body_pose(item.name).position.copy()
        assert x_min + item.half_size[0] <= x <= x_max - item.half_size[0]
        assert y_min + item.half_size[1] <= y <= y_max - item.half_size[1]
    sim.step(round(SETTLE_SECONDS / sim.control_timestep))
    for item in g1_tables.OBJECTS:
        pose = sim.body_pose(item.name)
        drift = float(np.linalg.norm(pose.position - start[item.name]))
        assert drift < MAX_OBJECT_DRIFT_M, f"{item.name} moved {drift * 1000:.2f} mm"
        assert abs(pose.orientation_wxyz[0]) > 0.9999, f"{item.name} tilted"
    assert sim.base_state().pose.position[2] > 0.7, "the robot still stands"


def test_tables_and_objects_are_entities_with_bounds_and_the_objects_move(robot):
    sim = Simulation(robot)
    entities = SceneEntities(sim)
    assert entities.names == ("g1", "box", "cube", "can", "table_0", "table_1")
    for item in g1_tables.OBJECTS:
        entity = entities.get(item.name)
        assert entity.kind is EntityKind.OBJECT and entity.movable
        lower, upper = entities.world_box(item.name)
        np.testing.assert_allclose(upper - lower, 2 * np.asarray(item.half_size), atol=1e-9)
    for table in g1_tables.TABLES:
        entity = entities.get(table.name)
        assert entity.kind is EntityKind.OBSTACLE and not entity.movable and "navigation map" in entity.description
        lower, upper = entities.world_box(table.name)
        x_min, x_max, y_min, y_max = table.xy_bounds
        np.testing.assert_allclose(lower, [x_min, y_min, 0.0], atol=1e-9)
        np.testing.assert_allclose(upper, [x_max, y_max, table.top_z], atol=1e-9)
        np.testing.assert_allclose(entities.state(table.name).pose.position[:2], table.center_xy, atol=1e-9)
        with pytest.raises(FixedEntityError, match="movable entities: g1, box, cube, can"):
            entities.set_state(table.name, Pose(np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])))
    second = g1_tables.PLACE_TABLE
    target = np.array([*second.center_xy, second.top_z + g1_tables.CUBE.half_size[2]])
    entities.set_state("cube", Pose(target, np.array([1.0, 0.0, 0.0, 0.0])))
    np.testing.assert_allclose(entities.state("cube").pose.position, target, atol=1e-12)
    sim.step(round(0.5 / sim.control_timestep))
    np.testing.assert_allclose(entities.state("cube").pose.position, target, atol=MAX_OBJECT_DRIFT_M)
    sim.reset()  # the keyframe puts it back on the first table
    np.testing.assert_allclose(entities.state("cube").pose.position, g1_tables.object_rest_position(g1_tables.CUBE),
                               atol=1e-12)


def test_the_g1_walks_in_the_scene_its_controller_leaving_the_objects_out(robot):
    """The whole-body QP works on the robot's dofs and mass; the objects' free joints are not the robot's."""
    sim = Simulation(robot)
    walker = WalkingController(sim.model, robot.biped)
    sim.set_controller(Slot.LOCOMOTION, walker)
    start = sim.base_state().pose.position.copy()
    walker.set_velocity_command(0.0, 0.15, 0.0)  # to the left, away from both tables
    for _ in range(round(3.0 / sim.control_timestep)):
        sim.step(1)
        assert not walker.status().fallen, walker.status().message
    walker.set_velocity_command(0.0, 0.0, 0.0)
    sim.step(round(3.0 / sim.control_timestep))
    assert walker.status().mode is LocomotionMode.STANDING and walker.qp_fallback_count == 0
    assert 0.25 < sim.base_state().pose.position[1] - start[1] < 0.7
    for item in g1_tables.OBJECTS:
        rest = np.asarray(g1_tables.object_rest_position(item))
        assert np.linalg.norm(sim.body_pose(item.name).position - rest) < MAX_OBJECT_DRIFT_M


def test_an_arm_reaches_in_the_scene_its_ik_leaving_the_objects_out(robot):
    sim = Simulation(robot)
    arm = ArmController(robot)
    sim.set_controller(Slot.ARM, arm)
    sim.step(125)
    start = arm.status("right_arm").tool_pose
    arm.set_target("right_arm", Pose(start.position + np.array([0.15, 0.05, 0.15]), start.orientation_wxyz), False, 0.15, 0.5)
    for _ in range(round(6.0 / sim.control_timestep)):
        sim.step(1)
        if arm.status("right_arm").settled:
            break
    status = arm.status("right_arm")
    assert status.settled and status.position_error <= 1e-3, status


def test_in_their_palm_pose_the_hands_keep_clear_of_the_palm_pads_faces(robot):
    """The fetch squeezes with the wrist pads (robot_models.g1_palms): in the hands' palm pose no hand geom
    (the tucked thumb above all, which open stands 11 cm proud of the palm) reaches a pad's face."""
    model, data = robot.model, mujoco.MjData(robot.model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(robot.default_keyframe).id)
    assert set(robot.palm_hand_pose) == set(names.HAND_JOINTS) and set(robot.palms) == {"left_arm", "right_arm"}

    def deepest(site: str, side: str) -> float:
        """How far past the pad's face [m] (along its normal) the hand's contact geoms reach."""
        mujoco.mj_kinematics(model, data)
        face = data.site(site)
        normal = face.xmat.reshape(3, 3)[:, 2]
        reach = -np.inf
        for name, *_ in names.HAND_PADS:
            if not name.startswith(side):
                continue
            geom = model.geom(name).id
            rotation, size = data.geom_xmat[geom].reshape(3, 3), model.geom_size[geom]
            if model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_BOX:
                extent = float(np.abs(rotation.T @ normal) @ size)
            else:  # capsule: half length along its z, then its radius
                extent = abs(float(rotation[:, 2] @ normal)) * size[1] + size[0]
            reach = max(reach, float((data.geom_xpos[geom] - face.xpos) @ normal) + extent)
        return reach

    open_reach = {arm: deepest(site, arm.split("_")[0]) for arm, site in robot.palms.items()}
    assert min(open_reach.values()) > 0.03, "open, the thumbs stand past the pads"
    for joint, angle in robot.palm_hand_pose.items():
        data.qpos[model.joint(joint).qposadr[0]] = angle
    for arm, site in robot.palms.items():
        assert deepest(site, arm.split("_")[0]) < -0.01, f"{arm}: a finger or thumb reaches the pad's face"
