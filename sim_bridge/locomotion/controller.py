"""DCM walking with a whole-body torque QP, as the simulation's ``Slot.LOCOMOTION`` controller.

Every control step: an online footstep plan (from the measured footholds, the filtered velocity
command and a line/heading-keeping pull toward the planned path) gives a ZMP reference; its DCM
reference comes from closed-form backward integration; DCM tracking gives a desired CoP, hence a CoM
acceleration; the torque QP (:mod:`sim_bridge.locomotion.wbc`) turns it into leg and waist torques.

While walking, the leg and waist actuators are switched from position servos to torque motors (their
gains are restored when the robot stands still again, holding the pose it stopped in). The floating
base is never written: the robot moves only through its feet pushing on the floor.
"""

from __future__ import annotations

import enum
import math

import mujoco
import numpy as np

from robot_models import g1_constants as names
from sim_bridge.errors import InvalidGoalError
from sim_bridge.locomotion.params import GaitParameters
from sim_bridge.locomotion.planner import (
    Footstep,
    Side,
    ZmpSegment,
    clip_to_polygon,
    convex_hull,
    dcm_reference,
    SwingSample,
    rotation,
    swing_sample,
    wrap_angle,
)
from sim_bridge.locomotion.types import LocomotionMode, LocomotionStatus, Twist2D
from sim_bridge.locomotion.wbc import GRAVITY, WbcTargets, WholeBodyQP

MOTOR_JOINTS = names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS + names.WAIST_JOINTS
SERVO_JOINTS = names.LEFT_ARM_JOINTS + names.RIGHT_ARM_JOINTS

# Walking posture: a deeper crouch than the stand keyframe gives more reach [rad].
WALK_CROUCH = {"hip_pitch": -0.4, "knee": 0.8, "ankle_pitch": -0.4}
HALF_STEP_WIDTH = 0.1185  # lateral distance from the walking frame to each sole centre [m]
SHIFT_DURATION = 0.6  # initial weight shift onto the first stance foot [s]
SETTLE_DURATION = 0.6  # final shift of the ZMP to the midpoint between the feet [s]
HORIZON = 2.0  # DCM preview horizon [s]
DCM_GAIN = 6.0  # DCM tracking gain k [1/s]
HEIGHT_KP, HEIGHT_KD = 100.0, 20.0
LINE_KEEPING = 0.3  # fraction of the lateral path error removed per step
SPEED_INTEGRAL_GAIN = 0.5
SPEED_INTEGRAL_LIMIT = 0.05  # [m]
STEP_ADJUST_DEADBAND = 0.01  # [m]
SWING_FREEZE = 0.75  # fraction of the swing after which its target no longer changes
LOAD_RAMP = 0.03  # time for a touching-down foot to take full load [s]
REACH_X = (-0.20, 0.35)  # swing sole x relative to the stance sole, stance frame [m]
REACH_LATERAL = (0.15, 0.40)  # outward distance between sole centres [m]
SUPPORT_MARGIN = 0.01  # the desired CoP stays this far inside the sole [m]
FALL_HEIGHT = 0.45  # pelvis height below which the robot has fallen [m]
FALL_TILT = math.radians(50.0)
HANDOVER_SPEED = 0.03  # CoM speed below which standing is handed back to the position servos [m/s]
HANDOVER_DELAY = 0.5  # time standing still before the hand-over [s]
VELOCITY_FILTER_TIME = 0.5  # [s]


class _Phase(enum.Enum):
    IDLE = "idle"  # position servos hold the stance; the controller does not run
    SHIFT = "shift"
    SINGLE = "single"
    DOUBLE = "double"
    SETTLE = "settle"
    BALANCE = "balance"  # feet together, QP balancing before the hand-over
    FALLEN = "fallen"


def _yaw_of(mat: np.ndarray) -> float:
    return math.atan2(mat[3], mat[0])


def _mid_angle(a: float, b: float) -> float:
    return a + 0.5 * wrap_angle(b - a)


