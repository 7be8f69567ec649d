"""The standing G1 picks the small cube with its right hand, holds it up by friction, and puts it back (issue 21,
items 3 and 6, in the core): fingers close until they touch; no weld, no attachment."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import pytest

import robot_models
from robot_models import g1_tables
from robot_models.g1_grasp import HANDS
from sim_bridge.arm import PickPlaceStage
from sim_bridge.controller import Slot
from sim_bridge.fetch.bimanual import tilt_of
from sim_bridge.fetch.one_hand import PALM, finger_forces, grasp_rotation, hand_of, ready_tool_pose
from sim_bridge.fetch.one_hand_pick import OneHandConfig, OneHandGoal, OneHandPick
from sim_bridge.fetch.rig import FetchRig
from sim_bridge.skills import SkillRun, SkillStatus

ARM = "right_arm"
# The stance for the right hand: the pelvis this far behind the object and to its left [m] (the palm faces left).
PELVIS_BEHIND_M = 0.18
PELVIS_LEFT_M = 0.10
MAX_SIM_S = 40.0
OTHER_SHOULDER_PITCH_RAD = 0.4


@dataclass
class Held:
    """What was measured while the object was up (stage TRANSPORT)."""

    seconds: float = 0.0
    min_rise_m: float = math.inf
    min_grip_n: float = math.inf
    min_fingers: int = 99  # fingers (not the palm) pressing on it with 1 N at least


@pytest.fixture(scope="module")
def robot() -> robot_models.RobotSpec:
    return robot_models.load(robot_models.G1, "tables")


def grip_yaw(yaw: float) -> float:
    """The heading [rad] that faces the object's face nearest the world's x axis (a cube turned by ``yaw`` [rad])."""
    quarter = math.pi / 2
    return yaw - quarter * round(yaw / quarter)


def stand_at(rig: FetchRig, name: str, xy: tuple[float, float], yaw: float,
             stance_error: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
    """Put the object at ``xy`` [m] turned by ``yaw`` [rad], the robot at its stance facing the object's face
    (off by ``stance_error``: forward [m], left [m], turn [rad]) with the right hand raised above the table
    (joints and servo targets), balancing on the walker."""
    sim, model, data = rig.sim, rig.sim.model, rig.sim.data
    adr = int(model.joint(name).qposadr[0])
    data.qpos[adr:adr + 2] = xy
    data.qpos[adr + 3:adr + 7] = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
    heading = grip_yaw(yaw)
    forward, left = np.array([math.cos(heading), math.sin(heading)]), np.array([-math.sin(heading), math.cos(heading)])
    ahead, aside, turn = stance_error
    base = int(model.joint(model.body_jntadr[model.body(rig.robot.base_body).id]).qposadr[0])
    data.qpos[base:base + 2] = np.asarray(xy) + (ahead - PELVIS_BEHIND_M) * forward + (aside + PELVIS_LEFT_M) * left
    data.qpos[base + 3:base + 7] = [math.cos((heading + turn) / 2), 0.0, 0.0, math.sin((heading + turn) / 2)]
    mujoco.mj_forward(model, data)
    hand = hand_of(model, HANDS[ARM])
    rotation = grasp_rotation(hand, yaw, heading + turn, OneHandConfig().palm_tilt_rad)
    ready = ready_tool_pose(hand, data.body(name).xpos, rotation, back_m=0.12, rise_m=0.08)
    solution = rig.arms.kinematics.solve(ARM, data.qpos.copy(), ready, False)
    for joint, angle in zip(solution.joint_names, solution.positions, strict=True):
        data.qpos[model.joint(joint).qposadr[0]] = data.ctrl[model.actuator(joint).id] = angle
    # The other hand hangs level with the table top's underside at the stance: swing it back, clear of the table.
    shoulder = "left_shoulder_pitch_joint"
    data.qpos[model.joint(shoulder).qposadr[0]] = data.ctrl[model.actuator(shoulder).id] = OTHER_SHOULDER_PITCH_RAD
    mujoco.mj_forward(model, data)
    rig.walker.hold_balance(True)
    sim.step(round(0.5 / sim.control_timestep))


@dataclass
class Picked:
    """A pick run to its end."""

    rig: FetchRig
    skill: OneHandPick
    run: SkillRun
    held: Held
    fallen: bool
    rest: np.ndarray  # where the object rested before, world [m]


def pick(robot: robot_models.RobotSpec, name: str, xy: tuple[float, float], yaw: float = 0.0,
         stance_error: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Picked:
    """Stand at the object, pick it with the right hand, hold it up, put it back; measure while it is up."""
    rig = FetchRig.of(robot)
    stand_at(rig, name, xy, yaw, stance_error)
    sim = rig.sim
    rest = sim.data.body(name).xpos.copy()
    skill = OneHandPick(rig.walker, rig.arms, HANDS[ARM], OneHandGoal(name))
    run = rig.legs.start(1, skill, sim.model, sim.data)
    held, fallen = Held(), False
    hand = skill.hand
    body = sim.model.body(name).id
    while run.status is SkillStatus.RUNNING and sim.time < MAX_SIM_S:
        sim.step(1)
        fallen = fallen or rig.walker.status().fallen
        if skill.stage is PickPlaceStage.TRANSPORT:
            forces = finger_forces(sim.model, sim.data, hand, body)
            held.seconds += sim.control_timestep
            held.min_rise_m = min(held.min_rise_m, float(sim.data.body(name).xpos[2] - rest[2]))
            held.min_grip_n = min(held.min_grip_n, sum(forces.values()))
            held.min_fingers = min(held.min_fingers, sum(1 for f, n in forces.items() if f != PALM and n >= 1.0))
    rig.sim.set_controller(Slot.LOCOMOTION, None)  # the legs back to their servos: the model is shared
    return Picked(rig, skill, run, held, fallen, rest)


@pytest.fixture(scope="module")
def cube_picked(robot: robot_models.RobotSpec) -> Picked:
    return pick(robot, "cube", g1_tables.CUBE.xy)


def test_the_g1_lifts_the_cube_with_one_hand_holds_it_and_puts_it_back(cube_picked: Picked) -> None:
    rig, skill, run, held, fallen, rest = (cube_picked.rig, cube_picked.skill, cube_picked.run, cube_picked.held,
                                           cube_picked.fallen, cube_picked.rest)
    assert run.status is SkillStatus.SUCCEEDED, (run.outcome, skill.events)
    assert not fallen
    assert held.min_rise_m >= 0.05, f"held up only {held.min_rise_m * 1e3:.0f} mm"
    assert held.seconds >= 3.0
    assert held.min_fingers >= 2, "the thumb and a finger pressed on it all the time (friction only)"
    assert held.min_grip_n > 10.0
    cube = rig.sim.data.body("cube")
    error = float(np.linalg.norm(cube.xpos - rest))
    assert error <= 0.02, f"put down {error * 1e3:.1f} mm from where it was"
    assert math.degrees(tilt_of(cube.xquat)) < 3.0, "it rests flat"
    assert run.final_result is not None and run.final_result["placement_error"] == pytest.approx(error, abs=2e-3)
    forces = finger_forces(rig.sim.model, rig.sim.data, skill.hand, rig.sim.model.body("cube").id)
    assert max(forces[f] for f in HANDS[ARM].fingers) == 0.0, "the fingers let go"


def test_the_one_hand_pick_reports_its_stages_in_order(cube_picked: Picked) -> None:
    skill, run = cube_picked.skill, cube_picked.run
    stages = [event.split()[1] for event in skill.events]
    assert stages == sorted(stages, key=lambda name: PickPlaceStage[name]), skill.events
    assert set(stages) == {stage.name for stage in PickPlaceStage}
    assert run.final_feedback is not None and run.final_feedback["stage_name"] == "RETREAT"


def test_a_pick_of_an_unknown_object_is_refused(robot: robot_models.RobotSpec) -> None:
    rig = FetchRig.of(robot)
    run = rig.legs.start(2, OneHandPick(rig.walker, rig.arms, HANDS[ARM], OneHandGoal("ball")), rig.sim.model, rig.sim.data)
    assert run.status is SkillStatus.ABORTED and run.outcome is not None and "ball" in run.outcome.message
    rig.sim.set_controller(Slot.LOCOMOTION, None)
