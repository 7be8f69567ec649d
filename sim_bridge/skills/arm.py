"""MoveArm and PickPlace as skills in the control step, commanding the arm controller.

MoveArm tracks a tool pose with the arm controller's mink IK and decides success from the measured
tool pose; PickPlace runs the staged friction grasp of :class:`~sim_bridge.arm.PickPlace` and
reports its stages. "Safe" after a cancel or a timeout means: the arm holds where it is (at once).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models.validation import check_range
from sim_bridge.arm import ArmController, PickPlace, PickPlaceFailure, PickPlaceGoal, PickPlaceProgress
from sim_bridge.arm.poses import rotation_error
from sim_bridge.errors import InvalidGoalError
from sim_bridge.skills.base import GoalVisuals, SkillOutcome, Values
from sim_bridge.state import Pose

SETTLED_S = 0.03  # the tool must stay within tolerance this long to count as arrived [s of sim time]

# PickPlace's failures, by the name of the action's result code they end with.
PICK_PLACE_CODES = {
    PickPlaceFailure.UNREACHABLE: "UNREACHABLE",
    PickPlaceFailure.GRASP_MISSED: "GRASP_FAILED",
    PickPlaceFailure.OBJECT_SLIPPED: "OBJECT_DROPPED",
    PickPlaceFailure.OBJECT_DROPPED: "OBJECT_DROPPED",
    PickPlaceFailure.PLACEMENT_INACCURATE: "PLACEMENT_FAILED",
    PickPlaceFailure.TIMEOUT: "TIMEOUT",
    PickPlaceFailure.CANCELED: "CANCELED",
}


@dataclass(frozen=True)
class MoveArmGoal:
    """Move an arm's tool point to a world pose.

    Attributes:
        arm: the arm's name.
        target: tool pose, world frame.
        position_tolerance: [m], > 0.
        orientation_tolerance: [rad]; 0 = position only.
        max_linear_speed: tool speed limit [m/s].
        max_angular_speed: tool angular speed limit [rad/s].
        timeout_s: [s] of sim time, > 0.
    """

    arm: str
    target: Pose
    position_tolerance: float
    orientation_tolerance: float
    max_linear_speed: float
    max_angular_speed: float
    timeout_s: float

    def __post_init__(self) -> None:
        check_range("position_tolerance", self.position_tolerance, 0, low_open=True, unit="m", error=InvalidGoalError)
        check_range("orientation_tolerance (0 = position only)", self.orientation_tolerance, 0, unit="rad",
                    error=InvalidGoalError)
        check_range("timeout", self.timeout_s, 0, low_open=True, unit="s", error=InvalidGoalError)

    @property
    def position_only(self) -> bool:
        return self.orientation_tolerance == 0.0


class _ArmSkill:
    """What MoveArm and PickPlace share: the arm, its elapsed time and timeout, cancel."""

    pose_frame = "world"

    def __init__(self, arms: ArmController, arm: str, timeout_s: float) -> None:
        self.arms = arms
        self.resource = arm
        self._timeout = timeout_s
        self._t0 = 0.0
        self._now = 0.0
        self._cancel = False

    def request_cancel(self) -> None:
        self._cancel = True

    def update_settings(self, settings: Mapping[str, float]) -> None:
        """Nothing of a running arm goal changes with the server's parameters."""

    def _tick(self, data: mujoco.MjData) -> SkillOutcome | None:
        """Cancel and timeout; None while the goal's own logic should run."""
        self._now = float(data.time)
        if self._cancel:
            self._halt()
            return SkillOutcome.canceled("canceled: the arm holds where it is")
        if self._now - self._t0 > self._timeout:
            self._halt()
            return SkillOutcome.aborted("TIMEOUT", self._timeout_message())
        return None

    def _halt(self) -> None:
        self.arms.hold(self.resource)

    def _timeout_message(self) -> str:
        return f"timed out after {self._timeout:.1f} s of sim time"


