"""The G1 fetches the small cube (and the can) with one hand: walk, reach, close the fingers, lift, carry, place
(issue 21, items 3 and 4, in the core): the same goal as the box's, the fingers hold it by friction (no weld, no attachment)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
import pytest

import robot_models
from robot_models import g1_tables
from sim_bridge.arm import PickPlaceStage
from sim_bridge.controller import Slot
from sim_bridge.errors import InvalidGoalError
from sim_bridge.fetch import FetchGoal, FetchSkill, OneHandFetch, check_fetchable
from sim_bridge.fetch.bimanual import tilt_of
from sim_bridge.fetch.one_hand import PALM, finger_forces
from sim_bridge.fetch.rig import FetchRig
from sim_bridge.fetch.stance import edge_clearance
from sim_bridge.locomotion import LocomotionMode
from sim_bridge.navigation import grid_from_obstacles
from sim_bridge.skills import SkillStatus

PLACE = (1.02, -2.8)  # on the second table, 12 cm inside its edge facing the robot's side
MAX_SIM_S = 150.0


@dataclass
class Trace:
    stages: list[int] = field(default_factory=list)
    carried_s: float = 0.0
    min_fingers_while_carried: int = 99  # fingers (not the palm) pressing on it with 1 N at least
    min_grip_while_carried: float = math.inf
    fallen: bool = False


@pytest.fixture(scope="module")
def robot() -> robot_models.RobotSpec:
    return robot_models.load(robot_models.G1, "tables")


def _turn(robot: robot_models.RobotSpec, data: mujoco.MjData, name: str, yaw_deg: float) -> None:
    """Turn object ``name`` about the vertical to ``yaw_deg`` where it stands."""
    adr = int(robot.model.joint(name).qposadr[0])
    yaw = math.radians(yaw_deg)
    data.qpos[adr + 3:adr + 7] = [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)]
    mujoco.mj_forward(robot.model, data)


def _fetch_to_the_second_table(robot: robot_models.RobotSpec, item: g1_tables.ObjectLayout,
                               others_within_m: float = 0.01, yaw_deg: float = 0.0, arm: str = "right_arm") -> None:
    """Fetch ``item`` (turned ``yaw_deg`` where it stands) from the first table to ``PLACE`` with ``arm``'s hand and
    check the run, the grip and the placement (the other objects stay within ``others_within_m`` [m] of where they
    were)."""
    rig = FetchRig.of(robot)
    sim = rig.sim
    if yaw_deg:
        _turn(robot, sim.data, item.name, yaw_deg)
    skill = rig.skill(FetchGoal(item.name, *PLACE))
    assert isinstance(skill, OneHandFetch)
    body = sim.model.body(item.name).id
    wall = time.perf_counter()
    run = rig.legs.start(1, skill, sim.model, sim.data)
    assert skill.layout.arm == arm
    trace = Trace()
    while run.status is SkillStatus.RUNNING and sim.time < MAX_SIM_S:
        sim.step(1)
        trace.fallen = trace.fallen or rig.walker.status().fallen
        if run.status is not SkillStatus.RUNNING:
            break
        if not trace.stages or trace.stages[-1] != skill.milestone:
            trace.stages.append(skill.milestone)
        if skill.stage is PickPlaceStage.TRANSPORT:
            forces = finger_forces(sim.model, sim.data, skill.hand, body)
            trace.carried_s += sim.control_timestep
            trace.min_fingers_while_carried = min(trace.min_fingers_while_carried,
                                                  sum(1 for f, n in forces.items() if f != PALM and n >= 1.0))
            trace.min_grip_while_carried = min(trace.min_grip_while_carried, float(skill.feedback(sim.data)["grip_force"]))
    wall = time.perf_counter() - wall
    final_mode = rig.walker.status().mode
    sim.set_controller(Slot.LOCOMOTION, None)  # the legs back to their servos: the model is shared
    held = sim.data.body(item.name)
    place = np.array([*PLACE, g1_tables.PLACE_TABLE.top_z + item.half_size[2]])
    error = float(np.linalg.norm(held.xpos - place))
    print(f"one-hand fetch of the {item.name}: {run.outcome}, placed {error * 1e3:.1f} mm from the place, "
          f"{sim.time:.1f} s sim, {wall:.0f} s wall; {skill.events}")
    assert run.outcome is not None and run.status is SkillStatus.SUCCEEDED, (run.outcome, skill.events)
    assert error <= 0.02, f"placed {error * 1e3:.1f} mm from the place"
    assert math.degrees(tilt_of(held.xquat)) < 3.0, f"the {item.name} rests level"
    assert run.final_result is not None and run.final_result["placement_error"] == pytest.approx(error, abs=2e-3)
    assert not trace.fallen and final_mode is LocomotionMode.STANDING
    assert trace.stages == [int(stage) for stage in PickPlaceStage], skill.events
    assert run.final_feedback is not None and run.final_feedback["stage_name"] == "RETREAT"
    assert trace.carried_s > 5.0, "carried while walking to the second table"
    assert trace.min_fingers_while_carried >= 2, "the thumb and a finger pressed on it all the way (friction only)"
    assert trace.min_grip_while_carried > 5.0
    forces = finger_forces(sim.model, sim.data, skill.hand, body)
    assert max(forces[f] for f in skill.layout.fingers) == 0.0, "the fingers let go"
    for other in (o for o in g1_tables.OBJECTS if o.name != item.name):  # the other objects stay where they were
        rest = np.asarray(g1_tables.object_rest_position(other))
        assert np.linalg.norm(sim.body_pose(other.name).position - rest) < others_within_m, other.name


def test_the_g1_fetches_the_cube_to_the_second_table_with_one_hand(robot: robot_models.RobotSpec) -> None:
    _fetch_to_the_second_table(robot, g1_tables.CUBE)


def test_the_g1_fetches_the_can_turned_with_the_left_hand(robot: robot_models.RobotSpec) -> None:
    """The 12 cm can stands taller than the cube: the palm tilts less (``OneHandConfig.tall_palm_tilt_rad``), or its
    upper edge tips the can in the hand. Turned -20 degrees the stance turns with it, and the left hand takes it: the
    stance then stands to the can's right, away from the table (to its left, the right hand's, it came 3.4 cm nearer
    the edge). Reaching for it the robot may brush the box beside it (on the table)."""
    _fetch_to_the_second_table(robot, g1_tables.CAN, others_within_m=0.02, yaw_deg=-20.0, arm="left_arm")


def test_small_objects_go_to_one_hand_the_box_to_both_palms(robot: robot_models.RobotSpec) -> None:
    rig = FetchRig.of(robot)
    assert isinstance(rig.skill(FetchGoal("can", *PLACE)), OneHandFetch)
    box = rig.skill(FetchGoal("box", *PLACE))
    assert isinstance(box, FetchSkill) and not isinstance(box, OneHandFetch)


def test_what_one_hand_cannot_take_is_refused_with_the_reason(robot: robot_models.RobotSpec) -> None:
    without_hands = replace(robot, hands={})
    with pytest.raises(InvalidGoalError, match=r"wide across its grip axis.*no hand to grasp with"):
        check_fetchable(without_hands, "cube", 25.0)
    cube = robot.model.body("cube").id
    mass = float(robot.model.body_mass[cube])
    robot.model.body_mass[cube] = 0.8
    try:
        with pytest.raises(InvalidGoalError, match="too heavy for one hand"):
            check_fetchable(robot, "cube", 25.0)
    finally:
        robot.model.body_mass[cube] = mass
    rig = FetchRig.of(robot)
    with pytest.raises(InvalidGoalError, match="does not keep 'cube' whole on a table top"):
        rig.skill(FetchGoal("cube", 0.0, -2.8)).start(rig.sim.model, rig.sim.data)
    adr = int(robot.model.joint("cube").qposadr[0])
    rig.sim.data.qpos[adr:adr + 3] = [0.5, 1.5, g1_tables.CUBE.half_size[2]]  # on the floor
    mujoco.mj_forward(rig.sim.model, rig.sim.data)
    with pytest.raises(InvalidGoalError, match="does not rest upright on a table top"):
        rig.skill(FetchGoal("cube", *PLACE)).start(rig.sim.model, rig.sim.data)
    run = rig.legs.start(2, rig.skill(FetchGoal("cube", *PLACE)), rig.sim.model, rig.sim.data)
    assert run.status is SkillStatus.ABORTED and run.outcome is not None and run.outcome.code == "INVALID_GOAL"
    rig.sim.set_controller(Slot.LOCOMOTION, None)


def test_a_turned_cube_gets_a_stance_turned_with_it_and_the_hand_that_keeps_clear_of_the_table(
        robot: robot_models.RobotSpec) -> None:
    # The stance stands 10 cm to the side away from the hand. Turned with the cube, that side runs toward the table's
    # edge or away from it: turned -25 degrees, the right hand's stance came 4 cm nearer the edge and the legs met
    # the table; the left hand's stands as far out as the right hand's does for +25. Turned 40 degrees (50 the other
    # way, a quarter turn being the same grip) the stance turns 40.
    rig = FetchRig.of(robot)
    first = robot.obstacles[0]

    def started(name: str, yaw_deg: float, arm: str | None = None) -> OneHandFetch:
        _turn(robot, rig.sim.data, name, yaw_deg)
        skill = OneHandFetch(robot, rig.walker, rig.arms, grid_from_obstacles(robot.obstacles), FetchGoal(name, *PLACE),
                             arm=arm)
        skill.start(rig.sim.model, rig.sim.data)
        assert skill.plan is not None
        return skill

    try:
        plain = started("cube", 0.0)
        assert plain.layout.arm == "right_arm" and plain.plan.pick.yaw == pytest.approx(0.0)  # a tie: the right hand
        toward, away = started("cube", 25.0), started("cube", -25.0)
        assert toward.plan.pick.yaw == pytest.approx(math.radians(25.0))
        assert away.plan.pick.yaw == pytest.approx(math.radians(-25.0))
        assert (toward.layout.arm, away.layout.arm) == ("right_arm", "left_arm")
        right_hand = started("cube", -25.0, arm="right_arm")
        clear = {name: edge_clearance(first, s.plan.pick.x, s.plan.pick.y)
                 for name, s in (("left", away), ("right", right_hand))}
        assert clear["left"] > clear["right"] + 0.03, clear
        assert edge_clearance(first, toward.plan.pick.x, toward.plan.pick.y) == pytest.approx(clear["left"], abs=0.02)
        assert started("cube", 40.0).plan.pick.yaw == pytest.approx(math.radians(40.0))
        assert started("cube", 50.0).plan.pick.yaw == pytest.approx(math.radians(-40.0))
    finally:
        mujoco.mj_resetDataKeyframe(rig.sim.model, rig.sim.data, rig.sim.model.key(robot.default_keyframe).id)
        rig.sim.set_controller(Slot.LOCOMOTION, None)
