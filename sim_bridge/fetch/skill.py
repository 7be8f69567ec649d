"""Fetch: a biped walks to an object on a table, squeezes it between its palms, carries it and places it.

The whole loco-manipulation task as one skill in the control step, on the measured state. It owns the
legs (through the locomotion skills :class:`~sim_bridge.skills.NavigateSkill` and
:class:`~sim_bridge.skills.WalkSkill`, which it runs itself) and both arms (through the arm
controller, which must run in the simulation's ``Slot.ARM``). Its stages are PickPlace's:

- APPROACH: navigate to the point behind the stance, raise the hands ready, walk forward onto the stance;
- DESCEND: the palms to the box's sides, short of them;
- GRASP: the palms close until each measures the grip force on the box (friction only, no attachment);
- LIFT: up by the lift height, the grip force regulated;
- TRANSPORT: the arms hold their joints; step back, navigate to the place's approach, walk onto its stance;
- PLACE: the box over the place, then down onto the table;
- RELEASE: the palms open until they no longer touch it;
- RETREAT: the hands rise, the robot steps back; the placement is measured.

Failures: FELL (the robot fell), OBJECT_DROPPED (no palm touches it while held: where it lies),
GRASP_FAILED, UNREACHABLE (an arm cannot reach), PLACEMENT_FAILED, TIMEOUT; a walk's own failure is
passed on. Cancel: the robot stops walking, stands and keeps holding what it holds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import mujoco
import numpy as np

from robot_models import RobotSpec
from sim_bridge.arm import ArmController, PickPlaceStage
from sim_bridge.arm.poses import quat_to_mat
from sim_bridge.fetch import bimanual
from sim_bridge.fetch.align import StanceAligner
from sim_bridge.fetch.bimanual import Palm, grip_forces, palms_of, set_palm_hand_pose, tilt_of, tool_target, yaw_matrix, yaw_of
from sim_bridge.fetch.goal import NAVIGATION_INFLATION_M, FetchGoal, FetchPlan, plan_fetch
from sim_bridge.fetch.grip import GripConfig
from sim_bridge.fetch.outcome import Lasting, dropped, fetch_visuals, placement, walk_failure
from sim_bridge.fetch.stance import Stance, StanceConfig, wrap
from sim_bridge.locomotion import WalkingController
from sim_bridge.navigation import OccupancyGrid
from sim_bridge.skills.base import GoalVisuals, SkillOutcome, Values
from sim_bridge.skills.locomotion import LEGS, NavigateGoal, NavigateSkill, WalkGoal, WalkSkill
from sim_bridge.state import Pose

Stage = PickPlaceStage
STANDING_PHASES = ("idle", "balance")  # gait phases of a biped standing on both feet (GaitPhase.kind)


class FetchSkill:
    """The fetch of one object (see the module). A skill for the legs' :class:`~sim_bridge.skills.SkillHost`.

    Args:
        robot: the robot scene (tables are its obstacles, palms its ``palms``).
        walker: the walking controller the legs' host runs.
        arms: the arm controller in ``Slot.ARM``.
        grid: the scene's navigation map.
        goal: what to fetch where.
        stance: stance distances; grip: grip tuning.
    """

    name = "pick_place"
    resource = LEGS
    pose_frame = "world"

    def __init__(self, robot: RobotSpec, walker: WalkingController, arms: ArmController, grid: OccupancyGrid,
                 goal: FetchGoal, stance: StanceConfig | None = None, grip: GripConfig | None = None) -> None:
        self.robot, self.walker, self.arms, self.grid, self.goal = robot, walker, arms, grid, goal
        self.also_holds: tuple[str, ...] = tuple(arms.arms)  # it moves both arms: their goals wait for it
        self.stance_config = stance or StanceConfig()
        self.config = grip or GripConfig()
        self.palms: tuple[Palm, Palm] = palms_of(robot)
        self.plan: FetchPlan | None = None
        self.stage = Stage.APPROACH
        self.stage_progress = 0.0
        self._phase = ""
        self._phase_t0 = 0.0
        self._t0 = self._now = 0.0
        self._walk: WalkSkill | NavigateSkill | None = None
        self._cancel = False
        self._canceling = False
        self._center = np.zeros(3)  # the grip's box centre now commanded (world [m])
        self._center_goal = np.zeros(3)
        self._yaw = 0.0  # the grip frame's yaw (the box's x axis, facing the robot's way) [rad]
        self._depth = [0.0, 0.0]  # each palm's squeeze depth past the box surface [m]
        self._next_grip = 0.0
        self._gripping = False
        self._squeezing = False
        self._aligner = StanceAligner(self.walker, self.config)
        self._gripped = Lasting(self.config.grasp_settle_s)  # the squeeze force reached, long enough to lift
        self._lost = Lasting(self.config.drop_after_s)  # no palm holds what it carries: dropped
        self._refused = Lasting(self.config.unreachable_s)  # an arm's controller gave up on its target
        self._forces = (0.0, 0.0)
        self._offset = np.zeros(3)
        self._turn_spot: Stance | None = None  # where the robot turns to the stance heading before raising its hands
        self._base_qpos = 0
        self.placement_error = math.nan
        self.events: list[str] = []

    # ----- Skill protocol ------------------------------------------------------------------
    @property
    def milestone(self) -> int:
        return int(self.stage)

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        held = bimanual.in_palms(model, data, self.palms, self.goal.object_name, self.config.contact_force_n)
        self.plan = plan_fetch(self.robot, data, self.goal, self.grid, self.stance_config, in_hand=held)
        self._base_qpos = int(model.jnt_qposadr[model.body_jntadr[model.body(self.robot.base_body).id]])
        self._t0 = self._now = float(data.time)
        set_palm_hand_pose(self.robot, model, data)  # the hands take their palm pose on the way
        # Standing at the tables the legs keep balancing actively: the arms' reaches and the box's weight would
        # rock a robot standing on its leg servos, and its hands with it.
        self.walker.hold_balance(True)
        if held:  # in the palms already (a fetch canceled while it held it): straight to the place, same grip
            self._yaw = self._grip_yaw(float(yaw_of(data.xquat[self.plan.body])), data)
            self._depth = bimanual.squeeze_depths(self.palms, [self.arms.status(p.arm) for p in self.palms], self._yaw)
            self._enter("back_off", Stage.TRANSPORT)
            x, y, _ = self._base(data)
            if not self.grid.inflated(NAVIGATION_INFLATION_M).is_free(x, y):  # at a table: step back first
                self._walk_by(-self.stance_config.approach_back_m, model, data)
            return
        self._enter("navigate_pick", Stage.APPROACH)
        pick = self.plan.pick
        self._start_walk(NavigateSkill(self.walker, self.robot.base_body, self.grid,
                                       NavigateGoal(pick.approach_x, pick.approach_y, pick.yaw), self._nav_settings()),
                         model, data)

    def request_cancel(self) -> None:
        self._cancel = True

    def stop_now(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if self._walk is not None:
            self._walk.stop_now(model, data)
        self._hold_arms()
        self.walker.hold_balance(False)

    def update_settings(self, settings: Mapping[str, float]) -> None:
        """Nothing of a running fetch changes with the server's parameters."""

    def visuals(self) -> GoalVisuals:
        """The place (world frame), and while walking the walk's own path, goal pose and footsteps."""
        return fetch_visuals(self.plan, self._walk)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        outcome = self._update(model, data, control_dt)
        if outcome is not None:
            self.walker.hold_balance(False)  # standing still afterwards, the legs go back to their servos
        return outcome

    def _update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        self._now = float(data.time)
        plan = self.plan
        assert plan is not None  # set by start
        self._measure(model, data, control_dt)
        status = self.walker.status()
        if status.fallen:
            self.stop_now(model, data)
            return SkillOutcome.aborted("FELL", f"fell in stage {self.stage.name}: {status.message}")
        if self._cancel and not self._canceling:
            self._canceling = True
            if self._walk is not None:
                self._walk.request_cancel()
            self._hold_arms()
        if self._canceling:
            if self._walk is not None and self._walk.update(model, data, control_dt) is None:
                return None
            self._walk = None
            self._regulate(model, data)
            return SkillOutcome.canceled(f"canceled in stage {self.stage.name}: the robot stands"
                                         + (", holding the object" if self._held() else ""))
        if self._now - self._t0 > self.goal.timeout_s:
            self.stop_now(model, data)
            return SkillOutcome.aborted("TIMEOUT", f"timed out after {self.goal.timeout_s:.0f} s in stage {self.stage.name}")
        dropped = self._dropped(data)
        if dropped is not None:
            self.stop_now(model, data)
            return dropped
        if self._walk is not None:
            outcome = self._walk.update(model, data, control_dt)
            if outcome is None:
                return None
            self._walk = None
            if outcome.code != "SUCCESS":
                self._hold_arms()
                return walk_failure(outcome, self._phase)
        self._regulate(model, data)
        if self._phase in ("reach", "squeeze", "lift", "over_place", "lower", "release"):
            unreachable = self._unreachable()
            if unreachable is not None:
                return unreachable
        return self._advance(model, data)

    def feedback(self, data: mujoco.MjData) -> Values:
        plan = self.plan
        body = plan.body if plan is not None else 0
        percent = 100.0 * (int(self.stage) + self.stage_progress) / len(Stage)
        remaining = 0.0
        if self._walk is not None:
            walked = self._walk.feedback(data).get("distance_remaining", 0.0)
            remaining = float(walked) if isinstance(walked, (int, float)) else 0.0
        return {
            "stage": int(self.stage),
            "stage_name": self.stage.name,
            "stage_progress": self.stage_progress,
            "percent_complete": percent,
            "object_pose": Pose(data.xpos[body].copy(), data.xquat[body].copy()),
            "elapsed": self._now - self._t0,
            "distance_remaining": remaining,
            "grip_force": min(self._forces),
            "grip_force_left": self._forces[0],
            "grip_force_right": self._forces[1],
            "phase": self._phase,
        }

    def result(self, data: mujoco.MjData) -> Values:
        plan = self.plan
        body = plan.body if plan is not None else 0
        return {"final_object_pose": Pose(data.xpos[body].copy(), data.xquat[body].copy()),
                "placement_error": self.placement_error}

    # ----- phases ----------------------------------------------------------------------------
    def _advance(self, model: mujoco.MjModel, data: mujoco.MjData) -> SkillOutcome | None:
        plan = self.plan
        assert plan is not None
        config, phase, elapsed = self.config, self._phase, self._now - self._phase_t0
        box = data.xpos[plan.body]
        if phase == "navigate_pick":
            # Face the stance's heading where the navigation ended, hands still low: walking on with the hands
            # raised and the heading off would sweep them across the table into the object.
            x, y, _ = self._feet(data)
            self._turn_spot = replace(plan.pick, x=x, y=y)
            self._enter("turn_pick", Stage.APPROACH)
        elif phase == "turn_pick":
            assert self._turn_spot is not None
            if not self._align(self._turn_spot, data, elapsed):
                return None
            self._enter("ready_pick", Stage.APPROACH)
            self._ready_pose(data, plan.pick_top_z)
        elif phase == "ready_pick":
            if self._arms_arrived(config.ready_tolerance_m) or elapsed > config.move_timeout_s:
                self._hold_arms()
                self._enter("walk_pick", Stage.APPROACH)
                self._walk_onto(plan.pick, model, data)
        elif phase == "walk_pick":
            self._enter("align_pick", Stage.APPROACH)
        elif phase == "align_pick":
            if not self._align(plan.pick, data, elapsed):
                return None
            self._enter("reach", Stage.DESCEND)
            self._yaw = self._grip_yaw(float(yaw_of(data.xquat[plan.body])), data)
            # The palms take the box a little behind its centre: less reach, the box's weight ahead of the grip.
            back = min(config.grip_back_m, max(0.0, float(plan.half_size[0]) - config.palm_half_length_m))
            up = min(config.grip_up_m, max(0.0, float(plan.half_size[2]) - config.palm_half_height_m))
            self._center = box - back * yaw_matrix(self._yaw)[:, 0] + np.array([0.0, 0.0, up])
            self._center_goal = self._center.copy()
            self._depth = [-config.clearance_m, -config.clearance_m]
            self._set_grip_speed(config.reach_speed_mps)
        elif phase == "reach":
            self.stage_progress = min(1.0, min(self.arms.status(p.arm).progress for p in self.palms))
            if self._arms_arrived(config.reach_tolerance_m):
                self._enter("squeeze", Stage.GRASP)
                self._gripping = self._squeezing = True
            elif elapsed > config.move_timeout_s:
                return self._fail("UNREACHABLE", "the palms did not reach the object's sides: "
                                  + "; ".join(self.arms.status(p.arm).reason or f"{p.arm} "
                                              f"{self.arms.status(p.arm).position_error * 1e3:.0f} mm off" for p in self.palms))
        elif phase == "squeeze":
            target = config.grasp_fraction * self.goal.grip_force_n
            self.stage_progress = min(1.0, min(self._forces) / target)
            if self._gripped.update(self._now, min(self._forces) >= target):
                self._enter("lift", Stage.LIFT)
                self._center_goal = self._center + np.array([0.0, 0.0, self.goal.lift_height_m])
            if self._phase == "squeeze" and elapsed > config.grasp_timeout_s:
                return self._fail("GRASP_FAILED", f"the palms closed {self._depth[0] * 1e3:.0f} / {self._depth[1] * 1e3:.0f} "
                                  f"mm past the sides measuring {self._forces[0]:.1f} / {self._forces[1]:.1f} N")
        elif phase == "lift":
            rise = float(box[2]) - (plan.pick_top_z + float(plan.half_size[2]))
            self.stage_progress = min(1.0, max(0.0, rise / self.goal.lift_height_m))
            if self._at_goal() and elapsed > config.lift_settle_s:
                self._hold_arms()
                self._gripping = self._squeezing = False
                self._enter("back_off", Stage.TRANSPORT)
                self._walk_by(-self.stance_config.approach_back_m, model, data)
        elif phase == "back_off":
            place = plan.place
            self._enter("navigate_place", Stage.TRANSPORT)
            self._start_walk(NavigateSkill(self.walker, self.robot.base_body, self.grid,
                                           NavigateGoal(place.approach_x, place.approach_y, place.yaw),
                                           self._nav_settings()), model, data)
        elif phase == "navigate_place":
            self._enter("walk_place", Stage.TRANSPORT)
            self._walk_onto(plan.place, model, data)
        elif phase == "walk_place":
            self._enter("align_place", Stage.TRANSPORT)
        elif phase == "align_place":
            if self._align(plan.place, data, elapsed):
                self._enter("over_place", Stage.PLACE)
                self._start_carry(data)
                above = plan.place_center.copy()
                above[2] = self._center[2]
                self._center_goal = above - self._offset
        elif phase == "over_place":
            if self._at_goal() and self._arms_arrived(config.place_tolerance_m, held=True):
                self._enter("lower", Stage.PLACE)
                self._center_goal = plan.place_center - self._offset - np.array([0.0, 0.0, config.place_press_m])
        elif phase == "lower":
            # Let go as soon as the table carries the box: pressing it down would push the hands up, which
            # tips a robot standing on its servos backward.
            resting = float(box[2]) <= plan.place_center[2] + config.rest_tolerance_m
            if resting or (self._at_goal() and elapsed > config.lift_settle_s) or elapsed > config.move_timeout_s:
                self._enter("release", Stage.RELEASE)
                self._release()
        elif phase == "release":
            self.stage_progress = min(1.0, elapsed / config.release_s)
            if elapsed >= config.release_s and max(self._forces) < config.contact_force_n:
                self._gripping = False
                self._enter("raise", Stage.RETREAT)
                self._center = self._center + np.array([0.0, 0.0, config.retreat_rise_m])
                self._center_goal = self._center.copy()
                self._depth = [-config.ready_clearance_m] * 2  # wide of the box, above its top
                self._set_grip_speed(config.retreat_speed_mps)
        elif phase == "raise":
            # The box is down and let go: a hand that cannot rise all the way (a turned grip near the edge of
            # its reach) only ends the rise early.
            given_up = any(self.arms.status(p.arm).unreachable for p in self.palms)
            if self._arms_arrived(config.ready_tolerance_m) or given_up or elapsed > config.move_timeout_s:
                self._hold_arms()
                self._enter("step_back", Stage.RETREAT)
                self._walk_by(-self.stance_config.approach_back_m, model, data)
        elif phase == "step_back":
            return self._finish(data)
        return None

    def _unreachable(self) -> SkillOutcome | None:
        """UNREACHABLE when an arm's controller has given up on its target for ``unreachable_s``.

        The grip re-targets the arms every period, and an IK solve may miss a target at the edge of the
        workspace by a millimetre once and reach it the next time: only a lasting refusal fails."""
        refused = [(palm.arm, self.arms.status(palm.arm)) for palm in self.palms]
        refused = [(arm, status) for arm, status in refused if status.unreachable]
        if not self._refused.update(self._now, bool(refused)):
            if refused and not self._gripping:  # nothing re-targets the arms: try the same targets again
                self._set_grip_speed(self.config.reach_speed_mps)
            return None
        return self._fail("UNREACHABLE", "; ".join(f"{arm}: {status.reason}" for arm, status in refused))

    # ----- helpers ---------------------------------------------------------------------------
    def _enter(self, phase: str, stage: Stage) -> None:
        self._phase, self._phase_t0 = phase, self._now
        if stage != self.stage:
            self.stage_progress = 0.0
        self.stage = stage
        self._gripped.clear()
        self.events.append(f"{self._now:.2f} {stage.name} {phase}")

    def _measure(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        """The grip forces on the object now, at the start of each control step."""
        self._forces = grip_forces(model, data, self.palms, self.plan.body if self.plan else 0, solve=True)

    def _fail(self, code: str, message: str) -> SkillOutcome:
        self._hold_arms()
        return SkillOutcome.aborted(code, f"{self.stage.name}: {message}")

    def _nav_settings(self) -> dict[str, float]:
        return self.config.navigation_settings(self.goal.walking_speed_mps)

    def _start_walk(self, walk: WalkSkill | NavigateSkill, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._walk = walk
        walk.start(model, data)

    def _base(self, data: mujoco.MjData) -> tuple[float, float, float]:
        q = data.qpos[self._base_qpos:self._base_qpos + 7]
        return float(q[0]), float(q[1]), yaw_of(q[3:7])

    def _walk_by(self, distance: float, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        limits = self.robot.walking
        assert limits is not None  # a robot with a walker has walking limits
        if abs(distance) < self.config.min_walk_m:
            return
        self._start_walk(WalkSkill(self.walker, self.robot.base_body,
                                   WalkGoal(distance, min(self.goal.walking_speed_mps, 0.2), 0.0, limits),
                                   {"walking_speed": self.goal.walking_speed_mps}), model, data)

    def _feet(self, data: mujoco.MjData) -> tuple[float, float, float]:
        """The midpoint between the soles (world x, y [m]) and the pelvis heading [rad]."""
        x, y = self.walker.feet_midpoint(data)
        return x, y, self._base(data)[2]

    def _walk_onto(self, stance: Stance, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        x, y, yaw = self._feet(data)
        distance = (stance.x - x) * math.cos(yaw) + (stance.y - y) * math.sin(yaw)
        self._walk_by(distance, model, data)

    def _align(self, stance: Stance, data: mujoco.MjData, elapsed: float) -> bool:
        """Step onto the stance (see :class:`StanceAligner`); True once standing on it (or out of time)."""
        return self._aligner.step(stance, self._feet(data), elapsed, self._standing())

    def _standing(self) -> bool:
        """Standing again: the walker balances on both feet (it holds the balance: no hand-over to the servos)."""
        return self.walker.gait_phase().kind in STANDING_PHASES

    def _grip_yaw(self, box_yaw: float, data: mujoco.MjData) -> float:
        heading = self._base(data)[2]
        return box_yaw + math.pi * round(wrap(heading - box_yaw) / math.pi)

    def _ready_pose(self, data: mujoco.MjData, top_z: float) -> None:
        plan = self.plan
        assert plan is not None
        x, y, yaw = self._base(data)
        self._yaw = yaw
        forward = yaw_matrix(yaw)[:, 0]
        self._center = np.array([x, y, top_z + float(plan.half_size[2]) + self.config.ready_rise_m])
        self._center += self.config.ready_forward_m * forward
        self._center_goal = self._center.copy()
        hx, hy = float(plan.half_size[0]), float(plan.half_size[1])  # a box turned against the heading: its corner
        turn = math.asin(abs(math.sin(float(yaw_of(data.xquat[plan.body])) - yaw)))  # sticks out beyond its +-y faces
        self._depth = [-(self.config.ready_clearance_m + max(0.0, hx * math.sin(turn) - hy * (1.0 - math.cos(turn))))] * 2
        self._set_grip_speed(self.config.reach_speed_mps)

    def _set_grip_speed(self, speed: float) -> None:
        """Target both tools at the commanded grip (centre, yaw, each palm's depth), moving at ``speed`` [m/s]."""
        plan = self.plan
        assert plan is not None
        half_width = float(plan.half_size[1])
        for palm, depth in zip(self.palms, self._depth, strict=True):
            target = tool_target(palm, self._center, self._yaw, half_width, depth, self.config.hand_pitch_rad)
            self.arms.set_target(palm.arm, target, False, speed, 1.0)

    def _regulate(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """At the grip rate: move the commanded centre toward its goal; regulate each palm's squeeze."""
        if not self._gripping or self._now + 1e-9 < self._next_grip:
            return
        config = self.config
        self._next_grip = self._now + config.grip_period_s
        step = self._center_goal - self._center
        distance = float(np.linalg.norm(step))
        if distance > 0.0:
            self._center = self._center + step * min(1.0, config.carry_speed_mps * config.grip_period_s / distance)
        if self._squeezing and not self._canceling:
            for side in (0, 1):
                error = self.goal.grip_force_n - self._forces[side]
                change = float(np.clip(config.squeeze_gain * error * config.grip_period_s, -config.max_squeeze_step_m,
                                       config.max_squeeze_step_m))
                self._depth[side] = float(np.clip(self._depth[side] + change, -config.clearance_m, config.max_depth_m))
        self._set_grip_speed(2.0)

    def _at_goal(self) -> bool:
        return float(np.linalg.norm(self._center_goal - self._center)) < 1e-6

    def _arms_arrived(self, tolerance: float, held: bool = False) -> bool:
        statuses = [self.arms.status(p.arm) for p in self.palms]
        if held:
            return all(s.progress >= 1.0 for s in statuses)
        return all(s.progress >= 1.0 and s.position_error <= tolerance for s in statuses)

    def _hold_arms(self) -> None:
        for palm in self.palms:
            self.arms.hold(palm.arm)

    def _start_carry(self, data: mujoco.MjData) -> None:
        """Take the grip again in Cartesian space where the hands are now; keep the box's offset from the grip centre."""
        plan = self.plan
        assert plan is not None
        tools = [self.arms.status(p.arm).tool_pose for p in self.palms]
        faces = [t.position + quat_to_mat(t.orientation_wxyz) @ p.position_in_tool
                 for t, p in zip(tools, self.palms, strict=True)]
        self._center = 0.5 * (faces[0] + faces[1])
        self._yaw = self._grip_yaw(float(yaw_of(data.xquat[plan.body])), data)
        self._offset = data.xpos[plan.body] - self._center  # the box's centre from the grip's, world [m]
        self._center_goal = self._center.copy()
        self._gripping = self._squeezing = True
        self._next_grip = 0.0

    def _release(self) -> None:
        """Open the palms to the clearance at the reaching speed; the grip is no longer regulated."""
        self._gripping = self._squeezing = False
        self._depth = [-self.config.clearance_m] * 2
        self._center_goal = self._center.copy()
        self._set_grip_speed(self.config.reach_speed_mps)

    def _held(self) -> bool:
        return min(self._forces) >= self.config.contact_force_n

    def _dropped(self, data: mujoco.MjData) -> SkillOutcome | None:
        plan = self.plan
        assert plan is not None
        carrying = self.stage in (Stage.LIFT, Stage.TRANSPORT, Stage.PLACE)
        if not self._lost.update(self._now, carrying and not self._held()):
            return None
        return dropped(self.goal.object_name, self.stage.name, data.xpos[plan.body])

    def _finish(self, data: mujoco.MjData) -> SkillOutcome:
        plan = self.plan
        assert plan is not None
        position, quat = data.xpos[plan.body], data.xquat[plan.body]
        self.placement_error = float(np.linalg.norm(position - plan.place_center))
        tilt = tilt_of(quat)
        self.stage_progress = 1.0
        return placement(self.placement_error, tilt, self.goal.placement_tolerance_m, self.config.max_place_tilt_rad)
