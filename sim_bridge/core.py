"""The simulation core: owns MjModel/MjData, steps physics, runs in-loop controllers.

Nothing here knows about ROS. The sim node is the only caller that steps it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import mujoco
import numpy as np

from robot_models import RobotSpec
from robot_models.cameras import CameraLayout
from sim_bridge.controller import Controller, Slot
from sim_bridge.errors import InvalidGoalError, SimulationFaultError, UnknownNameError
from sim_bridge.servo import JointServo
from sim_bridge.state import BaseState, Pose, SimState

_BADQACC = int(mujoco.mjtWarning.mjWARN_BADQACC)
MAX_PUSH_FORCE_N = 5000.0
MAX_PUSH_TORQUE_NM = 1000.0
MAX_PUSH_DURATION_S = 10.0
# A push is bounded by the mass it moves (the body's whole tree: a link pushes its robot): at most
# PUSH_MAX_ACCELERATION_G times gravity, and an impulse that changes the tree's velocity by at most
# PUSH_MAX_DELTA_V_MPS. A shove that fells a humanoid passes (the G1: up to 3.4 kN, 241 N s); a
# 50 g box gets at most 4.9 N and 0.35 N s (a toss of ~2.5 m at most), not a launch into the sky.
PUSH_MAX_ACCELERATION_G = 10.0
PUSH_MAX_DELTA_V_MPS = 7.0
PUSH_LEVER_ARM_M = 0.3  # torque bound = force bound x this arm


@dataclass
class _Push:
    """A constant wrench on one body for a number of physics steps still to run."""

    body_id: int
    wrench: np.ndarray  # force [N] then torque [N m], world frame, at the body's centre of mass
    steps_left: int


@dataclass(frozen=True)
class _TiltMount:
    """A camera's tilt joint, resolved: its qpos address and its position servo's actuator."""

    layout: CameraLayout
    qpos_adr: int
    actuator_id: int


@runtime_checkable
class Sampled(Protocol):
    """A slot's occupant that observes the physics between its updates (e.g. a battery meter).

    Its ``sample`` is called at the end of every :meth:`Simulation.step_physics` call, so the
    simulation can step in batches while its controller is idle and the occupant still sees all of it.
    """

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Account for the physics up to the current sim time."""
        ...


def _as_slice(indices: np.ndarray) -> slice | np.ndarray:
    """A slice when the indices are consecutive (indexing then gives a view, cheaper than gathering)."""
    if len(indices) and np.array_equal(indices, np.arange(indices[0], indices[0] + len(indices))):
        return slice(int(indices[0]), int(indices[0]) + len(indices))
    return indices


