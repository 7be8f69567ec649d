"""In-loop arm controller: smooth Cartesian reference, mink IK on a private configuration, joint targets.

Runs in the simulation's ``Slot.ARM`` at the control rate, between ``mj_step1`` and ``mj_step2``.
It writes ``data.ctrl`` only for the actuators of the arms (and grippers) it drives, so another
controller (e.g. walking) can own the legs at the same time. Not thread-safe: call its methods
from the thread that steps the simulation (or under the lock that guards stepping).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

from robot_models import RobotSpec
from sim_bridge.arm.description import ArmInfo, arm_infos, check_arm_name
from sim_bridge.arm.kinematics import ArmKinematics
from sim_bridge.arm.poses import interpolate_quat, mat_to_quat, rotation_error, validate_pose
from sim_bridge.arm.types import ArmControllerConfig, ArmMode, ArmStatus, GripperStatus
from sim_bridge.errors import InvalidGoalError, SimError
from sim_bridge.state import Pose

MAX_LINEAR_SPEED = 2.0  # [m/s]
MAX_ANGULAR_SPEED = 2.0 * math.pi  # [rad/s]
MIN_JERK_PEAK = 1.875  # peak / mean speed of a minimum-jerk profile


def _min_jerk(fraction: float) -> float:
    tau = min(max(fraction, 0.0), 1.0)
    return tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau)


@dataclass
class _ArmState:
    """Mutable state of one arm's tracking loop (private)."""

    mode: ArmMode = ArmMode.IDLE
    q_cmd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    start: Pose | None = None
    target: Pose | None = None
    reference: Pose | None = None
    position_only: bool = False
    duration: float = 0.0
    elapsed: float = 0.0
    stall_time: float = 0.0
    unreachable: bool = False
    reason: str = ""
    gripper_active: bool = False
    gripper_width: float = 0.0
    gripper_force: float = 0.0


