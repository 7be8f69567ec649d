"""Pick a small object with one hand where the robot stands, hold it up, and put it down: a skill in the control step.

The robot stands at the table (a stance within the arm's reach: the walk there is the fetch's); the
walker keeps it balancing on both feet while the arm moves (``hold_balance``). The stages are PickPlace's:

- APPROACH: the hand opens and goes beside the object, ``approach_m`` out along the palm normal and
  ``approach_rise_m`` up from the grasp;
- DESCEND: in along a straight line until the object's centre is at the hand's grasp point;
- GRASP: the fingers close until each touches (:class:`~sim_bridge.fetch.one_hand.FingerCloser`); the grasp is
  made when the thumb and another finger press on the object for ``grasp_settle_s``;
- LIFT: the hand rises ``lift_height_m``;
- TRANSPORT: it holds still ``hold_s`` (the fetch carries it here);
- PLACE: the object over its place, then down until the table carries it;
- RELEASE: the fingers open;
- RETREAT: the hand backs out along the palm normal and up; the placement is measured.

Failures: FELL, UNREACHABLE (the arm cannot reach), GRASP_FAILED (the fingers closed without holding),
OBJECT_DROPPED (no longer held while lifted or carried: where it lies), PLACEMENT_FAILED, TIMEOUT. Only
friction holds the object.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import mujoco
import numpy as np

from robot_models.hands import HandLayout
from robot_models.validation import check_range
from sim_bridge.arm import ArmController, PickPlaceStage
from sim_bridge.errors import InvalidGoalError, UnknownNameError
from sim_bridge.fetch.bimanual import tilt_of, yaw_of
from sim_bridge.fetch.one_hand import FingerCloser, Hand, finger_forces, grasp_rotation, grasp_tool_pose, hand_of, holds
from sim_bridge.fetch.outcome import Lasting, dropped, placement
from sim_bridge.locomotion import WalkingController
from sim_bridge.skills.base import SkillOutcome, Values
from sim_bridge.state import Pose

Stage = PickPlaceStage


@dataclass(frozen=True)
class OneHandGoal:
    """Pick ``object_name`` with one hand, lift it, hold it, and put it down.

    Attributes:
        object_name: a small object of the scene resting in the hand's reach.
        lift_height_m: how far it is lifted [m].
        hold_s: how long it is held up [s of sim time].
        place_xy: where its centre goes down, world [m]; None: where it was picked.
        placement_tolerance_m: largest distance from the place counted as success [m].
        timeout_s: for the whole task [s of sim time].
    """

    object_name: str
    lift_height_m: float = 0.08
    hold_s: float = 3.0
    place_xy: tuple[float, float] | None = None
    placement_tolerance_m: float = 0.02
    timeout_s: float = 60.0

    def __post_init__(self) -> None:
        check_range("lift_height", self.lift_height_m, 0.02, 0.25, unit="m", error=InvalidGoalError)
        check_range("hold", self.hold_s, 0.0, 600.0, unit="s", error=InvalidGoalError)
        check_range("timeout", self.timeout_s, 0.0, 3600.0, low_open=True, unit="s", error=InvalidGoalError)


@dataclass(frozen=True)
class OneHandConfig:
    """How the hand moves and closes.

    Attributes:
        palm_tilt_rad: the palm faces the robot's midline tilted this much down [rad] (the fingers and the palm's
            lower edge stay above the table top under a low object's centre).
        tall_palm_tilt_rad, tall_half_height_m: ... and this much for an object whose centre rests this high above
            the table or higher [rad, m]: there is room below, and a palm tilted more leans its upper edge into
            the object's side as the fingers close, tipping it in the hand (a 12 cm can: 10 degrees, 19 carried).
        approach_m, approach_rise_m: the hand starts this far out along the palm normal and this far up from
            the grasp [m], and backs out there after the release.
        reach_speed_mps, carry_speed_mps: hand speeds reaching and holding [m/s].
        close_speed: finger travel fraction per second [1/s].
        touch_force_n: a finger pressing this hard touches [N].
        squeeze_rad: a touching finger's targets stay this far past where it touched [rad].
        hold_force_n: the thumb and another finger pressing this hard hold the object [N].
        grasp_settle_s: ... for this long before the lift [s].
        drop_after_s: not held this long while lifted is a drop [s].
        place_press_m: the object is lowered to this far below its resting height [m].
        rest_tolerance_m: an object this close to its resting height rests [m].
        release_s: the fingers open for this long at least, until no finger touches, and twice as long at most [s].
        arrive_tolerance_m: a move has arrived within this [m].
        move_timeout_s, grasp_timeout_s: longest arm move, longest closing [s].
        max_place_tilt_rad: a placed object tilted more is not placed.
    """

    palm_tilt_rad: float = 0.3
    tall_palm_tilt_rad: float = 0.15
    tall_half_height_m: float = 0.05
    approach_m: float = 0.06
    approach_rise_m: float = 0.04
    reach_speed_mps: float = 0.15
    carry_speed_mps: float = 0.06
    close_speed: float = 1.5
    touch_force_n: float = 1.0
    squeeze_rad: float = 0.5
    hold_force_n: float = 0.5
    grasp_settle_s: float = 0.3
    drop_after_s: float = 0.3
    place_press_m: float = 0.003
    rest_tolerance_m: float = 0.004
    release_s: float = 0.5
    arrive_tolerance_m: float = 0.01
    move_timeout_s: float = 6.0
    grasp_timeout_s: float = 3.0
    max_place_tilt_rad: float = math.radians(5.0)

    def __post_init__(self) -> None:
        for item in fields(self):
            if item.name not in ("palm_tilt_rad", "place_press_m"):
                check_range(item.name, getattr(self, item.name), 0.0, low_open=True, error=InvalidGoalError)

    def palm_tilt(self, half_height_m: float) -> float:
        """The palm's tilt [rad] for an object whose centre rests ``half_height_m`` [m] above the table."""
        return self.tall_palm_tilt_rad if half_height_m >= self.tall_half_height_m else self.palm_tilt_rad


