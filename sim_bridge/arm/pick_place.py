"""Pick-and-place skill: stages a physical friction grasp through the arm controller.

The object is held only by finger contact and friction (no weld, no teleport). The skill runs in
the control loop: install :class:`PickPlace` in ``Slot.ARM`` in place of its
:class:`~sim_bridge.arm.ArmController`; it forwards to the controller and advances its stages
before the controller's update, on the measured state. Poll :meth:`PickPlace.progress`.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from robot_models import ArmScene
from robot_models.validation import check_range, is_number
from sim_bridge.arm.controller import ArmController
from sim_bridge.arm.description import check_arm_name
from sim_bridge.arm.poses import quat_to_mat
from sim_bridge.errors import InvalidGoalError, UnknownNameError
from sim_bridge.state import Pose


class PickPlaceStage(enum.IntEnum):
    """Stages in execution order."""

    APPROACH = 0
    DESCEND = 1
    GRASP = 2
    LIFT = 3
    TRANSPORT = 4
    PLACE = 5
    RELEASE = 6
    RETREAT = 7


class PickPlaceFailure(enum.IntEnum):
    """Outcome codes (NONE while running or on success)."""

    NONE = 0
    UNREACHABLE = 1
    GRASP_MISSED = 2
    OBJECT_SLIPPED = 3
    OBJECT_DROPPED = 4
    PLACEMENT_INACCURATE = 5
    TIMEOUT = 6
    CANCELED = 7


@dataclass(frozen=True)
class PickPlaceGoal:
    """What to pick and where to put it.

    Attributes:
        object_name: a graspable object of the scene (``RobotSpec.objects``).
        place_position: where the object goes, world frame [m]: x, y of its centre on the table, and
            z either the table top (where it rests) or the height of its centre resting there,
            within ``PLACE_Z_TOLERANCE_M``; it is placed resting on the table (see ``place_problem``).
        place_yaw: object yaw at the place pose [rad]; None keeps the yaw it has when grasped
            (modulo the box's quarter-turn symmetry).
        arm: arm with a gripper.
        approach_height: tool height above the grasp point before descending [m].
        lift_height: height the object is lifted above the table [m].
        transport_speed: tool speed in free motion [m/s].
        contact_speed: tool speed near the table (descend, place) [m/s].
        grip_force: squeeze force per finger [N].
        placement_tolerance: largest placement error counted as success [m].
    """

    object_name: str
    place_position: tuple[float, float, float]
    place_yaw: float | None = None
    arm: str = "arm"
    approach_height: float = 0.10
    lift_height: float = 0.15
    transport_speed: float = 0.4
    contact_speed: float = 0.15
    grip_force: float = 20.0
    placement_tolerance: float = 0.005

    def __post_init__(self) -> None:
        for name in ("approach_height", "lift_height", "transport_speed", "contact_speed", "grip_force", "placement_tolerance"):
            check_range(name, getattr(self, name), 0, low_open=True, error=InvalidGoalError)
        if len(self.place_position) != 3 or not all(is_number(v) for v in self.place_position):
            raise InvalidGoalError(f"place_position needs 3 finite values [m], got {self.place_position}")


@dataclass(frozen=True)
class PickPlaceProgress:
    """Feedback and result of a pick-and-place.

    Attributes:
        stage: current (or last) stage.
        stage_progress: fraction of the stage done, in [0, 1].
        percent: overall progress [%].
        object_pose: measured object pose, world frame.
        done: the skill ended (success or failure).
        success: ended with the object placed within tolerance.
        failure: failure code (NONE while running or on success).
        reason: human-readable failure reason ("" otherwise).
        placement_error: distance object centre -> place position [m] (NaN before release).
        object_lift: highest rise of the object above its start while carried [m].
    """

    stage: PickPlaceStage
    stage_progress: float
    percent: float
    object_pose: Pose
    done: bool
    success: bool
    failure: PickPlaceFailure
    reason: str
    placement_error: float
    object_lift: float


@dataclass
class _Run:
    goal: PickPlaceGoal
    object_body: int
    start_position: np.ndarray
    stage: PickPlaceStage = PickPlaceStage.APPROACH
    stage_started: float = 0.0
    stage_commanded: bool = False
    stage_progress: float = 0.0
    grasp_offset_in_tool: np.ndarray = field(default_factory=lambda: np.zeros(3))
    grasp_yaw: float = 0.0
    place_tool_yaw: float = 0.0
    contact_history: list[bool] = field(default_factory=list)
    no_contact_ticks: int = 0
    object_lift: float = 0.0
    done: bool = False
    success: bool = False
    failure: PickPlaceFailure = PickPlaceFailure.NONE
    reason: str = ""
    placement_error: float = math.nan


PLACE_Z_TOLERANCE_M = 0.01  # a place height this close to the table top or to the resting centre is honoured


def place_problem(scene: ArmScene, position: tuple[float, float, float] | np.ndarray) -> str:
    """Why an object cannot be placed at ``position`` (world frame [m]); "" when it can.

    Objects are placed resting on the table: x and y must keep the whole object on the table top,
    and z must say "on the table": the table top's height or the resting centre's (table top + half
    the object), each within ``PLACE_Z_TOLERANCE_M``. A place in mid-air or under the table cannot be
    honoured and is refused rather than quietly moved.
    """
    x, y, z = (float(v) for v in position)
    if not all(math.isfinite(v) for v in (x, y, z)):
        return f"place position ({x}, {y}, {z}) must be finite"
    top, half = scene.objects_table_top_z, scene.object_half_size
    if top is None or scene.table_xy_bounds is None:
        return "this scene has no table to place objects on"
    bounds = scene.table_xy_bounds
    x_low, x_high, y_low, y_high = bounds[0] + half, bounds[1] - half, bounds[2] + half, bounds[3] - half
    if not (x_low <= x <= x_high and y_low <= y <= y_high):
        return (f"place position ({x:.3f}, {y:.3f}) is off the table: x must be in [{x_low:.3f}, {x_high:.3f}] m "
                f"and y in [{y_low:.3f}, {y_high:.3f}] m (world frame)")
    if not top - PLACE_Z_TOLERANCE_M <= z <= top + half + PLACE_Z_TOLERANCE_M:
        return (f"place height z = {z:.3f} m (world frame) cannot be honoured: objects are placed resting on the "
                f"table; give z = {top:.3f} m (the table top) or {top + half:.3f} m (the resting centre), "
                f"within {PLACE_Z_TOLERANCE_M * 100:g} cm")
    return ""


GRIP_SAFETY = 4.0  # a grip must hold this many times the object's weight by friction


def min_grip_force_n(model: mujoco.MjModel, object_name: str) -> float:
    """The weakest squeeze per finger [N] that holds ``object_name`` with :data:`GRIP_SAFETY`.

    Two fingers hold by friction: 2 mu F >= safety m g, with mu the object's sliding friction (MuJoCo
    takes the larger of the two surfaces', so this is on the safe side).
    """
    body = model.body(object_name)
    geoms = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) == body.id]
    mu = max((float(model.geom_friction[g][0]) for g in geoms), default=1.0) or 1.0
    gravity = float(np.linalg.norm(model.opt.gravity))
    return GRIP_SAFETY * float(body.mass[0]) * gravity / (2.0 * mu)


def _tool_down_quat(yaw: float) -> np.ndarray:
    """Tool z axis pointing down, tool x axis at ``yaw`` [rad] about world z: Rz(yaw) Rx(pi)."""
    return np.array([0.0, math.cos(0.5 * yaw), math.sin(0.5 * yaw), 0.0])


def _yaw_of(quat_wxyz: np.ndarray) -> float:
    mat = quat_to_mat(quat_wxyz)
    return math.atan2(mat[1, 0], mat[0, 0])


def _nearest_quarter_turn(yaw: float, reference: float) -> float:
    """The angle ``yaw + k pi/2`` closest to ``reference`` [rad] (a box looks the same every quarter turn)."""
    return reference + ((yaw - reference + math.pi / 4) % (math.pi / 2)) - math.pi / 4


class PickPlace:
    """Pick an object with a friction grasp and place it; a ``Slot.ARM`` controller wrapping an ArmController.

    Args:
        arm_controller: the scene's arm controller (the skill drives it; it must not also be
            installed in a slot).
        table_top_z: height of the surface objects rest on [m] (default from the scene).
        stage_timeout: longest time a stage may take [s].
    """

    SLIP_TOLERANCE = 0.010  # [m] drift of the object in the tool frame counted as a slip
    MIN_GRASP_TIME = 0.3  # [s]
    GRASP_CONTACT_TICKS = 25  # window of control steps in which the fingers must touch the object 80 % of the time
    LOST_CONTACT_TICKS = 10  # control steps without finger contact counted as a drop (contacts chatter briefly)
    PLACE_CLEARANCE = 0.002  # [m] height above the table the object is let go from
    RELEASE_CLEARANCE = 0.03  # [m] opening beyond the object size when releasing

    def __init__(self, arm_controller: ArmController, table_top_z: float | None = None, stage_timeout: float = 6.0) -> None:
        self.arm = arm_controller
        self.robot = arm_controller.robot
        scene = arm_controller.robot.arm_scene
        z = scene.objects_table_top_z if table_top_z is None else table_top_z
        if z is None:
            raise InvalidGoalError(f"robot {self.robot.name!r} has no table: pass table_top_z")
        self.table_top_z = float(z)
        self.half_size = scene.object_half_size
        self.stage_timeout = float(stage_timeout)
        self._run: _Run | None = None
        self._data: mujoco.MjData | None = None
        self._model: mujoco.MjModel | None = None

    # ----- Controller protocol (forwarded) ---------------------------------------------------
    @property
    def active(self) -> bool:
        return self.arm.active or (self._run is not None and not self._run.done)

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._model, self._data = model, data
        self._run = None
        self.arm.reset(model, data)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        self._model, self._data = model, data
        if self._run is not None and not self._run.done:
            self._advance(self._run, data)
        self.arm.update(model, data, control_dt)

    # ----- skill -----------------------------------------------------------------------------
    def start(self, goal: PickPlaceGoal) -> None:
        """Begin a pick-and-place, preempting a running one.

        Raises:
            UnknownNameError: unknown object or arm (the message lists the valid names).
            InvalidGoalError: the arm has no gripper or the place position is off the table.
        """
        if goal.object_name not in self.robot.objects:
            raise UnknownNameError(f"unknown object {goal.object_name!r}; objects: {', '.join(self.robot.objects) or 'none'}")
        info = check_arm_name(self.arm.arms, goal.arm)
        if not info.gripper_joints:
            with_gripper = [a for a, i in self.arm.arms.items() if i.gripper_joints]
            raise InvalidGoalError(f"arm {goal.arm!r} has no gripper; arms with a gripper: {', '.join(with_gripper) or 'none'}")
        problem = place_problem(self.arm.robot.arm_scene, goal.place_position)
        if problem:
            raise InvalidGoalError(problem)
        data = self._require_data()
        assert self._model is not None  # set with the data
        body = self._model.body(goal.object_name).id
        self._run = _Run(goal=goal, object_body=body, start_position=data.xpos[body].copy(), stage_started=float(data.time))

    def cancel(self) -> None:
        """Stop now: the arm holds where it is, the gripper keeps its command; ends CANCELED."""
        if self._run is not None and not self._run.done:
            self.arm.hold(self._run.goal.arm)
            self._finish(self._run, PickPlaceFailure.CANCELED, "canceled")

    def progress(self) -> PickPlaceProgress:
        """Feedback (while running) or result (when ``done``)."""
        run = self._run
        if run is None:
            raise InvalidGoalError("no pick-and-place was started")
        data = self._require_data()
        stage_progress = 1.0 if run.success else run.stage_progress
        percent = 100.0 * (int(run.stage) + stage_progress) / len(PickPlaceStage)
        return PickPlaceProgress(
            stage=run.stage, stage_progress=stage_progress, percent=percent,
            object_pose=Pose(data.xpos[run.object_body].copy(), data.xquat[run.object_body].copy()),
            done=run.done, success=run.success, failure=run.failure, reason=run.reason,
            placement_error=run.placement_error, object_lift=run.object_lift,
        )

    # ----- internals -------------------------------------------------------------------------
    def _require_data(self) -> mujoco.MjData:
        if self._data is None:
            raise InvalidGoalError("the pick-and-place skill is not installed: Simulation.set_controller(Slot.ARM, skill)")
        return self._data

    def _finish(self, run: _Run, failure: PickPlaceFailure, reason: str) -> None:
        run.done, run.failure, run.reason, run.success = True, failure, reason, failure == PickPlaceFailure.NONE

    def _next(self, run: _Run, data: mujoco.MjData) -> None:
        run.stage = PickPlaceStage(int(run.stage) + 1)
        run.stage_started, run.stage_commanded, run.stage_progress = float(data.time), False, 0.0

    def _move(self, run: _Run, position: np.ndarray, yaw: float, speed: float) -> bool:
        self.arm.set_target(run.goal.arm, Pose(np.asarray(position, dtype=float), _tool_down_quat(yaw)), False, speed, 2.0)
        status = self.arm.status(run.goal.arm)
        if status.unreachable:
            self.arm.hold(run.goal.arm)
            self._finish(run, PickPlaceFailure.UNREACHABLE, f"{run.stage.name}: {status.reason}")
            return False
        return True

    def _arrived(self, run: _Run, tolerance: float, still: bool) -> bool:
        status = self.arm.status(run.goal.arm)
        run.stage_progress = status.progress
        if status.unreachable:
            self._finish(run, PickPlaceFailure.UNREACHABLE, f"{run.stage.name}: {status.reason}")
            return False
        if still:
            return status.settled
        return status.progress >= 1.0 and status.position_error <= tolerance and status.orientation_error <= 0.02

    def _tool(self, data: mujoco.MjData, run: _Run) -> tuple[np.ndarray, np.ndarray]:
        info = self.arm.arms[run.goal.arm]
        return data.site_xpos[info.site_id].copy(), data.site_xmat[info.site_id].reshape(3, 3).copy()

    def _check_held(self, run: _Run, data: mujoco.MjData) -> bool:
        """Fail with SLIPPED or DROPPED when the object does not follow the gripper."""
        status = self.arm.status(run.goal.arm)
        assert status.gripper is not None
        run.no_contact_ticks = 0 if run.goal.object_name in status.gripper.contact_bodies else run.no_contact_ticks + 1
        if run.no_contact_ticks >= self.LOST_CONTACT_TICKS:
            self._finish(run, PickPlaceFailure.OBJECT_DROPPED,
                         f"{run.stage.name}: the fingers lost contact with {run.goal.object_name!r} (dropped)")
            return False
        tool_pos, tool_mat = self._tool(data, run)
        offset = tool_mat.T @ (data.xpos[run.object_body] - tool_pos)
        drift = float(np.linalg.norm(offset - run.grasp_offset_in_tool))
        if drift > self.SLIP_TOLERANCE:
            self._finish(run, PickPlaceFailure.OBJECT_SLIPPED,
                         f"{run.stage.name}: {run.goal.object_name!r} slipped {drift * 1000:.1f} mm in the gripper")
            return False
        run.object_lift = max(run.object_lift, float(data.xpos[run.object_body][2] - run.start_position[2]))
        return True

    def _elapsed(self, run: _Run, data: mujoco.MjData) -> float:
        return float(data.time) - run.stage_started

    def _advance(self, run: _Run, data: mujoco.MjData) -> None:
        if self._elapsed(run, data) > self.stage_timeout:
            self.arm.hold(run.goal.arm)
            self._finish(run, PickPlaceFailure.TIMEOUT, f"{run.stage.name} took longer than {self.stage_timeout:.1f} s")
            return
        goal, stage = run.goal, run.stage
        object_position = data.xpos[run.object_body]
        size = 2.0 * self.half_size
        if stage == PickPlaceStage.APPROACH:
            if not run.stage_commanded:
                # Of the box's four equivalent yaws, grasp at the one nearest tool yaw 0 (mid wrist range).
                run.grasp_yaw = _nearest_quarter_turn(_yaw_of(data.xquat[run.object_body]), 0.0)
                opening = min(size + 2 * self.RELEASE_CLEARANCE, self.arm.robot.arm_scene.gripper_open_width)
                self.arm.set_gripper(goal.arm, opening, goal.grip_force)
                above = object_position + np.array([0.0, 0.0, goal.approach_height])
                run.stage_commanded = self._move(run, above, run.grasp_yaw, goal.transport_speed)
            elif self._arrived(run, 0.003, still=False):
                self._next(run, data)
        elif stage == PickPlaceStage.DESCEND:
            if not run.stage_commanded:
                run.stage_commanded = self._move(run, object_position.copy(), run.grasp_yaw, goal.contact_speed)
            elif self._arrived(run, 0.001, still=True):
                self._next(run, data)
        elif stage == PickPlaceStage.GRASP:
            if not run.stage_commanded:
                self.arm.set_gripper(goal.arm, 0.0, goal.grip_force)
                run.stage_commanded, run.contact_history = True, []
                return
            status = self.arm.status(goal.arm)
            assert status.gripper is not None
            run.contact_history.append(goal.object_name in status.gripper.contact_bodies)
            recent = run.contact_history[-self.GRASP_CONTACT_TICKS:]
            held = len(recent) == self.GRASP_CONTACT_TICKS and sum(recent) >= 0.8 * self.GRASP_CONTACT_TICKS
            elapsed = self._elapsed(run, data)
            run.stage_progress = min(elapsed / self.MIN_GRASP_TIME, 1.0)
            if elapsed >= self.MIN_GRASP_TIME and status.gripper.width < 0.5 * size:
                self._finish(run, PickPlaceFailure.GRASP_MISSED,
                             f"GRASP: the fingers closed to {status.gripper.width * 1000:.1f} mm "
                             f"without holding {goal.object_name!r}")
                return
            if elapsed >= self.MIN_GRASP_TIME and held:
                tool_pos, tool_mat = self._tool(data, run)
                run.grasp_offset_in_tool = tool_mat.T @ (object_position - tool_pos)
                self._next(run, data)
        elif stage == PickPlaceStage.LIFT:
            if not self._check_held(run, data):
                return
            if not run.stage_commanded:
                tool_pos, _ = self._tool(data, run)
                lift_z = self.table_top_z + self.half_size + goal.lift_height
                lifted = np.array([tool_pos[0], tool_pos[1], lift_z])
                run.stage_commanded = self._move(run, lifted, run.grasp_yaw, goal.contact_speed)
            elif self._arrived(run, 0.003, still=False):
                self._next(run, data)
        elif stage == PickPlaceStage.TRANSPORT:
            if not self._check_held(run, data):
                return
            if not run.stage_commanded:
                object_yaw = _yaw_of(data.xquat[run.object_body])
                desired = object_yaw if goal.place_yaw is None else goal.place_yaw
                # Tool yaw that gives the object its place yaw, then the quarter turn nearest the grasp yaw.
                run.place_tool_yaw = _nearest_quarter_turn(desired + (run.grasp_yaw - object_yaw), run.grasp_yaw)
                target = self._tool_for_object(run, self.table_top_z + self.half_size + goal.lift_height)
                run.stage_commanded = self._move(run, target, run.place_tool_yaw, goal.transport_speed)
            elif self._arrived(run, 0.002, still=False):
                self._next(run, data)
        elif stage == PickPlaceStage.PLACE:
            if not self._check_held(run, data):
                return
            if not run.stage_commanded:
                target = self._tool_for_object(run, self.table_top_z + self.half_size + self.PLACE_CLEARANCE)
                run.stage_commanded = self._move(run, target, run.place_tool_yaw, goal.contact_speed)
            else:
                resting = object_position[2] <= self.table_top_z + self.half_size + 0.0005
                if self._arrived(run, 0.0015, still=False) or (resting and run.stage_progress >= 1.0):
                    self._next(run, data)
        elif stage == PickPlaceStage.RELEASE:
            if not run.stage_commanded:
                self.arm.set_gripper(goal.arm, size + self.RELEASE_CLEARANCE, goal.grip_force)
                run.stage_commanded = True
                return
            status = self.arm.status(goal.arm)
            assert status.gripper is not None
            run.stage_progress = min(max((status.gripper.width - size) / self.RELEASE_CLEARANCE, 0.0), 1.0)
            if status.gripper.width >= size + 0.8 * self.RELEASE_CLEARANCE:
                self._next(run, data)
        elif stage == PickPlaceStage.RETREAT:
            if not run.stage_commanded:
                tool_pos, _ = self._tool(data, run)
                above = tool_pos + np.array([0.0, 0.0, goal.approach_height])
                run.stage_commanded = self._move(run, above, run.place_tool_yaw, goal.transport_speed)
            elif self._arrived(run, 0.003, still=False):
                place = self._place_position(run)
                run.placement_error = float(np.linalg.norm(data.xpos[run.object_body] - place))
                run.stage_progress = 1.0
                if run.placement_error <= goal.placement_tolerance:
                    self._finish(run, PickPlaceFailure.NONE, "")
                else:
                    self._finish(run, PickPlaceFailure.PLACEMENT_INACCURATE,
                                 f"placed {run.placement_error * 1000:.1f} mm from the place position "
                                 f"(tolerance {goal.placement_tolerance * 1000:.1f} mm)")

    def _place_position(self, run: _Run) -> np.ndarray:
        x, y, _ = run.goal.place_position
        return np.array([x, y, self.table_top_z + self.half_size])

    def _tool_for_object(self, run: _Run, object_z: float) -> np.ndarray:
        """Tool position that puts the object's centre over the place position at height ``object_z`` [m]."""
        place = self._place_position(run)
        place[2] = object_z
        tool_mat = quat_to_mat(_tool_down_quat(run.place_tool_yaw))
        return place - tool_mat @ run.grasp_offset_in_tool