class Simulation:
    """A robot scene stepping at a fixed physics step, with controllers at the control step.

    The control step is ``robot.control_decimation`` physics steps. At each control step the
    active controllers run in slot order on the current state (``mj_step1``), then the physics
    steps of the period run. When no controller is active (standing still under the servos'
    own PD), many physics steps are run in one ``mj_step`` call so Python stays off the hot path.

    Args:
        robot: the scene to simulate.
    """

    def __init__(self, robot: RobotSpec) -> None:
        self.robot = robot
        self.model: mujoco.MjModel = robot.model
        self.data = mujoco.MjData(self.model)
        self._timestep = float(self.model.opt.timestep)  # fixed: the control grid is built on it
        self.decimation = int(robot.control_decimation)
        if self.decimation < 1:
            raise ValueError(f"control decimation must be a whole number >= 1, got {robot.control_decimation}")
        self.servo = JointServo(self.model, robot.actuated_joints)
        self._controllers: dict[Slot, Controller] = {Slot.JOINT_SERVO: self.servo}
        self._sampled: tuple[Sampled, ...] = ()  # the occupants sampled after each step_physics call
        self._qpos_adr = _as_slice(np.array([self.model.joint(j).qposadr[0] for j in robot.actuated_joints]))
        self._dof_adr = _as_slice(np.array([self.model.joint(j).dofadr[0] for j in robot.actuated_joints]))
        self._actuator_ids = _as_slice(np.array([self.model.actuator(j).id for j in robot.actuated_joints]))
        self._base_body = self.model.body(robot.base_body).id
        self._base_qpos_adr = -1
        self._base_dof_adr = -1
        if robot.floating_base:
            joint_id = int(self.model.body_jntadr[self._base_body])
            self._base_qpos_adr = int(self.model.jnt_qposadr[joint_id])
            self._base_dof_adr = int(self.model.jnt_dofadr[joint_id])
        self._warnings_seen = 0
        self._warning_counts = self.data.warning.number  # a live view of MuJoCo's counters
        self._phase = 0  # physics steps since the last control update
        self._pushes: list[_Push] = []
        self._tilt_mounts = {
            camera.name: _TiltMount(camera, int(self.model.joint(camera.tilt_joint).qposadr[0]),
                                    int(self.model.actuator(camera.tilt_joint).id))
            for camera in robot.cameras if camera.tilt_joint is not None
        }
        self._tilt_targets = {name: mount.layout.default_tilt_rad for name, mount in self._tilt_mounts.items()}
        self.reset(robot.default_keyframe, keep_time=False)

    # ----- controllers -------------------------------------------------------------------
    def set_controller(self, slot: Slot, controller: Controller | None) -> None:
        """Install (or remove with ``None``) the controller of a slot. The servo slot is fixed."""
        if slot == Slot.JOINT_SERVO:
            raise ValueError("the joint servo slot cannot be replaced")
        if controller is None:
            removed = self._controllers.pop(slot, None)
            release = getattr(removed, "release", None)
            if release is not None:  # e.g. the walker hands the legs back to their servos
                release(self.model, self.data)
        else:
            controller.reset(self.model, self.data)
            self._controllers[slot] = controller
        self._controllers = dict(sorted(self._controllers.items()))
        self._sampled = tuple(c for c in self._controllers.values() if isinstance(c, Sampled))

    def controller(self, slot: Slot) -> Controller | None:
        return self._controllers.get(slot)

    # ----- time --------------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Simulation time [s]."""
        return float(self.data.time)

    @property
    def physics_timestep(self) -> float:
        """Physics step [s] (fixed for the simulation's life)."""
        return self._timestep

    @property
    def control_timestep(self) -> float:
        return self.physics_timestep * self.decimation

    def step(self, control_steps: int = 1) -> None:
        """Advance by whole control steps.

        Raises:
            SimulationFaultError: the physics diverged; call :meth:`reset`.
        """
        self.step_physics(int(control_steps) * self.decimation)

    def step_physics(self, physics_steps: int) -> None:
        """Advance by physics steps, running the controllers at every control-step boundary.

        The control grid is kept whatever ``physics_steps`` is: controllers run when the number
        of physics steps since the last control update reaches the decimation. A push
        (:meth:`push`) acts for exactly its physics steps, wherever the calls split them. The
        occupants that observe the physics (:class:`Sampled`) are sampled once at the end.

        Raises:
            SimulationFaultError: the physics diverged; call :meth:`reset`.
        """
        remaining = int(physics_steps)
        while self._pushes and remaining > 0:
            span = min(remaining, min(push.steps_left for push in self._pushes))
            self._step_span(span)
            remaining -= span
            for push in self._pushes:
                push.steps_left -= span
                if push.steps_left == 0:
                    self.data.xfrc_applied[push.body_id] -= push.wrench
            self._pushes = [push for push in self._pushes if push.steps_left > 0]
        if remaining > 0:
            self._step_span(remaining)
        for occupant in self._sampled:
            occupant.sample(self.model, self.data)

    def _step_span(self, physics_steps: int) -> None:
        remaining = int(physics_steps)
        model, data = self.model, self.data
        if remaining > 0 and not any(c.active for c in self._controllers.values()):
            # Nothing to run (controllers only start between calls): one batched call, grid kept.
            mujoco.mj_step(model, data, nstep=remaining)
            self._phase = (self._phase + remaining) % self.decimation
            self._check_fault()
            return
        while remaining > 0:
            if self._phase == 0:
                active = [c for c in self._controllers.values() if c.active]
                if not active:
                    # Nothing to run: batch to the last control boundary within reach, then the rest.
                    whole = remaining - remaining % self.decimation
                    if whole:
                        mujoco.mj_step(model, data, nstep=whole)
                        remaining -= whole
                        continue
                    mujoco.mj_step(model, data, nstep=remaining)
                    self._phase = remaining
                    break
                mujoco.mj_step1(model, data)
                for controller in active:
                    controller.update(model, data, self.control_timestep)
                mujoco.mj_step2(model, data)
                self._phase = 1 % self.decimation
                remaining -= 1
                continue
            chunk = min(remaining, self.decimation - self._phase)
            mujoco.mj_step(model, data, nstep=chunk)
            self._phase = (self._phase + chunk) % self.decimation
            remaining -= chunk
        self._check_fault()

    def _check_fault(self) -> None:
        # MuJoCo counts bad accelerations (and resets the state itself); NaN can only come with them.
        warnings = int(self._warning_counts[_BADQACC])
        if warnings != self._warnings_seen:
            self._warnings_seen = warnings
            raise SimulationFaultError(f"physics diverged at t={self.time:.3f} s (bad accelerations); reset the simulation")

    # ----- external pushes ---------------------------------------------------------------
    def push(self, body: str, force_n: Sequence[float], torque_nm: Sequence[float], duration_s: float) -> float:
        """Push a body: a constant force and torque (world frame, at its centre of mass) from now on.

        The wrench acts for ``duration_s`` rounded to whole physics steps (at least one) and adds
        to any push still acting. Returns the sim time [s] at which it ends.

        Raises:
            UnknownNameError: no body of that name (nothing is changed).
            ValueError: a value is not finite or out of range (nothing is changed).
        """
        body_id = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, body)
        if body_id <= 0:  # 0 is the world, which cannot be pushed
            names = [self.model.body(i).name for i in range(1, self.model.nbody)]
            raise UnknownNameError(f"unknown body {body!r}; bodies: {', '.join(names)}")
        force = np.asarray(force_n, dtype=float).reshape(3)
        torque = np.asarray(torque_nm, dtype=float).reshape(3)
        if not (np.all(np.isfinite(force)) and np.all(np.isfinite(torque)) and math.isfinite(duration_s)):
            raise ValueError("force, torque and duration must be finite numbers")
        if not 0.0 < duration_s <= MAX_PUSH_DURATION_S:
            raise ValueError(f"duration must be in (0, {MAX_PUSH_DURATION_S:g}] s of sim time, got {duration_s}")
        mass = float(self.model.body_subtreemass[self.model.body_rootid[body_id]])
        gravity = float(np.linalg.norm(self.model.opt.gravity)) or 9.81
        max_force = min(MAX_PUSH_FORCE_N, PUSH_MAX_ACCELERATION_G * gravity * mass)
        max_torque = min(MAX_PUSH_TORQUE_NM, max_force * PUSH_LEVER_ARM_M)
        max_impulse = PUSH_MAX_DELTA_V_MPS * mass
        what = f"{body!r} (it moves {mass:.3g} kg)"
        if np.linalg.norm(force) > max_force:
            raise ValueError(f"force {np.linalg.norm(force):.1f} N is too large for {what}; allowed: up to {max_force:.4g} N")
        if np.linalg.norm(torque) > max_torque:
            raise ValueError(f"torque {np.linalg.norm(torque):.1f} N m is too large for {what}; "
                             f"allowed: up to {max_torque:.4g} N m")
        if np.linalg.norm(force) * duration_s > max_impulse:
            raise ValueError(f"impulse {np.linalg.norm(force) * duration_s:.3g} N s (force x duration) is too large for "
                             f"{what}; allowed: up to {max_impulse:.3g} N s (a change of {PUSH_MAX_DELTA_V_MPS:g} m/s)")
        steps = max(1, round(duration_s / self.physics_timestep))
        push = _Push(body_id, np.concatenate([force, torque]), steps)
        self._pushes.append(push)
        self.data.xfrc_applied[body_id] += push.wrench  # on top of what others apply; taken off when it ends
        return self.time + steps * self.physics_timestep

    @property
    def pushing(self) -> bool:
        """True while a push acts."""
        return bool(self._pushes)

    # ----- reset -------------------------------------------------------------------------
    def reset(self, keyframe: str | None = None, keep_time: bool = True) -> None:
        """Restore a keyframe exactly. Sim time keeps running forward unless ``keep_time`` is false.

        Camera tilt mounts are the exception: each stands (and is held) at its commanded tilt
        (:meth:`set_camera_tilt`), which a reset keeps.

        Raises:
            UnknownNameError: the keyframe does not exist (nothing is changed).
        """
        name = keyframe or self.robot.default_keyframe
        key_id = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_KEY, name)
        if key_id < 0:
            raise UnknownNameError(f"unknown keyframe {name!r}; keyframes: {', '.join(self.robot.keyframes)}")
        now = self.data.time
        mujoco.mj_resetDataKeyframe(self.model, self.data, key_id)
        for name, mount in self._tilt_mounts.items():
            self.data.qpos[mount.qpos_adr] = self.data.ctrl[mount.actuator_id] = self._tilt_targets[name]
        self._pushes.clear()
        self.data.xfrc_applied[:] = 0.0
        if keep_time:
            self.data.time = now
        mujoco.mj_forward(self.model, self.data)
        self._phase = 0
        self._warnings_seen = int(self._warning_counts[_BADQACC])
        for controller in self._controllers.values():
            controller.reset(self.model, self.data)

    # ----- camera mounts ------------------------------------------------------------------
    def set_camera_tilt(self, camera: str, angle_rad: float) -> None:
        """Command a camera's tilt [rad] (+ = looking down); the mount's servo turns it there under physics.

        The target outlives :meth:`reset` (a reset puts the mount at it).

        Raises:
            InvalidGoalError: (a ValueError) the camera has no tilt mount, or the angle is not in its range
                (nothing is changed); the message names the range or the cameras that tilt.
        """
        mount = self._tilt_mount(camera)
        low, high = mount.layout.tilt_range_rad
        if not (math.isfinite(angle_rad) and low <= angle_rad <= high):
            raise InvalidGoalError(f"tilt of camera {camera!r} must be in [{low:g}, {high:g}] rad, got {angle_rad}")
        self._tilt_targets[camera] = float(angle_rad)
        self.servo.set_targets({str(mount.layout.tilt_joint): float(angle_rad)})

    def camera_tilt(self, camera: str) -> float:
        """A camera's measured tilt [rad] (the mount's joint angle; + = looking down).

        Raises:
            InvalidGoalError: (a ValueError) the camera has no tilt mount.
        """
        return float(self.data.qpos[self._tilt_mount(camera).qpos_adr])

    def _tilt_mount(self, camera: str) -> _TiltMount:
        mount = self._tilt_mounts.get(camera)
        if mount is None:
            tilting = ", ".join(self._tilt_mounts) or "none"
            fixed = [c.name for c in self.robot.cameras if c.name not in self._tilt_mounts]
            what = "is fixed (no tilt mount)" if camera in fixed else "is unknown"
            raise InvalidGoalError(f"camera {camera!r} {what}; cameras of {self.robot.name} with a tilt mount: {tilting}")
        return mount

    # ----- state -------------------------------------------------------------------------
    def base_state(self) -> BaseState:
        """Ground-truth base pose and body-frame twist."""
        data = self.data
        if self._base_qpos_adr >= 0:
            q = data.qpos[self._base_qpos_adr : self._base_qpos_adr + 7]
            v = data.qvel[self._base_dof_adr : self._base_dof_adr + 6]
            # Free joint: linear velocity in world, angular velocity in body frame.
            rot = np.empty(9)
            mujoco.mju_quat2Mat(rot, q[3:7])
            linear_body = rot.reshape(3, 3).T @ v[:3]
            return BaseState(Pose(q[:3].copy(), q[3:7].copy()), linear_body, v[3:6].copy())
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, data.xmat[self._base_body])
        return BaseState(Pose(data.xpos[self._base_body].copy(), quat), np.zeros(3), np.zeros(3))

    def joint_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities and actuator efforts of the actuated joints, shape (n,) each.

        These may be views into MjData (valid until the next step): copy what you keep.
        """
        data = self.data
        return data.qpos[self._qpos_adr], data.qvel[self._dof_adr], data.actuator_force[self._actuator_ids]

    def snapshot(self) -> SimState:
        """The state at this instant as typed values."""
        data = self.data
        return SimState(
            time=float(data.time),
            joint_names=self.robot.actuated_joints,
            joint_positions=data.qpos[self._qpos_adr].copy(),
            joint_velocities=data.qvel[self._dof_adr].copy(),
            joint_efforts=data.actuator_force[self._actuator_ids].copy(),
            base=self.base_state(),
        )

    def body_pose(self, name: str) -> Pose:
        """World pose of a body.

        Raises:
            UnknownNameError: no such body.
        """
        body_id = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if body_id < 0:
            raise UnknownNameError(f"unknown body {name!r}")
        return Pose(self.data.xpos[body_id].copy(), self.data.xquat[body_id].copy())