class HandMoves:
    """The hand's moves and its grasp, shared by :class:`OneHandPick` and the fetch's
    :class:`~sim_bridge.fetch.one_hand_fetch.OneHandFetch` (each sets these attributes): beside the object, in
    to the grasp, the fingers closed until they hold, up."""

    hand: Hand
    arms: ArmController
    closer: FingerCloser
    hand_config: OneHandConfig
    _rotation: np.ndarray  # the tool's orientation for the hand's moves, world frame, shape (3, 3)
    _tool: np.ndarray  # the tool position commanded last, world [m]
    _gripped: Lasting  # the thumb and a finger hold it, long enough to lift

    def _beside(self, center: np.ndarray) -> np.ndarray:
        """The tool position out along the palm normal and up from the grasp of an object at ``center`` (world [m])."""
        normal = self._rotation @ np.asarray(self.hand.layout.palm_normal_in_tool, dtype=float)
        grasp = grasp_tool_pose(self.hand, center, self._rotation).position
        return grasp - self.hand_config.approach_m * normal + np.array([0.0, 0.0, self.hand_config.approach_rise_m])

    def _move(self, tool_position: np.ndarray, speed_mps: float) -> None:
        self._tool = np.asarray(tool_position, dtype=float).copy()
        self.arms.set_target(self.hand.arm, grasp_tool_pose(self.hand, self._tool, self._rotation, np.zeros(3)),
                             False, speed_mps, 1.0)

    def _enter(self, phase: str, stage: Stage) -> None:
        raise NotImplementedError  # each skill records its phases and stages

    def _grasp_step(self, phase: str, now: float, elapsed: float, center: np.ndarray, held: bool,
                    forces: Mapping[str, float], lift_height_m: float) -> str | None:
        """The grasp's phases, each called once the one before it ended (its move arrived): from beside the object
        (any other ``phase``) in to the grasp ("reach": the object's ``center``, world [m], at the grasp point); the
        fingers close ("close"); once the thumb and a finger have held for ``grasp_settle_s``, up by
        ``lift_height_m`` [m] ("lift").

        Args:
            now, elapsed: the sim time and the time in ``phase`` [s]; held, forces: the grip now (finger forces [N]).

        Returns:
            why the grasp failed (the fingers closed without holding, or ran out of time), else None.
        """
        config = self.hand_config
        if phase == "reach":
            self._enter("close", Stage.GRASP)
            self.closer.close()
        elif phase == "close":
            if self._gripped.update(now, held):
                self._enter("lift", Stage.LIFT)
                self._move(self._tool + np.array([0.0, 0.0, lift_height_m]), config.carry_speed_mps)
            elif elapsed > config.grasp_timeout_s or (self.closer.done and elapsed > config.grasp_settle_s + 1.0):
                return "the fingers closed without holding (" + ", ".join(f"{f} {n:.1f} N" for f, n in forces.items()) + ")"
        else:
            self._enter("reach", Stage.DESCEND)
            self._move(grasp_tool_pose(self.hand, center, self._rotation).position, config.reach_speed_mps)
        return None


