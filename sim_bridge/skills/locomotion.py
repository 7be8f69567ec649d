"""Walk and NavigateToPose as skills in the control step, commanding the walking controller.

Both read the base pose from the simulation state at the control rate and command the walking
controller directly (what ``/cmd_vel`` does for teleoperation). A walk plans its last footsteps onto
its goal (:meth:`WalkingController.set_stop_point`) and ends when the robot stands there; a
navigation follows a planned path around the scene's static obstacles, replans when pushed off it
or blocked, and turns to the goal heading. "Safe" after a cancel or a timeout means: the robot has
closed its feet and stands (the walking controller reports STANDING), or it has fallen.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models import WalkingLimits
from robot_models.validation import check_range, is_number
from sim_bridge.errors import InvalidGoalError
from sim_bridge.locomotion import LocomotionMode, WalkingController
from sim_bridge.navigation import NoPathError, OccupancyGrid, PathFollower, plan_path
from sim_bridge.navigation.follower import FollowerCommand, wrap_angle
from sim_bridge.navigation.planner import path_length
from sim_bridge.skills.base import GoalVisuals, SkillOutcome, Values
from sim_bridge.state import Pose

LEGS = "legs"
ARRIVAL_TOLERANCE_M = 0.005  # the planned walking frame is this close to the goal: close the feet
MIN_APPROACH_SPEED_MPS = 0.08  # the deceleration toward the goal never commands less
APPROACH_DECELERATION = 0.4  # [m/s^2], below the gait's acceleration limit so the filter keeps up
HEADING_GAIN = 1.0  # [1/s] yaw-rate command per rad of heading error
LINE_GAIN = 0.5  # [rad/s per m] yaw-rate command per m of lateral error
MAX_CORRECTION_YAW_RATE = 0.3  # [rad/s]
STOP_TIMEOUT_S = 6.0  # a stop that has not ended standing after this long ends anyway [s]
FOLLOW_PERIOD_S = 0.05  # path following runs at 20 Hz of sim time (pure pursuit needs no more)
BLOCKED_AFTER_S = 15.0  # no progress along the path for this long: replan
PROGRESS_STEP_M = 0.05


def _base_pose(data: mujoco.MjData, qpos_adr: int) -> tuple[float, float, float]:
    """Base (x [m], y [m], yaw [rad]) from the free joint's qpos."""
    q = data.qpos[qpos_adr:qpos_adr + 7]
    w, x, y, z = (float(v) for v in q[3:7])
    return float(q[0]), float(q[1]), math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _pose(data: mujoco.MjData, qpos_adr: int) -> Pose:
    q = data.qpos[qpos_adr:qpos_adr + 7]
    return Pose(q[:3].copy(), q[3:7].copy())


def _free_joint_qpos(model: mujoco.MjModel, base_body: str) -> int:
    body = model.body(base_body).id
    return int(model.jnt_qposadr[model.body_jntadr[body]])


def _finite(**values: float) -> None:
    bad = [name for name, value in values.items() if not is_number(value)]
    if bad:
        raise InvalidGoalError(f"{', '.join(bad)} must be finite numbers")


@dataclass(frozen=True)
class WalkGoal:
    """Walk a distance along the heading the robot has when the goal starts.

    Attributes:
        distance_m: signed distance, forward positive [m], non-zero, within the robot's
            ``max_walk_distance_m``.
        speed_mps: pace [m/s] within the robot's ``speed_range_mps``; 0 = the ``walking_speed``
            setting (which may change while the goal runs).
        timeout_s: [s] of sim time; 0 = automatic (2.5 x the walking time + 10 s).
        limits: the robot's walking limits the goal is checked against.
    """

    distance_m: float
    speed_mps: float
    timeout_s: float
    limits: WalkingLimits

    def __post_init__(self) -> None:
        _finite(distance=self.distance_m, speed=self.speed_mps, timeout=self.timeout_s)
        longest = self.limits.max_walk_distance_m
        if not 0.0 < abs(self.distance_m) <= longest:
            raise InvalidGoalError(f"distance must be non-zero and within +-{longest:g} m, got {self.distance_m}")
        low, high = self.limits.speed_range_mps
        if self.speed_mps != 0.0 and not low <= self.speed_mps <= high:
            raise InvalidGoalError(f"speed must be in [{low}, {high}] m/s (0 = the walking_speed parameter), "
                                   f"got {self.speed_mps}")
        check_range("timeout (0 = automatic)", self.timeout_s, 0, unit="s", error=InvalidGoalError)


