"""The G1's Dex3-1 hands: actuated joints, position servos that open and close them, contact geoms for grasping."""

from __future__ import annotations

import mujoco
import pytest

import robot_models
from robot_models import g1_constants as names
from sim_bridge import Simulation, Slot
from sim_bridge.locomotion import WalkingController

SETTLE_S = 0.5  # a finger settles in about 0.1 s
POSE_TOLERANCE_RAD = 0.03


@pytest.fixture(scope="module")
def g1() -> robot_models.RobotSpec:
    return robot_models.load(robot_models.G1)


def _hand_angles(sim: Simulation) -> dict[str, float]:
    return {joint: float(sim.data.qpos[sim.model.joint(joint).qposadr[0]]) for joint in names.HAND_JOINTS}


def _worst_error(sim: Simulation, pose: dict[str, float]) -> float:
    angles = _hand_angles(sim)
    return max(abs(angles[joint] - target) for joint, target in pose.items())


def test_the_hand_joints_are_actuated_joints_in_their_own_groups(g1):
    assert len(names.LEFT_HAND_JOINTS) == len(names.RIGHT_HAND_JOINTS) == 7, "thumb 3, middle 2, index 2"
    assert set(names.HAND_JOINTS) <= set(g1.actuated_joints)
    assert g1.joint_groups["left_hand"] == names.LEFT_HAND_JOINTS
    assert g1.joint_groups["right_hand"] == names.RIGHT_HAND_JOINTS
    body = names.BODY_JOINTS
    assert g1.actuated_joints[: len(body)] == body, "the hands' actuators come after the body's"
    assert g1.actuated_joints[-1] == names.HEAD_CAMERA_TILT_JOINT
    for index, joint in enumerate(g1.actuated_joints):
        assert g1.model.actuator(index).name == joint, "actuated joints are in actuator order"
    for joint in names.HAND_JOINTS:
        low, high = g1.model.actuator(joint).forcerange
        assert high == -low == g1.joint_limits[joint].effort > 0.0, "a squeeze bounded by the URDF effort limit"
        for pose in (names.HAND_OPEN_POSE, names.HAND_CLOSED_POSE):
            assert g1.joint_limits[joint].lower <= pose[joint] <= g1.joint_limits[joint].upper, joint
    key = g1.model.key(names.STAND_KEYFRAME)
    for joint in names.HAND_JOINTS:
        assert key.qpos[g1.model.joint(joint).qposadr[0]] == names.HAND_OPEN_POSE[joint], "the stand has the hands open"


def test_a_standing_g1_closes_and_opens_its_hands(g1):
    sim = Simulation(g1)
    sim.step(round(SETTLE_S / sim.control_timestep))
    pelvis_z = sim.base_state().pose.position[2]
    assert _worst_error(sim, names.HAND_OPEN_POSE) < POSE_TOLERANCE_RAD, "the servos hold the hands open"
    open_angles = _hand_angles(sim)

    sim.servo.set_targets(names.HAND_CLOSED_POSE)
    sim.step(round(SETTLE_S / sim.control_timestep))
    assert _worst_error(sim, names.HAND_CLOSED_POSE) < POSE_TOLERANCE_RAD, _hand_angles(sim)
    closed_angles = _hand_angles(sim)
    moved = [joint for joint in names.HAND_JOINTS if abs(closed_angles[joint] - open_angles[joint]) > 0.5]
    assert len(moved) == 12, "every finger joint but the thumbs' swing travels more than 0.5 rad"

    sim.servo.set_targets(names.HAND_OPEN_POSE)
    sim.step(round(SETTLE_S / sim.control_timestep))
    assert _worst_error(sim, names.HAND_OPEN_POSE) < POSE_TOLERANCE_RAD, _hand_angles(sim)
    assert abs(sim.base_state().pose.position[2] - pelvis_z) < 0.005, "it stood still meanwhile"


def test_the_hands_hold_their_pose_while_walking(g1):
    sim = Simulation(g1)
    walker = WalkingController(sim.model, g1.biped)
    sim.set_controller(Slot.LOCOMOTION, walker)
    walker.set_velocity_command(0.5, 0.0, 0.0)
    worst = 0.0
    try:
        for _ in range(round(3.0 / sim.control_timestep)):
            sim.step(1)
            worst = max(worst, _worst_error(sim, names.HAND_OPEN_POSE))
        assert not walker.status().fallen and sim.base_state().pose.position[0] > 1.0, "it walked on"
    finally:
        sim.reset()  # the walker gives the shared model's leg actuators back to their servos
    assert worst < POSE_TOLERANCE_RAD


def test_a_hand_squeezing_past_its_limits_pushes_with_its_force_limit_at_most(g1):
    sim = Simulation(g1)
    beyond = {joint: 3.0 * angle for joint, angle in names.HAND_CLOSED_POSE.items()}  # past the joint limits
    sim.servo.set_targets(beyond)
    sim.step(round(SETTLE_S / sim.control_timestep))
    for joint in names.HAND_JOINTS:
        if beyond[joint] == 0.0:
            continue
        force = float(sim.data.actuator_force[sim.model.actuator(joint).id])
        assert abs(force) == pytest.approx(g1.joint_limits[joint].effort), joint


def test_the_hand_pads_are_grasp_contacts_that_touch_nothing_while_standing(g1):
    sim = Simulation(g1)
    model = sim.model
    pads = {model.geom(name).id for name, *_ in names.HAND_PADS}
    assert len(pads) == 14, "a palm and six finger links per hand"
    for pad in pads:
        assert model.geom_condim[pad] == 4 and model.geom_friction[pad][0] >= 1.0
        assert model.geom_solref[pad][0] <= 2 * model.opt.timestep + 1e-12, "stiff contacts on light links"
        assert model.geom_contype[pad] == names.HAND_CONTYPE and model.geom_conaffinity[pad] == 1
    box = names.HAND_CONTYPE | 1  # an object that collides with the hands and the floor
    assert all(model.geom_contype[pad] & box or model.geom_conaffinity[pad] & box for pad in pads)
    shell = [model.geom(name).id for name, *_ in names.BODY_SHELL]
    assert not any(model.geom_contype[pad] & model.geom_conaffinity[s] or model.geom_contype[s] & model.geom_conaffinity[pad]
                   for pad in pads for s in shell), "the pads never touch the body shell"
    sim.servo.set_targets(names.HAND_CLOSED_POSE)
    sim.step(round(SETTLE_S / sim.control_timestep))
    contacts = sim.data.contact[: sim.data.ncon]
    touching = {int(c.geom1) for c in contacts} | {int(c.geom2) for c in contacts}
    assert not touching & pads
    floor = model.geom(names.FLOOR_GEOM).id
    for pad in pads:
        assert mujoco.mj_geomDistance(model, sim.data, pad, floor, 1.0, None) > 0.3, "the hands are far above the floor"