class WalkingController:
    """Velocity-commanded walking for the G1, run inside the simulation's control step.

    Args:
        model: the G1 model (from ``robot_models.load("g1")``); the leg and waist actuators are
            switched to torque mode while walking and restored afterwards.
        params: gait parameters (defaults: 0.35 s swing, 0.10 s double support, 6 cm swing height).
    """

    def __init__(self, model: mujoco.MjModel, params: GaitParameters | None = None) -> None:
        self._params = params or GaitParameters()
        self._wbc = WholeBodyQP(model, MOTOR_JOINTS, SERVO_JOINTS)
        self._motor_actuators = np.array([model.actuator(j).id for j in MOTOR_JOINTS])
        self._motor_qpos = np.array([model.joint(j).qposadr[0] for j in MOTOR_JOINTS])
        self._saved_gain = model.actuator_gainprm[self._motor_actuators].copy()
        self._saved_bias = model.actuator_biasprm[self._motor_actuators].copy()
        self._pelvis = model.body(names.ROOT_BODY).id
        base_joint = model.body_jntadr[self._pelvis]
        self._base_qpos = int(model.jnt_qposadr[base_joint])
        self._base_dof = int(model.jnt_dofadr[base_joint])
        self._sole_site = {Side.LEFT: model.site(names.LEFT_SOLE_SITE).id, Side.RIGHT: model.site(names.RIGHT_SOLE_SITE).id}
        self._posture = np.zeros(len(MOTOR_JOINTS))
        for i, joint in enumerate(MOTOR_JOINTS):
            for key, value in WALK_CROUCH.items():
                if joint.endswith(f"_{key}_joint"):
                    self._posture[i] = value
        self._com_height = self._crouch_com_height(model)
        self._omega = math.sqrt(GRAVITY / self._com_height)
        self._jac_com = np.zeros((3, model.nv))
        self._data: mujoco.MjData | None = None
        self._target = np.zeros(3)
        self._tick_times: list[float] = []
        self._init_state()

    # ----- public API -------------------------------------------------------------------
    @property
    def params(self) -> GaitParameters:
        return self._params

    @property
    def com_height(self) -> float:
        """CoM height the walk keeps above the floor [m]."""
        return self._com_height

    @property
    def active(self) -> bool:
        # Called every control step by the simulation: plain comparisons only.
        phase = self._phase
        if phase is _Phase.IDLE:
            return self._has_target
        return phase is not _Phase.FALLEN

    @property
    def _has_target(self) -> bool:
        return self._target_nonzero

    @property
    def _target(self) -> np.ndarray:
        return self._target_value

    @_target.setter
    def _target(self, value: np.ndarray) -> None:
        self._target_value = value
        self._target_nonzero = bool(np.any(value != 0.0))

    def set_velocity_command(self, vx: float, vy: float, wz: float) -> None:
        """Command a walking velocity in the base heading frame; zero stops and stands with the feet together.

        Args:
            vx: forward speed [m/s], clamped to [-max_backward_speed, max_forward_speed].
            vy: leftward speed [m/s], clamped to +-max_lateral_speed.
            wz: turning rate [rad/s], clamped to +-max_yaw_rate.
            All limits are further reduced to what one step can reach
            (:attr:`GaitParameters.speed_limits`).

        Raises:
            InvalidGoalError: a component is not a finite number.
        """
        values = (vx, vy, wz)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            raise InvalidGoalError(f"velocity command {values} must be three finite numbers")
        forward, backward, lateral, yaw_rate = self._params.speed_limits
        self._target = np.array([
            min(max(float(vx), -backward), forward),
            min(max(float(vy), -lateral), lateral),
            min(max(float(wz), -yaw_rate), yaw_rate),
        ])

    def set_gait_parameters(self, params: GaitParameters) -> None:
        """Apply new gait parameters; they take effect from the next phase of the gait.

        Raises:
            InvalidGoalError: ``params`` is not a :class:`GaitParameters` (values are validated when it is built).
        """
        if not isinstance(params, GaitParameters):
            raise InvalidGoalError(f"expected GaitParameters, got {type(params).__name__}")
        self._params = params
        self.set_velocity_command(*self._target)

    def status(self) -> LocomotionStatus:
        """The current mode, step count, command and measured velocity."""
        if self._phase != _Phase.FALLEN and self._data is not None and self._has_fallen(self._data):
            self._fall_message = "fell while holding the stance"
            self._phase = _Phase.FALLEN
        if not self.active and self._data is not None:
            self._measured = self._instant_velocity(self._data)
        stopping = not np.any(self._target != 0.0)
        if self._phase == _Phase.FALLEN:
            mode, message = LocomotionMode.FALLEN, self._fall_message + "; reset the simulation"
        elif self._phase in (_Phase.IDLE, _Phase.BALANCE):
            mode, message = LocomotionMode.STANDING, "standing"
        elif stopping:
            mode, message = LocomotionMode.STOPPING, "stopping: closing the feet"
        else:
            mode, message = LocomotionMode.WALKING, "walking"
        return LocomotionStatus(
            mode=mode,
            steps_taken=self._steps,
            commanded=Twist2D(*map(float, self._target)),
            measured=Twist2D(*map(float, self._measured)),
            fallen=self._phase == _Phase.FALLEN,
            message=message,
        )

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Forget the gait, restore the position servos (the keyframe's ctrl holds the stance), zero the command."""
        self._restore_servos(model)
        self._data = data
        self._target = np.zeros(3)
        self._init_state()

    def release(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Give the legs back to their position servos, holding the current pose, and stop.

        Call this before removing the controller from the simulation while it is active;
        otherwise the leg actuators would stay in torque mode.
        """
        if self._phase not in (_Phase.IDLE, _Phase.FALLEN):
            self._hold_current_pose(model, data)
        self._target = np.zeros(3)
        self._init_state()

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        """One control step: fall check, gait state machine, DCM tracking, torque QP, write torques."""
        self._data = data
        self._dt = control_dt
        if self._phase == _Phase.FALLEN:
            return
        if self._has_fallen(data):
            self._fall_message = f"fell at t={data.time:.2f} s"
            self._phase = _Phase.FALLEN
            self._hold_current_pose(model, data)
            return
        if self._phase == _Phase.IDLE:
            self._start_torque_control(model, data)
        self._filter_command(control_dt)
        self._update_stopping()
        self._measure(data, control_dt)
        self._advance_phase(data, control_dt)
        if self._phase == _Phase.IDLE:
            return
        targets = self._targets(model, data)
        tau = self._wbc.solve(model, data, targets)
        self._last_tau = tau
        data.ctrl[self._motor_actuators] = tau
        self._maybe_hand_over(model, data)

    # ----- state ------------------------------------------------------------------------
    def _init_state(self) -> None:
        self._phase = _Phase.IDLE
        self._phase_time = 0.0
        self._phase_duration = 0.0
        self._velocity = np.zeros(3)  # rate-limited command
        self._stopping = False
        self._measured = np.zeros(3)
        self._steps = 0
        self._stance = Side.RIGHT
        self._zmp_start = np.zeros(2)
        self._frame_pos = np.zeros(2)  # planned walking frame (midpoint between the feet) [m]
        self._frame_yaw = 0.0
        self._step_frame_pos = np.zeros(2)
        self._step_frame_yaw = 0.0
        self._swing_start = np.zeros(3)
        self._swing_start_yaw = 0.0
        self._swing_target = Footstep(Side.LEFT, np.zeros(2), 0.0)  # nominal landing of the current swing
        self._swing_landing: Footstep | None = None  # the nominal target moved by step adjustment
        self._swing_closing = False
        self._landed_closing = False
        self._speed_correction = 0.0
        self._touchdown_com = np.zeros(2)
        self._touchdown_time = 0.0
        self._still_time = 0.0
        self._time = 0.0
        self._dt = 0.004
        self._last_tau = np.zeros(len(MOTOR_JOINTS))
        self._fall_message = ""

    def _crouch_com_height(self, model: mujoco.MjModel) -> float:
        data = mujoco.MjData(model)
        key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, names.STAND_KEYFRAME)
        if key >= 0:
            mujoco.mj_resetDataKeyframe(model, data, key)
        data.qpos[self._motor_qpos] = self._posture
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        sole = min(data.site_xpos[s][2] for s in self._sole_site.values())
        return float(data.subtree_com[self._pelvis][2] - sole)

    # ----- actuator modes ---------------------------------------------------------------
    def _start_torque_control(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        ids = self._motor_actuators
        model.actuator_gainprm[ids] = 0.0
        model.actuator_gainprm[ids, 0] = 1.0
        model.actuator_biasprm[ids] = 0.0
        feet = self._feet(data)
        self._frame_yaw = _mid_angle(feet[Side.LEFT].yaw, feet[Side.RIGHT].yaw)
        self._frame_pos = 0.5 * (feet[Side.LEFT].position + feet[Side.RIGHT].position)
        self._velocity = np.zeros(3)
        self._enter(_Phase.BALANCE, 0.0)
        self._zmp_start = self._frame_pos.copy()

    def _restore_servos(self, model: mujoco.MjModel) -> None:
        model.actuator_gainprm[self._motor_actuators] = self._saved_gain
        model.actuator_biasprm[self._motor_actuators] = self._saved_bias

    def _hold_current_pose(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._restore_servos(model)
        data.ctrl[self._motor_actuators] = data.qpos[self._motor_qpos]

    def _maybe_hand_over(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if self._phase != _Phase.BALANCE or np.any(self._target != 0.0) or self._still_time < HANDOVER_DELAY:
            return
        kp = self._saved_gain[:, 0]
        self._restore_servos(model)
        data.ctrl[self._motor_actuators] = data.qpos[self._motor_qpos] + self._last_tau / kp
        self._phase = _Phase.IDLE

    # ----- measurement ------------------------------------------------------------------
    def _has_fallen(self, data: mujoco.MjData) -> bool:
        height = data.qpos[self._base_qpos + 2]
        up_z = data.xmat[self._pelvis][8]
        return bool(height < FALL_HEIGHT or up_z < math.cos(FALL_TILT))

    def _feet(self, data: mujoco.MjData) -> dict[Side, Footstep]:
        return {
            side: Footstep(side, data.site_xpos[site][:2].copy(), _yaw_of(data.site_xmat[site]))
            for side, site in self._sole_site.items()
        }

    def _com_state(self, model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        mujoco.mj_jacSubtreeCom(model, data, self._jac_com, self._pelvis)
        return data.subtree_com[self._pelvis].copy(), self._jac_com @ data.qvel

    def _instant_velocity(self, data: mujoco.MjData) -> np.ndarray:
        """Pelvis (vx, vy) in its heading frame [m/s] and yaw rate [rad/s]."""
        yaw = _yaw_of(data.xmat[self._pelvis])
        linear = rotation(yaw).T @ data.qvel[self._base_dof : self._base_dof + 2]
        yaw_rate = (data.xmat[self._pelvis].reshape(3, 3) @ data.qvel[self._base_dof + 3 : self._base_dof + 6])[2]
        return np.array([linear[0], linear[1], yaw_rate])

    def _measure(self, data: mujoco.MjData, dt: float) -> None:
        alpha = min(1.0, dt / VELOCITY_FILTER_TIME)
        self._measured += alpha * (self._instant_velocity(data) - self._measured)

    def _filter_command(self, dt: float) -> None:
        p = self._params
        step = np.array([p.max_acceleration, p.max_acceleration, p.max_yaw_acceleration]) * dt
        self._velocity += np.clip(self._target - self._velocity, -step, step)

    def _update_stopping(self) -> None:
        """Stopping: zero command and the rate-limited velocity has reached zero (refreshed every tick)."""
        self._stopping = not np.any(self._target != 0.0) and not np.any(self._velocity != 0.0)

    # ----- gait state machine -----------------------------------------------------------
    def _enter(self, phase: _Phase, duration: float) -> None:
        self._phase = phase
        self._phase_time = 0.0
        self._phase_duration = duration

    def _advance_phase(self, data: mujoco.MjData, dt: float) -> None:
        self._time += dt
        self._phase_time += dt
        feet = self._feet(data)
        if self._phase == _Phase.BALANCE:
            if np.any(self._target != 0.0):
                lead = Side.RIGHT if (self._target[1] < 0 or (self._target[1] == 0 and self._target[2] < 0)) else Side.LEFT
                self._stance = lead.other
                self._zmp_start = self._balance_zmp(feet)
                self._frame_yaw = _mid_angle(feet[Side.LEFT].yaw, feet[Side.RIGHT].yaw)
                self._frame_pos = 0.5 * (feet[Side.LEFT].position + feet[Side.RIGHT].position)
                self._speed_correction = 0.0
                self._still_time = 0.0
                self._enter(_Phase.SHIFT, SHIFT_DURATION)
            return
        if self._phase == _Phase.SHIFT:
            if self._stopping:
                shift = self._segments(feet)[0]
                progress = min(self._phase_time / max(shift.duration, 1e-6), 1.0)
                self._zmp_start = shift.start + progress * (shift.end - shift.start)
                self._enter(_Phase.SETTLE, SETTLE_DURATION)
            elif self._phase_time >= self._phase_duration:
                self._touchdown_com = data.subtree_com[self._pelvis][:2].copy()
                self._touchdown_time = self._time
                self._begin_single(data, feet)
            return
        if self._phase == _Phase.SINGLE:
            if self._phase_time < SWING_FREEZE * self._phase_duration:
                self._swing_target, self._swing_closing = self._next_footstep(
                    self._step_frame_pos, self._step_frame_yaw, self._stance.other, feet[self._stance]
                )
            if self._phase_time >= self._phase_duration:
                self._touchdown(data, feet)
            return
        if self._phase == _Phase.DOUBLE:
            if self._phase_time >= self._phase_duration:
                if self._stopping and self._landed_closing:
                    self._zmp_start = feet[self._stance].position.copy()
                    self._enter(_Phase.SETTLE, SETTLE_DURATION)
                else:
                    self._begin_single(data, feet)
            return
        if self._phase == _Phase.SETTLE:
            if self._phase_time >= self._phase_duration:
                self._enter(_Phase.BALANCE, 0.0)
                self._zmp_start = self._balance_zmp(feet)
            return

    def _balance_zmp(self, feet: dict[Side, Footstep]) -> np.ndarray:
        return 0.5 * (feet[Side.LEFT].position + feet[Side.RIGHT].position)

    def _begin_single(self, data: mujoco.MjData, feet: dict[Side, Footstep]) -> None:
        swing = self._stance.other
        site = self._sole_site[swing]
        self._swing_start = data.site_xpos[site].copy()
        self._swing_start_yaw = feet[swing].yaw
        # Walking frame at the start of this step: measured from the stance sole, with the lateral
        # error against the planned path partly removed (line keeping) and the planned heading.
        stance = feet[self._stance]
        measured = stance.position - rotation(stance.yaw) @ np.array([0.0, self._stance.sign * HALF_STEP_WIDTH])
        error = rotation(self._frame_yaw).T @ (measured - self._frame_pos)
        error[1] *= 1.0 - LINE_KEEPING
        self._step_frame_pos = self._frame_pos + rotation(self._frame_yaw) @ error
        self._step_frame_yaw = self._frame_yaw
        self._swing_target, self._swing_closing = self._next_footstep(
            self._step_frame_pos, self._step_frame_yaw, swing, stance
        )
        self._swing_landing = None
        self._enter(_Phase.SINGLE, self._params.step_duration)

    def _touchdown(self, data: mujoco.MjData, feet: dict[Side, Footstep]) -> None:
        target = self._swing_target
        self._steps += 1
        self._frame_yaw = target.yaw
        self._frame_pos = target.position - rotation(target.yaw) @ np.array([0.0, target.side.sign * HALF_STEP_WIDTH])
        self._landed_closing = self._swing_closing
        # Speed integral: measured CoM advance over the last step against the command.
        com = data.subtree_com[self._pelvis][:2]
        elapsed = self._time - self._touchdown_time
        if elapsed > 0 and not self._stopping and self._velocity[0] != 0.0:
            speed = float((rotation(self._frame_yaw).T @ (com - self._touchdown_com))[0]) / elapsed
            self._speed_correction += SPEED_INTEGRAL_GAIN * (self._velocity[0] - speed) * self._params.step_period
            self._speed_correction = float(np.clip(self._speed_correction, -SPEED_INTEGRAL_LIMIT, SPEED_INTEGRAL_LIMIT))
        elif self._velocity[0] == 0.0:
            self._speed_correction = 0.0
        self._touchdown_com = com.copy()
        self._touchdown_time = self._time
        self._zmp_start = feet[self._stance].position.copy()
        self._stance = target.side
        self._enter(_Phase.DOUBLE, self._params.double_support_duration)

    # ----- footsteps ----------------------------------------------------------------------
    def _advance_frame(
        self, frame_pos: np.ndarray, frame_yaw: float, swing: Side, velocity: np.ndarray
    ) -> tuple[np.ndarray, float]:
        period = self._params.step_period
        turn = velocity[2] * period
        forward = velocity[0] * period + (self._speed_correction if velocity[0] != 0.0 else 0.0)
        lateral = 2.0 * velocity[1] * period if velocity[1] * swing.sign > 0 else 0.0
        new_pos = frame_pos + rotation(frame_yaw + 0.5 * turn) @ np.array([forward, lateral])
        return new_pos, frame_yaw + turn

    def _place(self, frame_pos: np.ndarray, frame_yaw: float, swing: Side, stance: Footstep) -> Footstep:
        position = frame_pos + rotation(frame_yaw) @ np.array([0.0, swing.sign * HALF_STEP_WIDTH])
        return Footstep(swing, self._clip_reach(position, swing, stance), frame_yaw)

    @staticmethod
    def _clip_reach(position: np.ndarray, swing: Side, stance: Footstep) -> np.ndarray:
        """The nearest sole position within the swing leg's reach box around the stance sole [m]."""
        turn = rotation(stance.yaw)
        relative = turn.T @ (position - stance.position)
        forward = min(max(relative[0], REACH_X[0]), REACH_X[1])
        outward = min(max(swing.sign * relative[1], REACH_LATERAL[0]), REACH_LATERAL[1])
        return stance.position + turn @ np.array([forward, swing.sign * outward])

    def _next_footstep(
        self, frame_pos: np.ndarray, frame_yaw: float, swing: Side, stance: Footstep
    ) -> tuple[Footstep, bool]:
        """The next landing of ``swing`` and whether it is a closing (zero-velocity) step."""
        footstep, closing, _, _ = self._next_footstep_and_frame(frame_pos, frame_yaw, swing, stance)
        return footstep, closing

    def _next_footstep_and_frame(
        self, frame_pos: np.ndarray, frame_yaw: float, swing: Side, stance: Footstep
    ) -> tuple[Footstep, bool, np.ndarray, float]:
        velocity = np.zeros(3) if self._stopping else self._velocity
        new_pos, new_yaw = self._advance_frame(frame_pos, frame_yaw, swing, velocity)
        return self._place(new_pos, new_yaw, swing, stance), not np.any(velocity != 0.0), new_pos, new_yaw

    def _segments(self, feet: dict[Side, Footstep]) -> list[ZmpSegment]:
        p = self._params
        t_ss, t_ds = p.step_duration, p.double_support_duration
        segments: list[ZmpSegment] = []
        stance = feet[self._stance]
        phase = self._phase
        if phase == _Phase.BALANCE:
            return [ZmpSegment(1.0, self._zmp_start, self._zmp_start)]
        if phase == _Phase.SETTLE:
            mid = self._balance_zmp(feet)
            return [ZmpSegment(self._phase_duration, self._zmp_start, mid), ZmpSegment(1.0, mid, mid)]
        if phase == _Phase.SHIFT:
            segments.append(ZmpSegment(self._phase_duration, self._zmp_start, stance.position))
            segments.append(ZmpSegment(t_ss, stance.position, stance.position))
            frame_pos, frame_yaw = self._frame_pos, self._frame_yaw
            support = stance
            closing = False
        elif phase == _Phase.SINGLE:
            segments.append(ZmpSegment(self._phase_duration, stance.position, stance.position))
            target = self._swing_target
            segments.append(ZmpSegment(t_ds, stance.position, target.position))
            if self._stopping and self._swing_closing:
                mid = 0.5 * (stance.position + target.position)
                return segments + [ZmpSegment(SETTLE_DURATION, target.position, mid), ZmpSegment(1.0, mid, mid)]
            segments.append(ZmpSegment(t_ss, target.position, target.position))
            frame_pos = target.position - rotation(target.yaw) @ np.array([0.0, target.side.sign * HALF_STEP_WIDTH])
            frame_yaw = target.yaw
            support = target
            closing = self._swing_closing
        else:  # DOUBLE
            segments.append(ZmpSegment(self._phase_duration, self._zmp_start, stance.position))
            previous = self._zmp_start
            if self._stopping and self._landed_closing:
                mid = 0.5 * (previous + stance.position)
                return segments + [ZmpSegment(SETTLE_DURATION, stance.position, mid), ZmpSegment(1.0, mid, mid)]
            segments.append(ZmpSegment(t_ss, stance.position, stance.position))
            frame_pos, frame_yaw = self._frame_pos, self._frame_yaw
            support = stance
            closing = False
        total = sum(s.duration for s in segments) - self._phase_time
        while total < HORIZON:
            swing = support.side.other
            if self._stopping and closing:
                break
            footstep, closing, frame_pos, frame_yaw = self._next_footstep_and_frame(frame_pos, frame_yaw, swing, support)
            segments.append(ZmpSegment(t_ds, support.position, footstep.position))
            segments.append(ZmpSegment(t_ss, footstep.position, footstep.position))
            total += t_ds + t_ss
            support = footstep
        if self._stopping and closing:
            last = segments[-1].end
            before = segments[-2].start
            mid = 0.5 * (last + before)
            segments.append(ZmpSegment(SETTLE_DURATION, last, mid))
            segments.append(ZmpSegment(1.0, mid, mid))
        return segments

    def _adjusted_landing(
        self, segments: list[ZmpSegment], stance: Footstep, cop: np.ndarray, dcm: np.ndarray
    ) -> Footstep:
        """Step adjustment: move the landing by the predicted end-of-step DCM error.

        The error is measured against the unadjusted plan (``segments`` are built from the nominal
        target), so the adjustment does not cancel itself.
        """
        target = self._swing_target
        remaining = max(self._phase_duration - self._phase_time, 0.0)
        predicted = cop + math.exp(self._omega * remaining) * (dcm - cop)
        reference = dcm_reference(segments, self._phase_duration, self._omega).dcm
        offset = predicted - reference
        size = float(np.linalg.norm(offset))
        if size <= STEP_ADJUST_DEADBAND:
            return target
        offset *= (size - STEP_ADJUST_DEADBAND) / size
        position = self._clip_reach(target.position + offset, target.side, stance)
        return Footstep(target.side, position, target.yaw)

    # ----- tasks ------------------------------------------------------------------------
    def _support_hull(self, data: mujoco.MjData, sides: tuple[Side, ...]) -> np.ndarray:
        hx = names.SOLE_HALF_SIZE[0] - SUPPORT_MARGIN
        hy = names.SOLE_HALF_SIZE[1] - SUPPORT_MARGIN
        points = []
        for side in sides:
            site = self._sole_site[side]
            rot = data.site_xmat[site].reshape(3, 3)[:2, :2]
            for sx in (1, -1):
                for sy in (1, -1):
                    points.append(data.site_xpos[site][:2] + rot @ np.array([sx * hx, sy * hy]))
        return convex_hull(np.array(points))

    def _targets(self, model: mujoco.MjModel, data: mujoco.MjData) -> WbcTargets:
        feet = self._feet(data)
        com, com_vel = self._com_state(model, data)
        segments = self._segments(feet)
        reference = dcm_reference(segments, self._phase_time, self._omega)
        dcm = com[:2] + com_vel[:2] / self._omega
        cop = reference.zmp + (1.0 + DCM_GAIN / self._omega) * (dcm - reference.dcm)
        single = self._phase == _Phase.SINGLE
        sides = (self._stance,) if single else (Side.LEFT, Side.RIGHT)
        cop = clip_to_polygon(cop, self._support_hull(data, sides))
        acceleration = np.zeros(3)
        acceleration[:2] = self._omega**2 * (com[:2] - cop)
        acceleration[2] = HEIGHT_KP * (self._com_height - com[2]) - HEIGHT_KD * com_vel[2]
        speed = float(np.linalg.norm(com_vel[:2]))
        self._still_time = self._still_time + self._dt if speed < HANDOVER_SPEED else 0.0

        load = {Side.LEFT: 1.0, Side.RIGHT: 1.0}
        swing_refs: dict[Side, SwingSample | None] = {Side.LEFT: None, Side.RIGHT: None}
        heading = _mid_angle(feet[Side.LEFT].yaw, feet[Side.RIGHT].yaw)
        if single:
            swing = self._stance.other
            load[swing] = 0.0
            if self._phase_time < SWING_FREEZE * self._phase_duration or self._swing_landing is None:
                self._swing_landing = self._adjusted_landing(segments, feet[self._stance], cop, dcm)
            sample = swing_sample(
                self._swing_start, self._swing_start_yaw, self._swing_landing, self._params.step_height,
                self._phase_time, self._phase_duration,
            )
            swing_refs[swing] = sample
            heading = _mid_angle(feet[self._stance].yaw, sample.yaw)
        elif self._phase == _Phase.DOUBLE:
            load[self._stance] = min(1.0, self._phase_time / LOAD_RAMP)
            load[self._stance.other] = max(0.0, 1.0 - self._phase_time / max(self._phase_duration, 1e-6))
        return WbcTargets(
            com_acceleration=acceleration,
            heading=heading,
            load=load,
            swing=swing_refs,
            posture=self._posture,
        )
