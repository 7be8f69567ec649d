"""ResetPose as a skill in the control step: stop, close the feet, return to the default posture under physics.

The walking controller stops the robot and closes its feet under the hips (what it does after any
stop) and hands the legs back to their position servos; then every actuated joint's servo target
moves smoothly from where it holds to the default keyframe's, and the goal succeeds once every joint
is within the tolerance of the keyframe's position and the joints have come to rest. A fallen robot
is refused ("fallen: reset the simulation"): it has no get-up.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models import RobotSpec
from robot_models.validation import check_range
from sim_bridge.errors import InvalidGoalError
from sim_bridge.locomotion import WalkingController
from sim_bridge.skills.base import SkillOutcome, Values
from sim_bridge.skills.locomotion import LEGS

DEFAULT_TOLERANCE_RAD = 0.05
MAX_TOLERANCE_RAD = 0.5
DEFAULT_TIMEOUT_S = 20.0
MAX_TIMEOUT_S = 600
POSTURE_DURATION_S = 1.5  # the servo targets move to the default pose over this much sim time
REST_SPEED_RAD_S = 0.05  # every joint slower than this counts as at rest
STOPPING, POSTURE, SETTLING = "stopping", "posture", "settling"


@dataclass(frozen=True)
class ResetPoseGoal:
    """tolerance_rad: largest joint error that counts as reached (0 = default); timeout_s: [s] of sim time (0 = default)."""

    tolerance_rad: float = 0.0
    timeout_s: float = 0.0

    def __post_init__(self) -> None:
        check_range(f"tolerance (0 = {DEFAULT_TOLERANCE_RAD:g} rad)", self.tolerance_rad, 0, MAX_TOLERANCE_RAD, unit="rad",
                    error=InvalidGoalError)
        check_range(f"timeout (0 = {DEFAULT_TIMEOUT_S:g} s)", self.timeout_s, 0, MAX_TIMEOUT_S, unit="s", error=InvalidGoalError)


class ResetPoseSkill:
    """Bring a standing robot back to its default keyframe posture (see the module's text)."""

    name = "reset_pose"
    resource = LEGS
    pose_frame = "odom"

    def __init__(self, walker: WalkingController, robot: RobotSpec, goal: ResetPoseGoal) -> None:
        self.walker = walker
        self._robot = robot
        self._tolerance = goal.tolerance_rad or DEFAULT_TOLERANCE_RAD
        self._timeout = goal.timeout_s or DEFAULT_TIMEOUT_S
        model = robot.model
        key = model.key(robot.default_keyframe)
        # The body's joints; a camera's tilt mount keeps the tilt its owner (/head) commanded.
        mounts = {camera.tilt_joint for camera in robot.cameras}
        posture = [j for j in robot.actuated_joints if j not in mounts]
        self._actuators = np.array([model.actuator(j).id for j in posture])
        self._qpos_adr = np.array([model.joint(j).qposadr[0] for j in posture])
        self._dof_adr = np.array([model.joint(j).dofadr[0] for j in posture])
        self._target_ctrl = key.ctrl[self._actuators].copy()
        self._target_q = key.qpos[self._qpos_adr].copy()
        self._phase = STOPPING
        self._refused: SkillOutcome | None = None
        self._cancel = False
        self._t0 = self._posture_t0 = 0.0
        self._ctrl0 = self._target_ctrl.copy()
        self._error = math.inf

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._t0 = float(data.time)
        self._error = self._joint_error(data)
        if self.walker.status().fallen:
            self._refused = SkillOutcome.aborted("FALLEN", "fallen: reset the simulation (/sim/reset); there is no get-up")
            return
        self.walker.set_stop_point(None)
        self.walker.set_velocity_command(0.0, 0.0, 0.0)  # stop: the walker closes the feet and hands over to the servos

    def _joint_error(self, data: mujoco.MjData) -> float:
        return float(np.max(np.abs(data.qpos[self._qpos_adr] - self._target_q)))

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        if self._refused is not None:
            return self._refused
        now = float(data.time)
        self._error = self._joint_error(data)
        status = self.walker.status()
        if status.fallen:
            return SkillOutcome.aborted("FELL", f"fell during reset_pose: {status.message}")
        if self._cancel and not self.walker.active:
            return SkillOutcome.canceled(f"canceled in phase {self._phase}: holding the pose reached")
        if now - self._t0 > self._timeout and not self.walker.active:
            return SkillOutcome.aborted("TIMEOUT", f"the default pose was not reached within {self._timeout:g} s "
                                                   f"(largest joint error {self._error:.3f} rad)")
        if self._cancel:
            return None
        if self._phase == STOPPING:
            self.walker.set_velocity_command(0.0, 0.0, 0.0)
            if not self.walker.active:  # standing on the position servos, feet closed
                self._phase, self._posture_t0 = POSTURE, now
                self._ctrl0 = data.ctrl[self._actuators].copy()
            return None
        if self._phase == POSTURE:
            s = min(1.0, (now - self._posture_t0) / POSTURE_DURATION_S)
            blend = s * s * (3.0 - 2.0 * s)
            data.ctrl[self._actuators] = self._ctrl0 + blend * (self._target_ctrl - self._ctrl0)
            if s >= 1.0:
                self._phase = SETTLING
            return None
        speed = float(np.max(np.abs(data.qvel[self._dof_adr])))
        if self._error <= self._tolerance and speed < REST_SPEED_RAD_S:
            return SkillOutcome.succeeded(f"default pose reached: largest joint error {self._error:.3f} rad "
                                          f"(tolerance {self._tolerance:g} rad)")
        return None

    def request_cancel(self) -> None:
        self._cancel = True

    def stop_now(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """The servos keep their current targets."""

    def update_settings(self, settings: Mapping[str, float]) -> None:
        """No settings."""

    def feedback(self, data: mujoco.MjData) -> Values:
        return {"max_joint_error": self._joint_error(data), "phase": self._phase}

    def result(self, data: mujoco.MjData) -> Values:
        return {"max_joint_error": self._joint_error(data)}
