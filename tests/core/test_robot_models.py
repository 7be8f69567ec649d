"""Every registered robot compiles and holds its keyframe under gravity."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest

import robot_models
from robot_models import g1_constants as g1_names, panda_constants as panda_names
from robot_models.validation import check_range, is_number
from sim_bridge import Simulation
from sim_bridge.arm import ArmKinematics
from sim_bridge.errors import SimError

HOLD_SECONDS = 10.0
MAX_BASE_DRIFT_M = 0.02  # horizontal drift of the base over HOLD_SECONDS
MAX_HEIGHT_LOSS_M = 0.02
MAX_JOINT_DRIFT_RAD = 0.05


@pytest.mark.parametrize("name", robot_models.ROBOT_NAMES)
def test_robot_holds_its_keyframe_for_ten_seconds(name):
    robot = robot_models.load(name)
    sim = Simulation(robot)
    start = sim.snapshot()
    sim.step(round(HOLD_SECONDS / sim.control_timestep))
    end = sim.snapshot()
    assert sim.time == pytest.approx(HOLD_SECONDS, abs=1e-6)
    assert np.all(np.isfinite(sim.data.qpos)) and np.all(np.isfinite(sim.data.qvel))
    drift = np.linalg.norm(end.base.pose.position[:2] - start.base.pose.position[:2])
    assert drift < MAX_BASE_DRIFT_M
    assert start.base.pose.position[2] - end.base.pose.position[2] < MAX_HEIGHT_LOSS_M
    assert np.abs(end.joint_positions - start.joint_positions).max() < MAX_JOINT_DRIFT_RAD


def test_g1_has_a_floating_base_and_real_soles():
    robot = robot_models.load("g1")
    model = robot.model
    assert robot.floating_base
    free = model.body(robot.base_body).jntadr[0]
    assert model.jnt_type[free] == mujoco.mjtJoint.mjJNT_FREE
    assert model.nu == 44 and len(robot.actuated_joints) == 44, "29 body joints, 14 hand joints, the camera's tilt mount"
    sole = model.geom("left_sole_box")
    width = 2 * sole.size[1]
    assert sole.type == mujoco.mjtGeom.mjGEOM_BOX and width >= 0.06, "a sole as wide as a real foot"
    colliding = [model.geom(i).name for i in range(model.ngeom) if model.geom_contype[i] or model.geom_conaffinity[i]]
    shell = sorted(name for name, *_ in g1_names.BODY_SHELL)
    pads = [name for name, *_ in g1_names.HAND_PADS]
    assert sorted(colliding) == sorted(["floor", "left_sole_box", "right_sole_box", *shell, *pads]), "no mesh collides"
    soles_and_floor = [model.geom(name).id for name in ("floor", "left_sole_box", "right_sole_box")]
    assert all(model.geom_contype[i] == 1 for i in soles_and_floor)
    assert all(model.geom_contype[model.geom(name).id] == g1_names.SHELL_CONTYPE and
               model.geom_conaffinity[model.geom(name).id] == 0 for name in shell), "the shell touches no body part"


def test_a_shoved_g1_falls_and_lies_on_the_floor_without_sinking_into_it():
    sim = Simulation(robot_models.load("g1"))
    sim.step(50)
    sim.push("pelvis", (0.0, 400.0, 0.0), (0.0, 0.0, 0.0), 0.5)
    sim.step(int(4.0 / sim.control_timestep))
    z = sim.data.xpos[1:, 2]  # every body's origin
    pelvis = sim.data.xpos[sim.model.body("pelvis").id, 2]
    assert pelvis < 0.3, "it fell"
    assert z.min() > 0.0 and pelvis > 0.05, "it lies on the floor, not in it"
    shell = {sim.model.geom(name).id for name, *_ in g1_names.BODY_SHELL}
    contacts = sim.data.contact[: sim.data.ncon]
    touching = {int(c.geom1) for c in contacts} | {int(c.geom2) for c in contacts}
    assert touching & shell, "the body shell carries it"


def test_g1_body_shell_touches_nothing_while_standing():
    sim = Simulation(robot_models.load("g1"))
    sim.step(50)
    floor = sim.model.geom(g1_names.FLOOR_GEOM).id
    for name, *_ in g1_names.BODY_SHELL:
        geom = sim.model.geom(name).id
        assert mujoco.mj_geomDistance(sim.model, sim.data, geom, floor, 1.0, None) > 0.08, name
    soles = {sim.model.geom(g1_names.LEFT_SOLE_GEOM).id, sim.model.geom(g1_names.RIGHT_SOLE_GEOM).id}
    for contact in sim.data.contact[: sim.data.ncon]:
        assert {int(contact.geom1), int(contact.geom2)} - {floor} <= soles


def test_panda_scene_has_grasp_settings_and_boxes():
    robot = robot_models.load("panda")
    model = robot.model
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and model.opt.impratio >= 10
    assert robot.objects == ("box_0", "box_1", "box_2")
    for name in robot.objects:
        assert model.geom(name).condim == 4
    assert model.neq == 0, "both fingers are actuated; no mimic equality"
    assert model.actuator("panda_finger_joint1").id >= 0 and model.actuator("panda_finger_joint2").id >= 0


def test_unknown_robot_lists_known_names():
    with pytest.raises(robot_models.UnknownRobotError, match="g1, panda"):
        robot_models.load("atlas")
    for lookup in (robot_models.sensors_of, robot_models.cameras_of):
        with pytest.raises(robot_models.UnknownRobotError, match="g1, panda"):
            lookup("atlas")


def test_the_registry_names_each_robot_and_knows_its_cameras_without_building_it():
    assert robot_models.ROBOT_NAMES == tuple(sorted((robot_models.G1, robot_models.PANDA)))
    for name in robot_models.ROBOT_NAMES:
        robot = robot_models.load(name, "")  # "" = the default scene, as None
        assert robot.name == name
        assert robot_models.cameras_of(name) == robot.cameras


def test_check_range_takes_numbers_only_and_says_what_is_allowed():
    check_range("x", np.float32(0.5), 0, 1)  # NumPy scalars are numbers
    check_range("x", 1, 0, 1)
    for bad in (-0.1, 1.5, math.nan, math.inf, True, "0.5", None, 10**400):
        with pytest.raises(ValueError, match=r"^x must be a finite number in \[0, 1\] m, got "):
            check_range("x", bad, 0, 1, unit="m")
    with pytest.raises(ValueError, match=r"a finite number > 0, got 0"):
        check_range("y", 0, 0, low_open=True)
    with pytest.raises(KeyError, match=r"a finite number in \(0, 180\) deg"):
        check_range("fovy", 180.0, 0, 180, low_open=True, high_open=True, unit="deg", error=KeyError)
    assert is_number(np.int64(3)) and not is_number(np.bool_(True)) and not is_number(math.nan)


def test_g1_course_scene_has_static_obstacles_and_unknown_scenes_are_refused():
    course = robot_models.load("g1", "course")
    assert course.scene == "course" and len(course.obstacles) >= 3
    for obstacle in course.obstacles:
        assert course.model.geom(obstacle.name).contype == 1
    assert robot_models.load("g1").obstacles == ()
    with pytest.raises(robot_models.UnknownSceneError, match="open, course"):
        robot_models.load("g1", "moon")


def test_skill_limits_live_on_the_spec():
    g1, panda = robot_models.load("g1"), robot_models.load("panda")
    assert g1.walking is not None and panda.walking is None, "only the legged robot walks"
    assert g1.walking.speed_range_mps == (0.05, 0.8)
    assert g1.walking.speed_range_mps[0] <= g1.walking.default_speed_mps <= g1.walking.speed_range_mps[1]
    assert g1.walking.max_walk_distance_m == 100.0
    assert g1.walking.fall_height_m == 0.45
    assert g1.walking.fall_tilt_rad == pytest.approx(math.radians(50.0))
    assert panda.grasp is not None and g1.grasp is None, "only the Panda has grippers"
    assert panda.grasp.max_force_n == 70.0
    assert 0.0 < panda.grasp.default_force_n <= panda.grasp.max_force_n
    for finger in panda.arm_scene.grippers["arm"]:
        assert panda.model.actuator(finger).forcerange[1] == panda.grasp.max_force_n, "the actuators' force limit"
    with pytest.raises(ValueError, match="default <= high"):
        robot_models.WalkingLimits(speed_range_mps=(0.05, 0.6), default_speed_mps=0.8, max_walk_distance_m=1.0,
                                   fall_height_m=0.4, fall_tilt_rad=1.0)
    with pytest.raises(ValueError, match="default <= max"):
        robot_models.GraspLimits(max_force_n=10.0, default_force_n=20.0)


def test_arm_facts_live_on_the_spec():
    panda = robot_models.load("panda")
    assert panda.arm_scene.grippers == {"arm": panda_names.FINGER_JOINTS}
    assert panda.arm_scene.gripper_open_width == pytest.approx(2 * panda_names.FINGER_OPEN)
    assert panda.arm_scene.obstacle_geoms == (panda_names.TABLE_GEOM,)
    assert panda.arm_scene.objects_table_top_z == panda_names.TABLE_TOP_Z
    assert panda.arm_scene.object_half_size == panda_names.BOX_HALF_SIZE
    assert panda.arm_scene.table_xy_bounds == pytest.approx((0.0, 0.9, -0.55, 0.55))
    g1 = robot_models.load("g1")
    assert g1.arm_scene.grippers == {} and g1.arm_scene.make_visuals_collide
    must_avoid = {g1_names.ROOT_BODY, g1_names.TORSO_BODY, "left_knee_link", "right_ankle_roll_link"}
    assert must_avoid <= set(g1.arm_scene.obstacle_bodies)
    with pytest.raises(ValueError, match="no grasp limits"):
        dataclasses.replace(panda, grasp=None)


@pytest.mark.parametrize("name", robot_models.ROBOT_NAMES)
def test_the_registry_s_facts_agree_with_every_built_scene(name):
    """bringup decides from the registry without building a model: its facts must be the built spec's."""
    from robot_models.registry import entry_of

    entry = entry_of(name)
    for scene in entry.scenes:
        robot_models.check_scene(name, scene)
        spec = robot_models.load(name, scene)
        assert spec.scene == scene
        assert robot_models.walks(name) == (spec.walking is not None and bool(spec.feet_sites))
        assert robot_models.sensors_of(name) == spec.sensors
        assert robot_models.cameras_of(name) == spec.cameras
    with pytest.raises(robot_models.UnknownSceneError, match="scenes: "):
        robot_models.check_scene(name, "no_such_scene")


