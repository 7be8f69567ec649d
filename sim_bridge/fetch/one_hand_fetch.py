"""Fetch a small object with one hand: the box fetch's walks, alignment and carry, with the fingers' grasp.

:class:`OneHandFetch` is a :class:`~sim_bridge.fetch.skill.FetchSkill` whose grasp is one hand's
(:mod:`sim_bridge.fetch.one_hand`): the walk to the stance, the turn and the steps onto it, the step back,
the carry to the place and the steps onto its stance are the box fetch's own phases; the phases at the
object and at the place are the hand's. The stances stand ``hand_side_m`` to the side of the object, away
from the hand (:func:`~sim_bridge.fetch.goal.plan_fetch` with a hand). The stages are PickPlace's:

- APPROACH: navigate to the point behind the stance, turn to its heading; the hand opens and rises ready (its
  grasp pose ``READY_BACKS_M`` back (the first the arm reaches), ``READY_RISE_M`` up and ``approach_m`` out
  along the palm normal, carried with the robot: the hand passes beside the object), the other arm swings back
  clear of the table (its first joint, the shoulder's pitch, to ``OTHER_ARM_SWING_RAD``, by its servo); walk onto the
  stance;
- DESCEND: the hand beside the object (out along the palm normal and up), then in until the object's centre
  is at the hand's grasp point;
- GRASP: the fingers close until each touches (:class:`~sim_bridge.fetch.one_hand.FingerCloser`); the grasp
  is made when the thumb and another finger press on it for ``grasp_settle_s``;
- LIFT: up by the goal's lift height;
- TRANSPORT: the arm holds its joints; step back, navigate to the place's approach, walk onto its stance;
- PLACE: the object over the place, then down until the table carries it;
- RELEASE: the fingers open;
- RETREAT: the hand backs out along the palm normal and up, the robot steps back; the placement is measured.

Failures are the box fetch's: FELL, OBJECT_DROPPED (the thumb and a finger no longer hold it while lifted,
carried or placed), GRASP_FAILED, UNREACHABLE, PLACEMENT_FAILED, TIMEOUT. Cancel: the robot stops, stands
and keeps holding what the fingers hold (their servo targets stay); a later fetch of an object the hand
holds goes straight to the place.

The hand: the one that holds the object already; else the one whose stance keeps the body farther from the
table (the stance stands to the side away from the hand, and turned with the object that side may run toward
the table's edge); on a tie the right one when the robot has it (the hand the standing pick was measured with,
tests/core/test_one_hand.py), else the robot's first.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from robot_models import RobotSpec
from sim_bridge.arm import ArmController, PickPlaceStage
from sim_bridge.arm.poses import quat_to_mat
from sim_bridge.arm.types import ArmMode
from sim_bridge.errors import InvalidGoalError
from sim_bridge.fetch.bimanual import yaw_matrix, yaw_of
from sim_bridge.fetch.goal import NAVIGATION_INFLATION_M, FetchGoal, for_one_hand, plan_fetch
from sim_bridge.fetch.grip import GripConfig
from sim_bridge.fetch.one_hand import (
    PALM,
    FingerCloser,
    finger_forces,
    grasp_rotation,
    grasp_tool_pose,
    hand_of,
    holds,
    ready_tool_pose,
)
from sim_bridge.fetch.one_hand_pick import HandMoves, OneHandConfig
from sim_bridge.fetch.skill import FetchSkill
from sim_bridge.fetch.stance import StanceConfig, edge_clearance
from sim_bridge.locomotion import WalkingController
from sim_bridge.navigation import OccupancyGrid
from sim_bridge.skills.base import SkillOutcome, Values
from sim_bridge.skills.locomotion import NavigateGoal, NavigateSkill

Stage = PickPlaceStage
READY_BACKS_M = (0.12, 0.09, 0.06, 0.03, 0.0)  # the ready hand: its grasp pose this far back against the fingers [m]
READY_RISE_M = 0.08  # ... and this far up, clear above the table top [m]
OTHER_ARM_SWING_RAD = 0.4  # the other arm's first joint (the G1's shoulder pitch): swung back, clear of the table
PREFERRED_HAND = "right_arm"
HAND_CLEARANCE_TIE_M = 0.01  # the other hand only when its stance stands this much farther from the table [m]
HAND_ALIGN_TOLERANCE_M = 0.015  # the steps onto a stance end this close to it [m]
HAND_PHASES = ("align_pick", "beside", "reach", "close", "lift", "align_place", "over_place", "lower", "release",
               "retreat")
MOVES = ("beside", "reach", "lift", "over_place", "retreat")  # phases that end when the hand arrives


class OneHandFetch(FetchSkill, HandMoves):
    """The fetch of a small object with one hand (see the module). A skill for the legs' host.

    Args:
        robot, walker, arms, grid, goal, stance, grip: as :class:`FetchSkill`'s (``grip``: the walks' and
            alignment's settings; by default aligned within ``HAND_ALIGN_TOLERANCE_M``).
        hand_config: how the hand moves and closes.
        arm: the hand's arm (a key of ``robot.hands``); None: the right one, or the first.

    Raises:
        InvalidGoalError: the robot has no such hand.
    """

    def __init__(self, robot: RobotSpec, walker: WalkingController, arms: ArmController, grid: OccupancyGrid,
                 goal: FetchGoal, stance: StanceConfig | None = None, grip: GripConfig | None = None,
                 hand_config: OneHandConfig | None = None, arm: str | None = None) -> None:
        # Closer onto the stances than the palms need: one arm reaching across in front of the body has a few
        # centimetres to spare before its elbow meets the torso.
        super().__init__(robot, walker, arms, grid, goal, stance, grip or GripConfig(align_tolerance_m=HAND_ALIGN_TOLERANCE_M))
        self._choose_hand = arm is None
        arm = arm or (PREFERRED_HAND if PREFERRED_HAND in robot.hands else next(iter(robot.hands), ""))
        if arm not in robot.hands:
            raise InvalidGoalError(f"robot {robot.name!r} has no hand on {arm!r} to grasp with; hands: "
                                   f"{', '.join(robot.hands) or 'none'}")
        self.hand_config = hand_config or OneHandConfig()
        self._use_hand(arm)
        self._rotation = np.eye(3)  # the tool's orientation for the hand's moves, world frame
        self._tool = np.zeros(3)  # the tool position commanded last, world [m]
        self._grasp_heading = 0.0  # the robot's heading when the hand took the object [rad]

    def _use_hand(self, arm: str) -> None:
        """Grasp with ``arm``'s hand (a key of ``robot.hands``); the other arm swings clear."""
        self.layout = self.robot.hands[arm]
        self.hand = hand_of(self.robot.model, self.layout)
        c = self.hand_config
        self.closer = FingerCloser(self.hand, c.close_speed, c.touch_force_n, c.squeeze_rad)
        self.other_arm = next((a for a in self.arms.arms if a != arm), None)
        self.fingers: dict[str, float] = dict.fromkeys([*self.layout.fingers, PALM], 0.0)

    def _holds(self, model: mujoco.MjModel, data: mujoco.MjData, arm: str) -> bool:
        name = self.goal.object_name
        hand = hand_of(model, self.robot.hands[arm])
        return (name in self.robot.objects and arm in self.arms.arms
                and holds(finger_forces(model, data, hand, model.body(name).id), hand, self.hand_config.hold_force_n))

    def _pick_hand(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Unless the goal named the arm: the hand that holds the object already, else the one whose stance keeps
        the body farther from the table. The stance stands ``hand_side_m`` to the side away from the hand; turned
        with the object, that side runs toward the table's edge or away from it, and a stance moved toward the edge
        put the legs against the table (a cube turned -25 to -30 degrees, the right hand: the robot bounced off
        the table's edge and stood 15 cm short). The preferred hand unless the other stands clear by more than
        ``HAND_CLEARANCE_TIE_M``."""
        if not self._choose_hand or len(self.robot.hands) < 2:
            return
        held = [arm for arm in self.robot.hands if self._holds(model, data, arm)]
        if held:
            self._use_hand(held[0])
            return
        best, best_clear = self.layout.arm, -math.inf
        for arm in sorted(self.robot.hands, key=lambda a: a != self.layout.arm):  # the preferred hand first
            try:
                plan = plan_fetch(self.robot, data, self.goal, self.grid, self.stance_config, hand=self.robot.hands[arm])
            except InvalidGoalError:
                continue
            table = next(t for t in self.robot.obstacles if t.name == plan.pick.table)
            clear = edge_clearance(table, plan.pick.x, plan.pick.y)
            if clear > best_clear + HAND_CLEARANCE_TIE_M:
                best, best_clear = arm, clear
        self._use_hand(best)

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._pick_hand(model, data)
        held = self._holds(model, data, self.layout.arm)
        self.plan = plan_fetch(self.robot, data, self.goal, self.grid, self.stance_config, in_hand=held, hand=self.layout)
        self._base_qpos = int(model.jnt_qposadr[model.body_jntadr[model.body(self.robot.base_body).id]])
        self._t0 = self._now = float(data.time)
        self.walker.hold_balance(True)  # standing at the tables the legs balance actively (as the box fetch's)
        if held:  # in the hand already (a fetch canceled while it held it): straight to the place, the fingers as they are
            self._rotation = quat_to_mat(self.arms.status(self.layout.arm).tool_pose.orientation_wxyz)
            self._grasp_heading = self._base(data)[2]
            self._enter("back_off", Stage.TRANSPORT)
            x, y, _ = self._base(data)
            if not self.grid.inflated(NAVIGATION_INFLATION_M).is_free(x, y):  # at a table: step back first
                self._walk_by(-self.stance_config.approach_back_m, model, data)
            return
        self.closer.open(data)
        self._enter("navigate_pick", Stage.APPROACH)
        pick = self.plan.pick
        self._start_walk(NavigateSkill(self.walker, self.robot.base_body, self.grid,
                                       NavigateGoal(pick.approach_x, pick.approach_y, pick.yaw), self._nav_settings()),
                         model, data)

    def feedback(self, data: mujoco.MjData) -> Values:
        """The box fetch's feedback; the grip force is the hand's (all its fingers and palm on the object)."""
        return {**super().feedback(data), "grip_force": sum(self.fingers.values())}

    # ----- the hand's phases -------------------------------------------------------------------
    def _advance(self, model: mujoco.MjModel, data: mujoco.MjData) -> SkillOutcome | None:
        if self._phase not in HAND_PHASES:
            return super()._advance(model, data)
        plan, config = self.plan, self.hand_config
        assert plan is not None  # set by start
        phase, elapsed = self._phase, self._now - self._phase_t0
        center = data.xpos[plan.body]
        if phase in MOVES:
            status = self.arms.status(self.layout.arm)
            near = status.progress >= 1.0 and status.position_error <= config.arrive_tolerance_m
            # The arm controller gives up on a target its IK misses by a millimetre: within the tolerance it is there.
            # The retreat only ends early where the hand cannot go: the object is down and let go.
            given_up = (status.unreachable and not near) or elapsed > config.move_timeout_s
            if given_up and phase != "retreat":
                return self._fail("UNREACHABLE", f"{phase}: " + (status.reason or f"{status.position_error * 1e3:.0f} mm off"))
            if not near and not given_up:
                return None
        if phase == "align_pick":
            if self._align(plan.pick, data, elapsed):
                self._grasp_heading = self._base(data)[2]
                self._rotation = grasp_rotation(self.hand, yaw_of(data.xquat[plan.body]), self._grasp_heading,
                                                config.palm_tilt(float(plan.half_size[2])))
                self._enter("beside", Stage.DESCEND)
                self._move(self._beside(center), config.reach_speed_mps)
        elif phase in ("beside", "reach", "close"):
            if phase == "close":
                touching = sum(1 for f in self.layout.fingers if self.fingers[f] >= config.hold_force_n)
                self.stage_progress = min(1.0, touching / 2.0)
            failure = self._grasp_step(phase, self._now, elapsed, center, self._held(), self.fingers, self.goal.lift_height_m)
            if failure is not None:
                return self._fail("GRASP_FAILED", failure)
        elif phase == "lift":
            self._hold_arms()
            self._enter("back_off", Stage.TRANSPORT)
            self._walk_by(-self.stance_config.approach_back_m, model, data)
        elif phase == "align_place":
            if self._align(plan.place, data, elapsed):
                self._enter("over_place", Stage.PLACE)
                # The hand as it lifted the object, turned with the robot: a pose the arm reached there.
                self._rotation = yaw_matrix(self._base(data)[2] - self._grasp_heading) @ self._rotation
                self._tool = self.arms.status(self.layout.arm).tool_pose.position.copy()
                above = plan.place_center.copy()
                above[2] = float(center[2])
                self._move(above - (center - self._tool), config.carry_speed_mps)
        elif phase == "over_place":
            self._enter("lower", Stage.PLACE)
            offset = center - self.arms.status(self.layout.arm).tool_pose.position
            self._move(plan.place_center - offset - np.array([0.0, 0.0, config.place_press_m]), config.carry_speed_mps)
        elif phase == "lower":
            status = self.arms.status(self.layout.arm)
            arrived = status.progress >= 1.0 and status.position_error <= config.arrive_tolerance_m
            resting = float(center[2]) <= plan.place_center[2] + config.rest_tolerance_m
            if resting or (arrived and elapsed > 0.5) or elapsed > config.move_timeout_s:
                self.arms.hold(self.layout.arm)
                self._enter("release", Stage.RELEASE)
                self.closer.open(data)
        elif phase == "release":
            self.stage_progress = min(1.0, elapsed / config.release_s)
            let_go = max(self.fingers[f] for f in self.layout.fingers) < config.touch_force_n  # the palm may rest on it
            if elapsed >= config.release_s and (let_go or elapsed >= 2.0 * config.release_s):
                self._enter("retreat", Stage.RETREAT)
                self._move(self._beside(center), config.reach_speed_mps)
        elif phase == "retreat":
            self._hold_arms()
            self._enter("step_back", Stage.RETREAT)
            self._walk_by(-self.stance_config.approach_back_m, model, data)
        return None

    # ----- hooks of the box fetch ----------------------------------------------------------------
    def _measure(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        """Each finger's force on the object; the closing fingers advance or squeeze (every control step)."""
        plan = self.plan
        assert plan is not None
        self.fingers = finger_forces(model, data, self.hand, plan.body, solve=True)
        self.closer.update(data, self.fingers, control_dt)
        total = sum(self.fingers.values())
        self._forces = (0.0, total) if self.layout.palm_normal_in_tool[1] > 0.0 else (total, 0.0)  # (left, right)

    def _held(self) -> bool:
        return holds(self.fingers, self.hand, self.hand_config.hold_force_n)

    def _unreachable(self) -> SkillOutcome | None:
        """The hand's moves judge their own reach (see ``_advance``)."""
        return None

    def _ready_pose(self, data: mujoco.MjData, top_z: float) -> None:
        """Raise the hand ready (its pose at the stance, carried to where the robot stands now) and swing the
        other arm back."""
        plan = self.plan
        assert plan is not None
        self._rotation = grasp_rotation(self.hand, yaw_of(data.xquat[plan.body]), plan.pick.yaw,
                                        self.hand_config.palm_tilt(float(plan.half_size[2])))
        x, y, _ = self._feet(data)
        out = self.hand_config.approach_m * (self._rotation @ np.asarray(self.layout.palm_normal_in_tool, dtype=float))
        for back in READY_BACKS_M:  # the farthest back the arm reaches (the pelvis sways a few centimetres)
            ready = ready_tool_pose(self.hand, data.xpos[plan.body], self._rotation, back, READY_RISE_M).position - out
            ready += np.array([x - plan.pick.x, y - plan.pick.y, 0.0])
            pose = grasp_tool_pose(self.hand, ready, self._rotation, np.zeros(3))
            if self.arms.kinematics.solve(self.layout.arm, data.qpos.copy(), pose, False).success:
                break
        self._move(ready, self.hand_config.reach_speed_mps)
        if self.other_arm is not None and self.arms.status(self.other_arm).mode is ArmMode.IDLE:
            # Its servo swings it (the arm controller leaves an idle arm's servos alone; it holds it there later).
            joint = self.robot.joint_groups[self.other_arm][0]
            data.ctrl[self.robot.model.actuator(joint).id] = OTHER_ARM_SWING_RAD


def fetch_skill(robot: RobotSpec, walker: WalkingController, arms: ArmController, grid: OccupancyGrid,
                goal: FetchGoal) -> FetchSkill:
    """The fetch of ``goal``: with one hand for a small object the robot's hands hold
    (:func:`~sim_bridge.fetch.goal.for_one_hand`), else with both palms (an unknown object is refused when it starts)."""
    if for_one_hand(robot, goal.object_name):
        return OneHandFetch(robot, walker, arms, grid, goal)
    return FetchSkill(robot, walker, arms, grid, goal)