class OneHandPick(HandMoves):
    """Pick, hold and put down one small object with one hand (see the module). A skill for a SkillHost.

    Args:
        walker: the walking controller (it keeps the robot balancing meanwhile).
        arms: the arm controller in ``Slot.ARM``.
        hand: the hand to use (its arm is the skill's resource).
        goal: what to pick; config: tuning.
    """

    name = "pick_place"
    pose_frame = "world"

    def __init__(self, walker: WalkingController, arms: ArmController, hand: HandLayout, goal: OneHandGoal,
                 config: OneHandConfig | None = None) -> None:
        self.walker, self.arms, self.layout, self.goal = walker, arms, hand, goal
        self.hand_config = config or OneHandConfig()
        self.resource = hand.arm
        self.stage = Stage.APPROACH
        self.events: list[str] = []
        self.forces: dict[str, float] = {}
        self.placement_error = math.nan
        self._phase, self._phase_t0, self._t0, self._now = "", 0.0, 0.0, 0.0
        self._body = -1
        self._rotation = np.eye(3)
        self._place = np.zeros(3)  # where the object's centre rests when placed, world [m]
        self._tool = np.zeros(3)  # the tool position commanded last, world [m]
        self._cancel = False
        self._gripped = Lasting(self.hand_config.grasp_settle_s)
        self._lost = Lasting(self.hand_config.drop_after_s)

    @property
    def milestone(self) -> int:
        return int(self.stage)

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Plan the grasp from the object's measured pose; open the hand and move it beside the object.

        Raises:
            UnknownNameError: no such object or hand names; InvalidGoalError: the arm cannot reach the approach.
        """
        try:
            self._body = int(model.body(self.goal.object_name).id)
        except KeyError as error:
            raise UnknownNameError(f"no object {self.goal.object_name!r}") from error
        if self.resource not in self.arms.arms:
            raise UnknownNameError(f"no arm {self.resource!r}; arms: {', '.join(self.arms.arms)}")
        self.hand = hand_of(model, self.layout)
        config = self.hand_config
        self.closer = FingerCloser(self.hand, config.close_speed, config.touch_force_n, config.squeeze_rad)
        self._t0 = self._now = float(data.time)
        center = data.xpos[self._body].copy()
        heading = yaw_of(data.xquat[model.body(self.arms.robot.base_body).id])
        self._rotation = grasp_rotation(self.hand, yaw_of(data.xquat[self._body]), heading, self.hand_config.palm_tilt_rad)
        x, y = self.goal.place_xy if self.goal.place_xy is not None else (float(center[0]), float(center[1]))
        self._place = np.array([x, y, float(center[2])])
        self.walker.hold_balance(True)
        self.closer.open(data)
        self._enter("approach", Stage.APPROACH)
        self._move(self._beside(center), self.hand_config.reach_speed_mps)
        if self.arms.status(self.resource).unreachable:
            raise InvalidGoalError(f"the {self.resource} cannot reach beside {self.goal.object_name!r}: "
                                   f"{self.arms.status(self.resource).reason}")

    def request_cancel(self) -> None:
        self._cancel = True

    def stop_now(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.arms.hold(self.resource)

    def update_settings(self, settings: Mapping[str, float]) -> None:
        """Nothing of a running pick changes with settings."""

    def feedback(self, data: mujoco.MjData) -> Values:
        body = max(self._body, 0)
        return {"stage": int(self.stage), "stage_name": self.stage.name, "phase": self._phase,
                "elapsed": self._now - self._t0, "grip_force": sum(self.forces.values()),
                "object_pose": Pose(data.xpos[body].copy(), data.xquat[body].copy()),
                **{f"force_{finger}": force for finger, force in self.forces.items()}}

    def result(self, data: mujoco.MjData) -> Values:
        body = max(self._body, 0)
        return {"final_object_pose": Pose(data.xpos[body].copy(), data.xquat[body].copy()),
                "placement_error": self.placement_error}

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        outcome = self._update(model, data, control_dt)
        if outcome is not None:
            self.walker.hold_balance(False)
        return outcome

    def _update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        self._now = float(data.time)
        self.forces = finger_forces(model, data, self.hand, self._body, solve=True)
        self.closer.update(data, self.forces, control_dt)
        if self.walker.status().fallen:
            self.arms.hold(self.resource)
            return SkillOutcome.aborted("FELL", f"fell in stage {self.stage.name}")
        if self._cancel:
            self.arms.hold(self.resource)
            return SkillOutcome.canceled(f"canceled in stage {self.stage.name}; the hand holds still")
        if self._now - self._t0 > self.goal.timeout_s:
            self.arms.hold(self.resource)
            return SkillOutcome.aborted("TIMEOUT", f"timed out in stage {self.stage.name}")
        held = holds(self.forces, self.hand, self.hand_config.hold_force_n)
        carrying = self._phase in ("lift", "hold", "over")
        if self._lost.update(self._now, carrying and not held):
            self.arms.hold(self.resource)
            return dropped(self.goal.object_name, self.stage.name, data.xpos[self._body])
        return self._advance(data, held)

    def _advance(self, data: mujoco.MjData, held: bool) -> SkillOutcome | None:
        config, phase, elapsed = self.hand_config, self._phase, self._now - self._phase_t0
        center = data.xpos[self._body]
        if phase in ("approach", "reach", "lift", "over", "retreat"):
            status = self.arms.status(self.resource)
            # The arm controller gives up on a target its IK misses by a millimetre; within the arrival
            # tolerance the hand is where it needs to be.
            near = status.progress >= 1.0 and status.position_error <= config.arrive_tolerance_m
            if (status.unreachable and not near) or (elapsed > config.move_timeout_s and phase != "retreat"):
                self.arms.hold(self.resource)
                reason = status.reason or f"{status.position_error * 1e3:.0f} mm off"
                return SkillOutcome.aborted("UNREACHABLE", f"{phase}: {reason}")
            if not self._arrived() and elapsed <= config.move_timeout_s:
                return None
        if phase in ("approach", "reach", "close"):
            failure = self._grasp_step(phase, self._now, elapsed, center, held, self.forces, self.goal.lift_height_m)
            if failure is not None:
                self.arms.hold(self.resource)
                return SkillOutcome.aborted("GRASP_FAILED", failure)
        elif phase == "lift":
            self._enter("hold", Stage.TRANSPORT)
        elif phase == "hold":
            if elapsed >= self.goal.hold_s:
                self._enter("over", Stage.PLACE)
                offset = center - self._tool  # the object from the tool now, world [m]
                self._move(np.array([*self._place[:2], center[2]]) - offset, config.carry_speed_mps)
        elif phase == "over":
            self._enter("lower", Stage.PLACE)
            offset = center - self._tool
            self._move(self._place - offset - np.array([0.0, 0.0, config.place_press_m]), config.carry_speed_mps)
        elif phase == "lower":
            resting = float(center[2]) <= self._place[2] + config.rest_tolerance_m
            if resting or (self._arrived() and elapsed > 0.5) or elapsed > config.move_timeout_s:
                self.arms.hold(self.resource)
                self._enter("release", Stage.RELEASE)
                self.closer.open(data)
        elif phase == "release":
            let_go = max(self.forces[f] for f in self.hand.layout.fingers) < config.touch_force_n  # the palm may rest on it
            if elapsed >= config.release_s and (let_go or elapsed >= 2.0 * config.release_s):
                self._enter("retreat", Stage.RETREAT)
                self._move(self._beside(center), config.reach_speed_mps)
        elif phase == "retreat":
            self.placement_error = float(np.linalg.norm(center - self._place))
            return placement(self.placement_error, tilt_of(data.xquat[self._body]), self.goal.placement_tolerance_m,
                             config.max_place_tilt_rad)
        return None

    def _arrived(self) -> bool:
        status = self.arms.status(self.resource)
        return status.progress >= 1.0 and status.position_error <= self.hand_config.arrive_tolerance_m

    def _enter(self, phase: str, stage: Stage) -> None:
        self._phase, self._phase_t0, self.stage = phase, self._now, stage
        self._gripped.clear()
        self.events.append(f"{self._now:.2f} {stage.name} {phase}")