@dataclass(frozen=True)
class _Stop:
    """Why a locomotion skill is stopping, and what it reports once the robot stands."""

    outcome: SkillOutcome
    started_at: float  # sim time [s]


class _LocomotionSkill:
    """What Walk and NavigateToPose share: the walker, the base pose, falls, timeouts, a safe stop."""

    resource = LEGS
    pose_frame = "odom"

    def __init__(self, walker: WalkingController, base_body: str, settings: Mapping[str, float]) -> None:
        self.walker = walker
        self._base_body = base_body
        self._settings = dict(settings)
        self._qpos_adr = -1
        self._t0 = 0.0
        self._now = 0.0
        self._timeout = math.inf
        self._steps0 = 0
        self._stop: _Stop | None = None
        self._cancel = False
        self._failed_plan: NoPathError | None = None

    def _setting(self, name: str, default: float) -> float:
        return float(self._settings.get(name, default))

    def update_settings(self, settings: Mapping[str, float]) -> None:
        self._settings.update(settings)

    def request_cancel(self) -> None:
        self._cancel = True

    def stop_now(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._halt()

    def _halt(self) -> None:
        self.walker.set_velocity_command(0.0, 0.0, 0.0)
        self.walker.set_stop_point(None)

    def _begin(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._qpos_adr = _free_joint_qpos(model, self._base_body)
        self._t0 = self._now = float(data.time)
        self._steps0 = self.walker.status().steps_taken  # a fallen robot: the first update ends the goal FELL

    def _supervise(self, data: mujoco.MjData, fell_what: str) -> SkillOutcome | None:
        """Falls, cancel, timeout and the end of a stop; None while the goal's own logic should run."""
        self._now = float(data.time)
        status = self.walker.status()
        if status.fallen:
            self._halt()
            return SkillOutcome.aborted("FELL", f"fell {fell_what}: {status.message}")
        stop = self._stop
        if stop is None:
            if self._cancel:
                self._stop_with(SkillOutcome.canceled("canceled: the robot stopped and stands"))
            elif self._now - self._t0 > self._timeout:
                self._stop_with(SkillOutcome.aborted("TIMEOUT", self._timeout_message()))
            return None
        self.walker.set_velocity_command(0.0, 0.0, 0.0)
        if status.mode is LocomotionMode.STANDING or self._now - stop.started_at > STOP_TIMEOUT_S:
            self.walker.set_stop_point(None)
            return stop.outcome
        return None

    def _stop_with(self, outcome: SkillOutcome) -> None:
        if self._stop is None:
            self._stop = _Stop(outcome, self._now)
            self.walker.set_velocity_command(0.0, 0.0, 0.0)

    def _timeout_message(self) -> str:
        return f"timed out after {self._timeout:.1f} s of sim time"

    def _steps(self) -> int:
        return self.walker.status().steps_taken - self._steps0


class WalkSkill(_LocomotionSkill):
    """Walk a distance straight ahead or back, holding the start heading and line.

    Settings: ``walking_speed`` [m/s] (used when the goal's speed is 0; may change while it runs).
    """

    name = "walk"

    def __init__(self, walker: WalkingController, base_body: str, goal: WalkGoal, settings: Mapping[str, float]) -> None:
        super().__init__(walker, base_body, settings)
        self.goal = goal
        self._start = (0.0, 0.0)
        self._heading = 0.0
        self._forward = (1.0, 0.0)

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._begin(model, data)
        x, y, yaw = _base_pose(data, self._qpos_adr)
        self._start, self._heading = (x, y), yaw
        self._forward = (math.cos(yaw), math.sin(yaw))
        d = self.goal.distance_m
        # The walking frame stands between the feet, not under the pelvis: move it by d.
        fx, fy = self.walker.feet_midpoint(data)
        self.walker.set_stop_point((fx + d * self._forward[0], fy + d * self._forward[1]))
        self._timeout = self.goal.timeout_s or abs(d) / self._speed() * 2.5 + 10.0

    def _speed(self) -> float:
        return self.goal.speed_mps or self._setting("walking_speed", self.goal.limits.default_speed_mps)

    def _walked(self, data: mujoco.MjData) -> tuple[float, float, float]:
        """(distance along the start heading [m], lateral offset [m], heading error [rad])."""
        x, y, yaw = _base_pose(data, self._qpos_adr)
        dx, dy = x - self._start[0], y - self._start[1]
        fx, fy = self._forward
        return dx * fx + dy * fy, fx * dy - fy * dx, wrap_angle(self._heading - yaw)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        walked, lateral, yaw_error = self._walked(data)
        outcome = self._supervise(data, f"after {walked:.2f} m")
        if outcome is not None or self._stop is not None:
            return outcome
        sign = 1.0 if self.goal.distance_m > 0 else -1.0
        stepped = self._steps() > 0  # the walking frame is planned from the first footstep on
        remaining = self.walker.stop_point_remaining() if stepped else abs(self.goal.distance_m)
        if stepped and abs(remaining) <= ARRIVAL_TOLERANCE_M:
            self._stop_with(SkillOutcome.succeeded(""))  # the message is written when it stands
            return None
        to_go = abs(remaining)
        speed = min(self._speed(), max(MIN_APPROACH_SPEED_MPS, math.sqrt(2.0 * APPROACH_DECELERATION * to_go)))
        wz = min(max(HEADING_GAIN * yaw_error - sign * LINE_GAIN * lateral, -MAX_CORRECTION_YAW_RATE), MAX_CORRECTION_YAW_RATE)
        self.walker.set_velocity_command(sign * speed, 0.0, wz)
        return None

    def _supervise(self, data: mujoco.MjData, fell_what: str) -> SkillOutcome | None:
        outcome = super()._supervise(data, fell_what)
        if outcome is not None and outcome.code == "SUCCESS":
            walked = self._walked(data)[0]
            return SkillOutcome.succeeded(f"walked {walked:.3f} m of {self.goal.distance_m:.3f} m")
        if outcome is not None and outcome.code == "TIMEOUT":
            walked = self._walked(data)[0]
            return SkillOutcome.aborted("TIMEOUT", f"{self._timeout_message()} having walked {walked:.2f} m")
        return outcome

    def feedback(self, data: mujoco.MjData) -> Values:
        walked = self._walked(data)[0]
        status = self.walker.status()
        return {
            "distance_walked": walked,
            "current_speed": status.measured.vx,
            "steps_taken": max(status.steps_taken - self._steps0, 0),
            "percent_complete": float(np.clip(100.0 * walked / self.goal.distance_m, 0.0, 100.0)),
            "elapsed": self._now - self._t0,
        }

    def result(self, data: mujoco.MjData) -> Values:
        return {"final_distance": self._walked(data)[0], "final_pose": _pose(data, self._qpos_adr)}


@dataclass(frozen=True)
class NavigateGoal:
    """Walk to a pose on the floor, around the scene's static obstacles.

    Attributes:
        x_m, y_m: goal position in the world (= odom = map) frame [m].
        yaw_rad: goal heading [rad].
    """

    x_m: float
    y_m: float
    yaw_rad: float

    def __post_init__(self) -> None:
        _finite(x=self.x_m, y=self.y_m, yaw=self.yaw_rad)


class NavigateSkill(_LocomotionSkill):
    """Plan a path on the obstacle grid, follow it (pure pursuit), turn to the goal heading.

    Settings: ``walking_speed`` [m/s], ``max_yaw_rate`` [rad/s], ``robot_radius`` and
    ``obstacle_detection_threshold`` [m] (obstacles are inflated by their sum), ``xy_goal_tolerance``
    [m], ``yaw_goal_tolerance`` [rad], ``replan_distance`` [m].
    """

    name = "navigate_to_pose"

    def __init__(self, walker: WalkingController, base_body: str, grid: OccupancyGrid, goal: NavigateGoal,
                 settings: Mapping[str, float]) -> None:
        super().__init__(walker, base_body, settings)
        self.goal = goal
        self._grid = grid
        self._inflated: OccupancyGrid | None = None
        self._follower: PathFollower | None = None
        self._command = FollowerCommand(0.0, 0.0, math.inf, 0.0, "follow")
        self._next_follow = 0.0
        self.recoveries = 0
        self._best_remaining = math.inf
        self._last_progress = 0.0
        self.path: list[tuple[float, float]] = []
        self._keep_out: tuple[tuple[float, float], ...] | None = None  # the inflated grid's occupied cells, for a viewer

    def visuals(self) -> GoalVisuals:
        """The planned path and the goal pose (world frame)."""
        goal = (self.goal.x_m, self.goal.y_m, self.goal.yaw_rad)
        steps = tuple((float(x), float(y), float(yaw)) for x, y, yaw in self.walker.planned_footsteps())
        cells: tuple[tuple[float, float], ...] = ()
        if self._inflated is not None:
            if self._keep_out is None:
                self._keep_out = self._inflated.occupied_centers()
            cells = self._keep_out
        return GoalVisuals(path_xy=tuple((float(x), float(y)) for x, y in self.path), goal_pose=goal, footsteps=steps,
                           keep_out_xy=cells, keep_out_cell_m=self._grid.resolution if cells else 0.0)

    def _plan(self, x: float, y: float) -> None:
        """Plan from (x, y) and start following. Raises NoPathError."""
        inflation = self._setting("robot_radius", 0.30) + self._setting("obstacle_detection_threshold", 0.15)
        if self._inflated is None:
            self._inflated = self._grid.inflated(inflation)
        self.path = plan_path(self._inflated, (x, y), (self.goal.x_m, self.goal.y_m))
        self._follower = PathFollower(self.path, self.goal.yaw_rad, xy_tolerance=self._setting("xy_goal_tolerance", 0.15),
                                      yaw_tolerance=self._setting("yaw_goal_tolerance", 0.15))
        self._best_remaining, self._last_progress = math.inf, self._now

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._begin(model, data)
        self.walker.set_stop_point(None)
        x, y, _ = _base_pose(data, self._qpos_adr)
        try:
            self._plan(x, y)
        except NoPathError as error:
            self._failed_plan = error
            return
        self._timeout = path_length(self.path) / self._setting("walking_speed", 0.3) * 3.0 + 30.0

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        if self._failed_plan is not None:
            return self._no_path(self._failed_plan)
        outcome = self._supervise(data, "while navigating")
        if outcome is not None or self._stop is not None:
            if outcome is not None and outcome.code == "SUCCESS":
                x, y, _ = _base_pose(data, self._qpos_adr)
                error = math.dist((x, y), (self.goal.x_m, self.goal.y_m))
                return SkillOutcome.succeeded(f"arrived {error:.2f} m from the goal after {self.recoveries} recoveries")
            return outcome
        if self._now + 1e-9 < self._next_follow:
            return None
        self._next_follow = self._now + FOLLOW_PERIOD_S
        assert self._follower is not None
        x, y, yaw = _base_pose(data, self._qpos_adr)
        speed = self._setting("walking_speed", 0.3)
        command = self._follower.command(x, y, yaw, speed, self._setting("max_yaw_rate", 0.6))
        self._command = command
        if command.distance_remaining < self._best_remaining - PROGRESS_STEP_M:
            self._best_remaining, self._last_progress = command.distance_remaining, self._now
        blocked = command.phase == "follow" and self._now - self._last_progress > BLOCKED_AFTER_S
        if command.cross_track_error > self._setting("replan_distance", 0.6) or blocked:
            self.recoveries += 1
            try:
                self._plan(x, y)
            except NoPathError as error:
                self._stop_with(SkillOutcome.aborted("NO_VALID_PATH", f"replanning failed: {error}"))
            return None
        if command.phase == "arrived":
            self._stop_with(SkillOutcome.succeeded(""))
            return None
        self.walker.set_velocity_command(command.vx, command.vy, command.wz)
        return None

    def _no_path(self, error: NoPathError) -> SkillOutcome:
        inflated = self._inflated
        goal_blocked = inflated is not None and not inflated.is_free(self.goal.x_m, self.goal.y_m)
        code = "GOAL_IN_OBSTACLE" if goal_blocked else "NO_VALID_PATH"
        return SkillOutcome.aborted(code, str(error))

    def _timeout_message(self) -> str:
        return f"timed out after {self._timeout:.0f} s of sim time"

    def feedback(self, data: mujoco.MjData) -> Values:
        remaining = self._command.distance_remaining
        if not math.isfinite(remaining):
            remaining = path_length(self.path) if self.path else 0.0
        speed = max(self._setting("walking_speed", 0.3), 1e-3)
        return {
            "current_pose": _pose(data, self._qpos_adr),
            "navigation_time": self._now - self._t0,
            "estimated_time_remaining": remaining / speed,
            "number_of_recoveries": self.recoveries,
            "distance_remaining": remaining,
            "message": self._command.phase if self._stop is None else "stopping",
        }

    def result(self, data: mujoco.MjData) -> Values:
        return {"final_pose": _pose(data, self._qpos_adr)}