class ArmController:
    """Cartesian tracking of every arm of a robot, plus its grippers (the ``Slot.ARM`` controller).

    Args:
        robot: the robot scene (one controller per simulation).
        config: tuning; defaults in :class:`ArmControllerConfig`.
    """

    def __init__(self, robot: RobotSpec, config: ArmControllerConfig | None = None) -> None:
        self.robot = robot
        self.config = config or ArmControllerConfig()
        # The IK model (~0.3 CPU-s for the G1's two arms) is built at the first arm goal, not with /sim: most runs
        # never move an arm, and every bring-up paid it at start.
        self._kinematics: ArmKinematics | None = None
        self.arms: dict[str, ArmInfo] = arm_infos(robot, robot.arm_scene)
        self._state = {arm: _ArmState() for arm in self.arms}
        self._model: mujoco.MjModel | None = None
        self._data: mujoco.MjData | None = None
        self._control_dt = robot.control_timestep
        self._ik_seconds: list[float] = []
        self._finger_bodies = {
            arm: {int(robot.model.jnt_bodyid[robot.model.joint(j).id]) for j in info.gripper_joints}
            for arm, info in self.arms.items()
        }

    @property
    def kinematics(self) -> ArmKinematics:
        """The arms' IK model and problems, built on first use (from the thread that steps, or under its lock)."""
        if self._kinematics is None:
            self._kinematics = ArmKinematics(self.robot, self.config)
        return self._kinematics

    # ----- Controller protocol -------------------------------------------------------------
    @property
    def active(self) -> bool:
        return any(s.mode != ArmMode.IDLE or s.gripper_active for s in self._state.values())

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Forget every goal; all arms go idle (the actuators keep the keyframe's targets)."""
        self._model, self._data = model, data
        self._state = {arm: _ArmState() for arm in self.arms}

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        self._model, self._data, self._control_dt = model, data, control_dt
        for arm, state in self._state.items():
            info = self.arms[arm]
            if state.mode == ArmMode.MOVING:
                self._track(info, state, data, control_dt)
            if state.mode != ArmMode.IDLE:
                self._write_arm(model, data, info, state)
            if state.gripper_active:
                self._write_gripper(model, data, info, state)

    # ----- commands ------------------------------------------------------------------------
    def set_target(
        self,
        arm: str,
        target_pose_world: Pose,
        position_only: bool = False,
        max_linear_speed: float | None = None,
        max_angular_speed: float | None = None,
    ) -> None:
        """Move the arm's tool point to a world pose along a straight line, preempting any goal.

        The tracking loop moves a reference with a minimum-jerk profile whose peak speeds stay
        under the limits, and keeps tracking the target after arrival. If the target is outside
        the workspace or the IK cannot reach it, the arm holds where it is and :meth:`status`
        reports ``unreachable`` with a reason.

        Args:
            arm: arm name (see ``arms``).
            target_pose_world: tool point goal, world frame.
            position_only: ignore the goal orientation.
            max_linear_speed: tool speed limit [m/s], in (0, 2]; default from the config.
            max_angular_speed: tool angular speed limit [rad/s], in (0, 2 pi]; default from the config.

        Raises:
            UnknownNameError: unknown arm (the message lists the arms).
            InvalidGoalError: malformed pose or speed out of range.
        """
        info = check_arm_name(self.arms, arm)
        target = validate_pose(target_pose_world)
        linear = self.config.default_linear_speed if max_linear_speed is None else float(max_linear_speed)
        angular = self.config.default_angular_speed if max_angular_speed is None else float(max_angular_speed)
        if not (math.isfinite(linear) and 0.0 < linear <= MAX_LINEAR_SPEED):
            raise InvalidGoalError(f"max_linear_speed must be in (0, {MAX_LINEAR_SPEED}] m/s, got {linear}")
        if not (math.isfinite(angular) and 0.0 < angular <= MAX_ANGULAR_SPEED):
            raise InvalidGoalError(f"max_angular_speed must be in (0, {MAX_ANGULAR_SPEED:.3f}] rad/s, got {angular}")
        data = self._require_data()
        state = self._state[arm]
        self._sync_if_idle(info, state, data)
        qpos = data.qpos.copy()
        qpos[info.qpos_adr] = state.q_cmd
        result = self.kinematics.solve(arm, qpos, target, position_only)
        problem = self.kinematics.tracking[arm]
        problem.set_configuration(data.qpos, state.q_cmd)
        start = problem.tool_pose()
        state.start, state.target, state.position_only = start, target, position_only
        state.elapsed, state.stall_time = 0.0, 0.0
        if not result.success:
            state.mode, state.unreachable, state.reason = ArmMode.HOLDING, True, result.reason
            state.reference = start
            state.duration = 0.0
            return
        distance = float(np.linalg.norm(target.position - start.position))
        angle = 0.0 if position_only else rotation_error(target.orientation_wxyz, start.orientation_wxyz)
        state.duration = max(MIN_JERK_PEAK * max(distance / linear, angle / angular), self._control_dt)
        state.mode, state.unreachable, state.reason = ArmMode.MOVING, False, ""
        state.reference = start

    def hold(self, arm: str) -> None:
        """Stop the arm's reference now and hold the current joint targets (cancel).

        Raises:
            UnknownNameError: unknown arm.
        """
        info = check_arm_name(self.arms, arm)
        data = self._require_data()
        state = self._state[arm]
        self._sync_if_idle(info, state, data)
        problem = self.kinematics.tracking[arm]
        problem.set_configuration(data.qpos, state.q_cmd)
        pose = problem.tool_pose()
        state.mode = ArmMode.HOLDING
        state.reference = pose
        if state.target is None or not state.unreachable:
            state.target = pose
        state.start = pose
        state.duration = 0.0

    def set_gripper(self, arm: str, width_m: float, force_n: float) -> None:
        """Move the fingers to a width, squeezing with at most ``force_n`` per finger when blocked.

        Each finger's target is ``max(width / 2, q - force / kp)``: it closes under a constant
        force until it reaches ``width / 2`` or touches an object, which it then squeezes with
        ``force_n``.

        Args:
            arm: arm name with a gripper.
            width_m: distance between the fingers [m], in [0, open width].
            force_n: squeeze force per finger [N], in (0, ``robot.grasp.max_force_n``] (70 N on the Panda).

        Raises:
            UnknownNameError: unknown arm.
            InvalidGoalError: the arm has no gripper, or a value out of range.
        """
        info = check_arm_name(self.arms, arm)
        if not info.gripper_joints:
            with_gripper = [a for a, i in self.arms.items() if i.gripper_joints]
            raise InvalidGoalError(f"arm {arm!r} has no gripper; arms with a gripper: {', '.join(with_gripper) or 'none'}")
        open_width = self.robot.arm_scene.gripper_open_width
        if not (math.isfinite(width_m) and 0.0 <= width_m <= open_width + 1e-9):
            raise InvalidGoalError(f"gripper width must be in [0, {open_width}] m, got {width_m}")
        grasp = self.robot.grasp
        if grasp is None:  # RobotSpec refuses grippers without grasp limits; this tells the type checker
            raise SimError(f"robot {self.robot.name!r} has grippers but no grasp limits")
        if not (math.isfinite(force_n) and 0.0 < force_n <= grasp.max_force_n):
            raise InvalidGoalError(f"gripper force must be in (0, {grasp.max_force_n}] N, got {force_n}")
        state = self._state[arm]
        state.gripper_active, state.gripper_width, state.gripper_force = True, float(width_m), float(force_n)

    # ----- status --------------------------------------------------------------------------
    def status(self, arm: str) -> ArmStatus:
        """The arm's measured state and goal progress.

        Raises:
            UnknownNameError: unknown arm.
        """
        info = check_arm_name(self.arms, arm)
        data = self._require_data()
        state = self._state[arm]
        tool = Pose(data.site_xpos[info.site_id].copy(), mat_to_quat(data.site_xmat[info.site_id]))
        target = state.target or tool
        position_error = float(np.linalg.norm(target.position - tool.position))
        orientation_error = 0.0 if state.position_only else rotation_error(target.orientation_wxyz, tool.orientation_wxyz)
        progress = 1.0 if state.duration <= 0.0 else min(state.elapsed / state.duration, 1.0)
        still = float(np.max(np.abs(data.qvel[info.dof_adr]))) < self.config.settle_joint_speed
        settled = (
            state.mode != ArmMode.IDLE and not state.unreachable and progress >= 1.0 and still
            and position_error <= self.config.position_tolerance
            and orientation_error <= self.config.orientation_tolerance
        )
        return ArmStatus(
            arm=arm, mode=state.mode, tool_pose=tool, target_pose=target, reference_pose=state.reference or tool,
            position_error=position_error, orientation_error=orientation_error, position_only=state.position_only,
            progress=progress, settled=settled, unreachable=state.unreachable, reason=state.reason,
            gripper=self._gripper_status(info, state, data),
        )

    def take_ik_timings(self) -> list[float]:
        """IK wall times per control step since the last call [s] (for benchmarks)."""
        timings, self._ik_seconds = self._ik_seconds, []
        return timings

    # ----- internals -----------------------------------------------------------------------
    def _require_data(self) -> mujoco.MjData:
        if self._data is None:
            raise SimError("the arm controller is not installed: call Simulation.set_controller(Slot.ARM, controller)")
        return self._data

    def _sync_if_idle(self, info: ArmInfo, state: _ArmState, data: mujoco.MjData) -> None:
        if state.mode == ArmMode.IDLE or state.q_cmd.shape != info.qpos_adr.shape:
            state.q_cmd = data.qpos[info.qpos_adr].copy()

    def _track(self, info: ArmInfo, state: _ArmState, data: mujoco.MjData, dt: float) -> None:
        assert state.start is not None and state.target is not None  # set together with MOVING
        state.elapsed += dt
        fraction = 1.0 if state.duration <= 0.0 else state.elapsed / state.duration
        s = _min_jerk(fraction)
        orientation = state.start.orientation_wxyz if state.position_only else interpolate_quat(
            state.start.orientation_wxyz, state.target.orientation_wxyz, s)
        state.reference = Pose(state.start.position + s * (state.target.position - state.start.position), orientation)
        problem = self.kinematics.tracking[info.name]
        iterations = self.config.max_ik_iterations_per_tick
        fine = (self.config.position_tolerance * 0.01, self.config.orientation_tolerance * 0.01)
        started = time.perf_counter()
        problem.set_configuration(data.qpos, state.q_cmd)
        problem.iterate(state.reference, state.position_only, dt / iterations, iterations, fine)
        self._ik_seconds.append(time.perf_counter() - started)
        state.q_cmd = problem.arm_q
        if fraction >= 1.0:
            position_error, orientation_error = problem.errors(state.target, state.position_only)
            if position_error > self.config.position_tolerance or orientation_error > self.config.orientation_tolerance:
                state.stall_time += dt
                if state.stall_time > self.config.stall_time:
                    state.unreachable = True
                    state.reason = (
                        f"IK converged {position_error * 1000:.1f} mm / {orientation_error:.3f} rad from the target "
                        "while tracking: joint limits or collision avoidance block the path"
                    )
                    state.mode = ArmMode.HOLDING
            else:
                state.stall_time = 0.0

    def _write_arm(self, model: mujoco.MjModel, data: mujoco.MjData, info: ArmInfo, state: _ArmState) -> None:
        ctrl = state.q_cmd.copy()
        if self.config.gravity_feedforward:
            torque = data.qfrc_bias[info.dof_adr] - data.qfrc_gravcomp[info.dof_adr]
            ctrl += torque / model.actuator_gainprm[info.actuator_ids, 0]
        data.ctrl[info.actuator_ids] = ctrl

    def _write_gripper(self, model: mujoco.MjModel, data: mujoco.MjData, info: ArmInfo, state: _ArmState) -> None:
        kp = model.actuator_gainprm[info.gripper_actuator_ids, 0]
        q = data.qpos[info.gripper_qpos_adr]
        data.ctrl[info.gripper_actuator_ids] = np.maximum(0.5 * state.gripper_width, q - state.gripper_force / kp)

    def _gripper_status(self, info: ArmInfo, state: _ArmState, data: mujoco.MjData) -> GripperStatus | None:
        if not info.gripper_joints:
            return None
        model = self._model
        assert model is not None
        fingers = self._finger_bodies[info.name]
        touched: set[str] = set()
        for contact in data.contact[: data.ncon]:
            body1, body2 = int(model.geom_bodyid[contact.geom1]), int(model.geom_bodyid[contact.geom2])
            if body1 in fingers and body2 not in fingers:
                touched.add(model.body(body2).name)
            elif body2 in fingers and body1 not in fingers:
                touched.add(model.body(body1).name)
        width = float(np.sum(data.qpos[info.gripper_qpos_adr]))
        force = float(-np.mean(data.actuator_force[info.gripper_actuator_ids]))
        commanded = state.gripper_width if state.gripper_active else width
        return GripperStatus(width=width, commanded_width=commanded, force=force,
                             in_contact=bool(touched), contact_bodies=tuple(sorted(touched)))