class MoveArmSkill(_ArmSkill):
    """Track the target; succeed once the motion is complete and the tool stays within tolerance."""

    name = "move_arm"

    def __init__(self, arms: ArmController, goal: MoveArmGoal) -> None:
        super().__init__(arms, goal.arm, goal.timeout_s)
        self.goal = goal
        self._start_distance = 1e-9
        self._within_since: float | None = None

    def visuals(self) -> GoalVisuals:
        """Where the tool is to go (world frame)."""
        x, y, z = (float(v) for v in self.goal.target.position)
        return GoalVisuals(target_xyz=(x, y, z))

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        goal = self.goal
        self.arms.set_target(goal.arm, goal.target, goal.position_only, goal.max_linear_speed, goal.max_angular_speed)
        self._t0 = self._now = float(data.time)
        self._start_distance = max(self.arms.status(goal.arm).position_error, 1e-9)

    def stop_now(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._halt()

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        outcome = self._tick(data)
        if outcome is not None:
            return outcome
        status = self.arms.status(self.goal.arm)
        if status.unreachable:
            return SkillOutcome.aborted("UNREACHABLE", f"unreachable: {status.reason}")
        goal = self.goal
        within = (status.progress >= 1.0 and status.position_error <= goal.position_tolerance
                  and (goal.position_only or status.orientation_error <= goal.orientation_tolerance))
        if not within:
            self._within_since = None
        elif self._within_since is None:
            self._within_since = self._now
        elif self._now - self._within_since >= SETTLED_S:
            return SkillOutcome.succeeded("reached the target")
        return None

    def _errors(self) -> tuple[Pose, float, float]:
        """The tool pose and its position [m] and orientation [rad] errors against the goal's target.

        Against the goal, not the controller's target: after a cancel or a timeout the arm holds,
        and the result says how far from the goal it stopped.
        """
        tool = self.arms.status(self.goal.arm).tool_pose
        target = self.goal.target
        position_error = float(np.linalg.norm(target.position - tool.position))
        orientation_error = 0.0 if self.goal.position_only else \
            rotation_error(target.orientation_wxyz, tool.orientation_wxyz)
        return tool, position_error, orientation_error

    def _timeout_message(self) -> str:
        error = self._errors()[1]
        return f"{super()._timeout_message()}, {error * 1e3:.1f} mm from the target"

    def feedback(self, data: mujoco.MjData) -> Values:
        tool, position_error, orientation_error = self._errors()
        return {
            "current_pose": tool,
            "position_error": position_error,
            "orientation_error": orientation_error,
            "distance_remaining": position_error,
            "percent_complete": min(100.0, max(0.0, 100.0 * (1.0 - position_error / self._start_distance))),
            "elapsed": self._now - self._t0,
        }

    def result(self, data: mujoco.MjData) -> Values:
        tool, position_error, orientation_error = self._errors()
        return {"final_pose": tool, "final_position_error": position_error, "final_orientation_error": orientation_error}


class PickPlaceSkill(_ArmSkill):
    """Run the pick-and-place stages; the stage number is the skill's milestone (every change is reported)."""

    name = "pick_place"

    def __init__(self, pick_place: PickPlace, goal: PickPlaceGoal, timeout_s: float) -> None:
        super().__init__(pick_place.arm, goal.arm, timeout_s)
        self.pick_place = pick_place
        self.goal = goal
        self._last: PickPlaceProgress | None = None

    def _progress(self) -> PickPlaceProgress:
        """This goal's progress; after a reset (or a newer pick) dropped the run, the last one measured."""
        if self._last is None or not self._last.done:
            self._last = self.pick_place.progress()
        return self._last

    @property
    def milestone(self) -> int:
        return int(self._progress().stage)

    def visuals(self) -> GoalVisuals:
        """Where the object is to be placed (world frame)."""
        x, y, z = (float(v) for v in self.goal.place_position)
        return GoalVisuals(target_xyz=(x, y, z))

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.pick_place.start(self.goal)
        self._t0 = self._now = float(data.time)
        self._last = None

    def stop_now(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._halt()

    def _halt(self) -> None:
        self.pick_place.cancel()  # the arm holds where it is
        super()._halt()

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        progress = self._progress()
        if progress.done:
            if progress.success:
                return SkillOutcome.succeeded(f"placed within {progress.placement_error * 1e3:.1f} mm")
            code = PICK_PLACE_CODES.get(progress.failure, "SIM_FAULT")
            return SkillOutcome.aborted(code, f"{progress.failure.name.lower()}: {progress.reason}")
        return self._tick(data)

    def _timeout_message(self) -> str:
        return f"{super()._timeout_message()} in stage {self._progress().stage.name}"

    def feedback(self, data: mujoco.MjData) -> Values:
        progress = self._progress()
        return {
            "stage": int(progress.stage),
            "stage_name": progress.stage.name,
            "stage_progress": progress.stage_progress,
            "percent_complete": progress.percent,
            "object_pose": progress.object_pose,
            "elapsed": self._now - self._t0,
        }

    def result(self, data: mujoco.MjData) -> Values:
        progress = self._progress()
        return {"final_object_pose": progress.object_pose, "placement_error": progress.placement_error}