def test_a_light_model_has_the_robot_s_kinematics_and_masses_without_its_meshes():
    full = robot_models.load("g1", "tables")
    light = robot_models.load("g1", "tables", visuals=False)
    assert full.visuals and not light.visuals
    assert light.model.nmesh == 0 < full.model.nmesh
    assert light.model.nbuffer < full.model.nbuffer / 100  # the meshes and their bounding volume trees
    for array in ("body_pos", "body_quat", "body_mass", "body_inertia", "body_ipos", "body_iquat", "jnt_qposadr",
                  "jnt_range", "site_pos", "key_qpos", "key_ctrl", "actuator_gainprm", "sensor_adr"):
        assert np.array_equal(getattr(full.model, array), getattr(light.model, array)), array
    for kind, count in ((mujoco.mjtObj.mjOBJ_BODY, "nbody"), (mujoco.mjtObj.mjOBJ_JOINT, "njnt"),
                        (mujoco.mjtObj.mjOBJ_SITE, "nsite"), (mujoco.mjtObj.mjOBJ_CAMERA, "ncam")):
        names = [mujoco.mj_id2name(full.model, kind, i) for i in range(getattr(full.model, count))]
        assert names == [mujoco.mj_id2name(light.model, kind, i) for i in range(getattr(light.model, count))]
    colliding = [full.model.geom(g).name for g in range(full.model.ngeom)
                 if full.model.geom_contype[g] or full.model.geom_conaffinity[g]]
    assert colliding == [light.model.geom(g).name for g in range(light.model.ngeom)]
    assert full.mjspec.meshes, "the spec keeps naming the meshes; only the light model goes without them"


def test_the_arms_ik_refuses_a_light_model_whose_visual_meshes_it_keeps_away_from():
    with pytest.raises(SimError, match="without its visual meshes"):
        ArmKinematics(robot_models.load("g1", visuals=False))
    assert ArmKinematics(robot_models.load("panda", visuals=False)).arms  # the Panda's IK avoids collision geoms
