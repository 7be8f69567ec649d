"""DCM walking with a whole-body torque QP, as the simulation's ``Slot.LOCOMOTION`` controller.

Every control step: an online footstep plan (from the measured footholds, the filtered velocity
command and a line/heading-keeping pull toward the planned path) gives a ZMP reference; its DCM
reference comes from closed-form backward integration; DCM tracking gives a desired CoP, hence a CoM
acceleration; the torque QP (:mod:`sim_bridge.locomotion.wbc`) turns it into leg and waist torques.

While walking, the leg and waist actuators are switched from position servos to torque motors (their
gains are restored when the robot stands still again, holding the pose it stopped in). The floating
base is never written: the robot moves only through its feet pushing on the floor.

Cost per control step: the ZMP preview is refilled from this step's measurements (the stance sole
and the CoM move every step) in float arithmetic on (x, y) tuples, into one reused
:class:`ZmpPreview` whose DCM is integrated once per step and serves both the tracking and the step
adjustment. Footsteps that follow a planned footstep depend on nothing measured, so they are
kept (``_plan``) until the command, the speed correction or the footstep they follow changes, which
at a steady command means once per gait phase; only a footstep placed from the measured stance sole
is planned every step. The QP is reduced and warm-started (see :mod:`.wbc`).
"""

from __future__ import annotations

import enum
import math
from typing import NamedTuple

import mujoco
import numpy as np

from robot_models import g1_constants as names
from robot_models.g1 import WALKING as G1_WALKING
from sim_bridge.errors import InvalidGoalError
from sim_bridge.locomotion.params import GaitParameters
from sim_bridge.locomotion.planner import (
    Footstep,
    Point,
    Side,
    SwingSample,
    ZmpPreview,
    clip_point,
    hull_of,
    rotate,
    swing_sample,
    unrotate,
    wrap_angle,
)
from sim_bridge.locomotion.types import LocomotionMode, LocomotionStatus, Twist2D
from sim_bridge.locomotion.wbc import GRAVITY, WbcTargets, WholeBodyQP

MOTOR_JOINTS = names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS + names.WAIST_JOINTS
# Joints left on their position servos while walking (the QP predicts their servos' torques): the arms and
# the head camera's tilt mount.
SERVO_JOINTS = names.LEFT_ARM_JOINTS + names.RIGHT_ARM_JOINTS + names.HEAD_JOINTS

# Walking posture: a deeper crouch than the stand keyframe gives more reach [rad].
WALK_CROUCH = {"hip_pitch": -0.5, "knee": 1.0, "ankle_pitch": -0.5}
HALF_STEP_WIDTH = 0.1185  # lateral distance from the walking frame to each sole centre [m]
SHIFT_DURATION = 0.6  # initial weight shift onto the first stance foot [s]
SETTLE_DURATION = 0.6  # final shift of the ZMP to the midpoint between the feet [s]
HORIZON = 2.0  # DCM preview horizon [s]
DCM_GAIN = 6.0  # DCM tracking gain k [1/s]
HEIGHT_KP, HEIGHT_KD = 100.0, 20.0
LINE_KEEPING = 0.3  # fraction of the lateral path error removed per step
LINE_STEP_GAIN = 0.1  # extra sideways landing offset per m of lateral path error (see _adjusted_landing)
LINE_STEP_LIMIT = 0.04  # [m]
SPEED_INTEGRAL_GAIN = 0.5
SPEED_INTEGRAL_LIMIT = 0.05  # [m]
STEP_ADJUST_DEADBAND = 0.01  # [m]
TIMING_ADAPTATION = True  # shorten a swing whose needed landing is out of reach (_adapt_timing)
TIMING_CROSSOVER = True  # also when the needed landing is inside the other foot's reach limit
TIMING_TRIGGER = 0.02  # the reach box moves the needed landing more than this [m]
TIMING_MIN_REMAINING = 0.12  # a shortened swing keeps at least this much time to land [s]
TIMING_MIN_SWING = 0.20  # shortest swing [s]
TIMING_MIN_CHANGE = 0.01  # smaller changes of the swing time are not made [s]
TIMING_SWING_HEIGHT = 1.0  # a restarted swing rises to at most this fraction of the step height ...
TIMING_MIN_HEIGHT = 0.01  # ... and at least this much [m]
TIMING_RUSHED_DOUBLE = 0.05  # double support after a shortened swing [s]
SWING_FREEZE = 0.85  # fraction of the swing after which its target no longer changes
LOAD_RAMP = 0.03  # time for a touching-down foot to take full load [s]
REACH_X = (-0.20, 0.45)  # swing sole x relative to the stance sole, stance frame [m]
REACH_LATERAL = (0.15, 0.48)  # outward distance between sole centres [m]
SUPPORT_MARGIN = 0.01  # the desired CoP stays this far inside the sole [m]
FALL_HEIGHT = G1_WALKING.fall_height_m  # pelvis height below which the robot has fallen [m] (the robot's spec)
_FALL_UP_Z = math.cos(G1_WALKING.fall_tilt_rad)  # the pelvis z axis's world z below which the robot has fallen
HANDOVER_SPEED = 0.03  # CoM speed below which standing is handed back to the position servos [m/s]
HANDOVER_DELAY = 0.5  # time standing still before the hand-over [s]
VELOCITY_FILTER_TIME = 0.5  # [s]

Velocity = tuple[float, float, float]  # (vx [m/s], vy [m/s], wz [rad/s]) in the heading frame
PlannedStep = tuple[Footstep, bool, Point, float]  # landing, closing step?, walking frame after it ([m], [rad])
_ZERO: Velocity = (0.0, 0.0, 0.0)
_CORNER_SIGNS = ((1, 1), (-1, 1), (-1, -1), (1, -1))  # counter-clockwise around the sole


class GaitPhase(NamedTuple):
    """Where the gait is: the phase's kind, the time spent in it and its planned duration [s]."""

    kind: str
    elapsed: float
    duration: float


class _Phase(enum.Enum):
    IDLE = "idle"  # position servos hold the stance; the controller does not run
    SHIFT = "shift"
    SINGLE = "single"
    DOUBLE = "double"
    SETTLE = "settle"
    BALANCE = "balance"  # feet together, QP balancing before the hand-over
    FALLEN = "fallen"


def _mid_angle(a: float, b: float) -> float:
    return a + 0.5 * wrap_angle(b - a)


def _midpoint(a: Point, b: Point) -> Point:
    return 0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])


def _frame_of(step: Footstep) -> Point:
    """The walking frame (midpoint between the feet) that puts this sole at its nominal place [m]."""
    dx, dy = rotate(step.yaw, 0.0, step.side.sign * HALF_STEP_WIDTH)
    return step.x - dx, step.y - dy


class WalkingController:
    """Velocity-commanded walking for the G1, run inside the simulation's control step.

    Args:
        model: the G1 model (from ``robot_models.load("g1")``); the leg and waist actuators are
            switched to torque mode while walking and restored afterwards.
        params: gait parameters (defaults: 0.35 s swing, 0.10 s double support, 6 cm swing height).
    """

    # Gait state (set by _init_state).
    _phase: _Phase
    _phase_time: float  # [s]
    _phase_duration: float  # [s]
    _velocity: Velocity  # rate-limited command
    _measured: Velocity  # filtered measured base velocity
    _steps: int
    _swing_landing: Footstep | None  # the nominal swing target moved by step adjustment

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
        self._sole_site = (model.site(names.LEFT_SOLE_SITE).id, model.site(names.RIGHT_SOLE_SITE).id)
        self._posture = np.zeros(len(MOTOR_JOINTS))
        for i, joint in enumerate(MOTOR_JOINTS):
            for key, value in WALK_CROUCH.items():
                if joint.endswith(f"_{key}_joint"):
                    self._posture[i] = value
        self._com_height = self._crouch_com_height(model)
        self._omega = math.sqrt(GRAVITY / self._com_height)
        self._jac_com = np.zeros((3, model.nv))
        self._preview = ZmpPreview()
        self._sole_half = (names.SOLE_HALF_SIZE[0] - SUPPORT_MARGIN, names.SOLE_HALF_SIZE[1] - SUPPORT_MARGIN)
        self._data: mujoco.MjData | None = None
        self._target: Velocity = _ZERO
        self._stop_point: Point | None = None
        self._stop_heading: float | None = None
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
            return self._target != _ZERO
        return phase is not _Phase.FALLEN

    @property
    def qp_fallback_count(self) -> int:
        """Control steps in which the torque QP failed and the previous contact forces were reused."""
        return self._wbc.fallback_count

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
        self._target = (
            min(max(float(vx), -backward), forward),
            min(max(float(vy), -lateral), lateral),
            min(max(float(wz), -yaw_rate), yaw_rate),
        )

    def set_stop_point(self, point: Point | None) -> None:
        """Walk no farther than ``point`` (world x, y [m]) along the walking heading; None lifts the limit.

        Footsteps are shortened so that the walking frame (the midpoint between the feet) lands on
        the point instead of passing it: a goal-directed walk plans its last steps onto its goal and
        then commands zero (:meth:`stop_point_remaining` says how far the planned frame still is).
        """
        self._stop_point = None if point is None else (float(point[0]), float(point[1]))

    def set_stop_heading(self, heading: float | None) -> None:
        """Turn no farther than ``heading`` (world yaw [rad]); None lifts the limit.

        Turning steps are shortened so that the walking frame's heading lands on it: a turn in place
        commands a yaw rate until :meth:`stop_heading_remaining` is zero, then zero. The heading is
        not wrapped: it is compared with the walking frame's heading, which starts at the measured
        yaw (in [-pi, pi]) when a walk starts and then accumulates the planned turns (so yaw0 + pi
        is half a turn to the left and yaw0 - pi half a turn to the right).

        Raises:
            InvalidGoalError: the heading is not finite.
        """
        if heading is not None and not math.isfinite(heading):
            raise InvalidGoalError(f"stop heading {heading!r} must be a finite number")
        self._stop_heading = None if heading is None else float(heading)

    def stop_heading_remaining(self) -> float:
        """Signed turn [rad] from the planned walking frame's heading to the stop heading (0 without one)."""
        if self._stop_heading is None:
            return 0.0
        return self._stop_heading - self._frame_yaw

    def stop_point_reached(self, tolerance: float = 0.005) -> bool:
        """True when the planned walking frame stands within ``tolerance`` [m] of the stop point (or there is none)."""
        if self._stop_point is None:
            return True
        pos = self._frame_pos
        return math.hypot(self._stop_point[0] - pos[0], self._stop_point[1] - pos[1]) <= tolerance

    def gait_phase(self) -> GaitPhase:
        """The phase of the gait: its kind (idle, shift, single, double, settle, balance, fallen), the
        time spent in it and its planned duration [s]."""
        return GaitPhase(self._phase.value, self._phase_time, self._phase_duration)

    def feet_midpoint(self, data: mujoco.MjData) -> Point:
        """The measured midpoint between the sole centres, world (x, y) [m]: where the walking frame stands."""
        left, right = self._feet(data)
        return _midpoint((left.x, left.y), (right.x, right.y))

    def stop_point_remaining(self) -> float:
        """Distance [m] along the walking heading from the planned walking frame to the stop point.

        The planned frame is the one the last footstep landed in; positive while the stop point is
        ahead, 0 without a stop point.
        """
        if self._stop_point is None:
            return 0.0
        pos, yaw = self._frame_pos, self._frame_yaw
        forward, _ = unrotate(yaw, self._stop_point[0] - pos[0], self._stop_point[1] - pos[1])
        return forward

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
        if self._phase is not _Phase.FALLEN and self._data is not None and self._has_fallen(self._data):
            self._fall_message = "fell while holding the stance"
            self._phase = _Phase.FALLEN
        if not self.active and self._data is not None:
            self._measured = self._instant_velocity(self._data)
        if self._phase is _Phase.FALLEN:
            mode, message = LocomotionMode.FALLEN, self._fall_message + "; reset the simulation"
        elif self._phase is _Phase.IDLE or self._phase is _Phase.BALANCE:
            mode, message = LocomotionMode.STANDING, "standing"
        elif self._target == _ZERO:
            mode, message = LocomotionMode.STOPPING, "stopping: closing the feet"
        else:
            mode, message = LocomotionMode.WALKING, "walking"
        return LocomotionStatus(
            mode=mode,
            steps_taken=self._steps,
            commanded=Twist2D(*self._target),
            measured=Twist2D(*self._measured),
            fallen=self._phase is _Phase.FALLEN,
            message=message,
        )

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Forget the gait, restore the position servos (the keyframe's ctrl holds the stance), zero the command."""
        self._restore_servos(model)
        self._data = data
        self._target = _ZERO
        self._stop_point = None
        self._stop_heading = None
        self._wbc.reset()
        self._init_state()

    def release(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Give the legs back to their position servos, holding the current pose, and stop.

        Call this before removing the controller from the simulation while it is active;
        otherwise the leg actuators would stay in torque mode.
        """
        if self._phase is not _Phase.IDLE and self._phase is not _Phase.FALLEN:
            self._hold_current_pose(model, data)
        self._target = _ZERO
        self._init_state()

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        """One control step: fall check, gait state machine, DCM tracking, torque QP, write torques."""
        self._data = data
        self._dt = control_dt
        if self._phase is _Phase.FALLEN:
            return
        if self._has_fallen(data):
            self._fall_message = f"fell at t={data.time:.2f} s"
            self._phase = _Phase.FALLEN
            self._hold_current_pose(model, data)
            return
        if self._phase is _Phase.IDLE:
            self._start_torque_control(model, data)
        self._filter_command(control_dt)
        self._timing = self._params.timing(self._velocity[0])
        self._stopping = self._target == _ZERO and self._velocity == _ZERO
        self._measure(data, control_dt)
        feet = self._feet(data)
        self._advance_phase(data, feet, control_dt)
        if self._phase is _Phase.IDLE:
            return
        tau = self._wbc.solve(model, data, self._targets(model, data, feet))
        self._last_tau = tau
        data.ctrl[self._motor_actuators] = tau
        self._maybe_hand_over(model, data)

    # ----- state ------------------------------------------------------------------------
    def _init_state(self) -> None:
        self._phase = _Phase.IDLE
        self._phase_time = 0.0
        self._phase_duration = 0.0
        self._velocity = _ZERO
        self._timing = self._params.timing(0.0)  # (single, double support) durations at the current speed [s]
        self._stopping = False
        self._measured = _ZERO
        self._steps = 0
        self._stance = Side.RIGHT
        self._zmp_start: Point = (0.0, 0.0)
        self._frame_pos: Point = (0.0, 0.0)  # planned walking frame (midpoint between the feet) [m]
        self._frame_yaw = 0.0
        self._step_frame_pos: Point = (0.0, 0.0)
        self._line_pos: Point = (0.0, 0.0)  # a point of the path line the walk keeps to [m]
        self._line_yaw = 0.0  # its heading [rad]
        self._line_error = 0.0  # lateral distance of the measured walking frame from the line at lift-off [m]
        self._step_frame_yaw = 0.0
        self._swing_start = (0.0, 0.0, 0.0)  # sole position at lift-off [m]
        self._swing_start_yaw = 0.0
        self._swing_origin = 0.0  # phase time at which the swing trajectory (re)started [s]
        self._swing_height = 0.06  # apex of the swing trajectory above its start [m]
        self._timing_adaptations = 0
        self._swing_target = Footstep(Side.LEFT, 0.0, 0.0, 0.0)  # nominal landing of the current swing
        self._swing_landing = None
        self._swing_closing = False
        self._landed_closing = False
        self._speed_correction = 0.0
        self._touchdown_com: Point = (0.0, 0.0)
        self._touchdown_time = 0.0
        self._still_time = 0.0
        self._time = 0.0
        self._dt = 0.004
        self._last_tau = np.zeros(len(MOTOR_JOINTS))
        self._fall_message = ""
        self._plan: list[PlannedStep] = []  # footsteps planned ahead (see _plan_after)
        self._plan_base: PlannedStep = (self._swing_target, False, (0.0, 0.0), 0.0)
        self._plan_key: tuple[object, ...] = ()

    def _crouch_com_height(self, model: mujoco.MjModel) -> float:
        data = mujoco.MjData(model)
        key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, names.STAND_KEYFRAME)
        if key >= 0:
            mujoco.mj_resetDataKeyframe(model, data, key)
        data.qpos[self._motor_qpos] = self._posture
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        sole = min(data.site_xpos[s][2] for s in self._sole_site)
        return float(data.subtree_com[self._pelvis][2] - sole)

    # ----- actuator modes ---------------------------------------------------------------
    def _start_torque_control(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        ids = self._motor_actuators
        model.actuator_gainprm[ids] = 0.0
        model.actuator_gainprm[ids, 0] = 1.0
        model.actuator_biasprm[ids] = 0.0
        left, right = self._feet(data)
        self._frame_yaw = _mid_angle(left.yaw, right.yaw)
        self._frame_pos = _midpoint((left.x, left.y), (right.x, right.y))
        self._velocity = _ZERO
        self._enter(_Phase.BALANCE, 0.0)
        self._zmp_start = self._frame_pos

    def _restore_servos(self, model: mujoco.MjModel) -> None:
        model.actuator_gainprm[self._motor_actuators] = self._saved_gain
        model.actuator_biasprm[self._motor_actuators] = self._saved_bias

    def _hold_current_pose(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self._restore_servos(model)
        data.ctrl[self._motor_actuators] = data.qpos[self._motor_qpos]

    def _maybe_hand_over(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if self._phase is not _Phase.BALANCE or self._target != _ZERO or self._still_time < HANDOVER_DELAY:
            return
        kp = self._saved_gain[:, 0]
        self._restore_servos(model)
        data.ctrl[self._motor_actuators] = data.qpos[self._motor_qpos] + self._last_tau / kp
        self._phase = _Phase.IDLE

    # ----- measurement ------------------------------------------------------------------
    def _has_fallen(self, data: mujoco.MjData) -> bool:
        height = data.qpos[self._base_qpos + 2]
        up_z = data.xmat[self._pelvis][8]
        return bool(height < FALL_HEIGHT or up_z < _FALL_UP_Z)

    def _feet(self, data: mujoco.MjData) -> tuple[Footstep, Footstep]:
        """The measured soles (left, right): centre (x, y) [m] and yaw [rad] in world."""
        left, right = self._sole_site
        xpos, xmat = data.site_xpos, data.site_xmat
        lx, ly, _ = xpos[left].tolist()
        rx, ry, _ = xpos[right].tolist()
        lm, rm = xmat[left].tolist(), xmat[right].tolist()
        return (
            Footstep(Side.LEFT, lx, ly, math.atan2(lm[3], lm[0])),
            Footstep(Side.RIGHT, rx, ry, math.atan2(rm[3], rm[0])),
        )

    def _instant_velocity(self, data: mujoco.MjData) -> Velocity:
        """Pelvis (vx, vy) in its heading frame [m/s] and yaw rate [rad/s]."""
        mat = data.xmat[self._pelvis].tolist()
        b = self._base_dof
        qvel = data.qvel[b : b + 6].tolist()
        vx, vy = unrotate(math.atan2(mat[3], mat[0]), qvel[0], qvel[1])
        yaw_rate = mat[6] * qvel[3] + mat[7] * qvel[4] + mat[8] * qvel[5]
        return vx, vy, yaw_rate

    def _measure(self, data: mujoco.MjData, dt: float) -> None:
        alpha = min(1.0, dt / VELOCITY_FILTER_TIME)
        now = self._instant_velocity(data)
        old = self._measured
        self._measured = (
            old[0] + alpha * (now[0] - old[0]), old[1] + alpha * (now[1] - old[1]), old[2] + alpha * (now[2] - old[2])
        )

    def _filter_command(self, dt: float) -> None:
        """Move the walking velocity toward the command at the gait's acceleration limits."""
        p = self._params
        linear, angular = p.max_acceleration * dt, p.max_yaw_acceleration * dt
        (vx, vy, wz), (tx, ty, tz) = self._velocity, self._target
        self._velocity = (
            vx + min(max(tx - vx, -linear), linear),
            vy + min(max(ty - vy, -linear), linear),
            wz + min(max(tz - wz, -angular), angular),
        )

    # ----- gait state machine -----------------------------------------------------------
    def _enter(self, phase: _Phase, duration: float) -> None:
        self._phase = phase
        self._phase_time = 0.0
        self._phase_duration = duration

    def _advance_phase(self, data: mujoco.MjData, feet: tuple[Footstep, Footstep], dt: float) -> None:
        self._time += dt
        self._phase_time += dt
        phase = self._phase
        if phase is _Phase.BALANCE:
            target = self._target
            if target != _ZERO:
                lead = Side.RIGHT if (target[1] < 0 or (target[1] == 0 and target[2] < 0)) else Side.LEFT
                left, right = feet
                self._stance = lead.other
                self._zmp_start = _midpoint((left.x, left.y), (right.x, right.y))
                self._frame_yaw = _mid_angle(left.yaw, right.yaw)
                self._frame_pos = self._zmp_start
                self._line_pos, self._line_yaw = self._frame_pos, self._frame_yaw
                self._speed_correction = 0.0
                self._still_time = 0.0
                self._enter(_Phase.SHIFT, SHIFT_DURATION)
            return
        if phase is _Phase.SHIFT:
            if self._stopping:
                # Freeze the ZMP where the shift toward the stance sole has brought it.
                stance = feet[self._stance.index]
                progress = min(self._phase_time / max(self._phase_duration, 1e-6), 1.0)
                sx, sy = self._zmp_start
                self._zmp_start = (sx + progress * (stance.x - sx), sy + progress * (stance.y - sy))
                self._enter(_Phase.SETTLE, SETTLE_DURATION)
            elif self._phase_time >= self._phase_duration:
                com = data.subtree_com[self._pelvis]
                self._touchdown_com = (float(com[0]), float(com[1]))
                self._touchdown_time = self._time
                self._begin_single(data, feet)
            return
        if phase is _Phase.SINGLE:
            if self._phase_time < SWING_FREEZE * self._phase_duration:
                self._swing_target, self._swing_closing = self._next_footstep(
                    self._step_frame_pos, self._step_frame_yaw, self._stance.other, feet[self._stance.index]
                )
            if self._phase_time >= self._phase_duration:
                self._touchdown(data, feet)
            return
        if phase is _Phase.DOUBLE:
            if self._phase_time >= self._phase_duration:
                if self._stopping and self._landed_closing:
                    stance = feet[self._stance.index]
                    self._zmp_start = (stance.x, stance.y)
                    self._enter(_Phase.SETTLE, SETTLE_DURATION)
                else:
                    self._begin_single(data, feet)
            return
        if phase is _Phase.SETTLE:
            if self._phase_time >= self._phase_duration:
                self._enter(_Phase.BALANCE, 0.0)
                left, right = feet
                self._zmp_start = _midpoint((left.x, left.y), (right.x, right.y))
            return

    def _begin_single(self, data: mujoco.MjData, feet: tuple[Footstep, Footstep]) -> None:
        swing = self._stance.other
        position = data.site_xpos[self._sole_site[swing.index]]
        self._swing_start = (float(position[0]), float(position[1]), float(position[2]))
        self._swing_start_yaw = feet[swing.index].yaw
        self._swing_origin = 0.0
        self._swing_height = self._params.step_height
        # Walking frame at the start of this step: measured from the stance sole, with the lateral
        # error against the planned path partly removed (line keeping) and the planned heading.
        # The path line is anchored where the walk started and moved only by the commanded steps
        # (sideways steps, turns), so a lateral bias per step cannot accumulate into a drift.
        stance = feet[self._stance.index]
        mx, my = _frame_of(stance)
        lx, ly = self._line_pos
        forward, lateral = unrotate(self._line_yaw, mx - lx, my - ly)
        dx, dy = rotate(self._line_yaw, forward, 0.0)
        lx, ly = self._line_pos = (lx + dx, ly + dy)  # the foot of the perpendicular from the measured frame
        self._line_error = lateral
        dx, dy = rotate(self._line_yaw, 0.0, lateral * (1.0 - LINE_KEEPING))
        self._step_frame_pos = (lx + dx, ly + dy)
        self._step_frame_yaw = self._frame_yaw
        self._swing_target, self._swing_closing = self._next_footstep(
            self._step_frame_pos, self._step_frame_yaw, swing, stance
        )
        self._swing_landing = None
        self._enter(_Phase.SINGLE, self._timing[0])

    def _touchdown(self, data: mujoco.MjData, feet: tuple[Footstep, Footstep]) -> None:
        target = self._swing_target
        self._steps += 1
        # The path line moves by the step's commanded sideways step and turn.
        velocity = _ZERO if self._stopping else self._velocity
        moved, turned = self._advance_frame(self._step_frame_pos, self._step_frame_yaw, target.side, velocity)
        _, sideways = unrotate(self._step_frame_yaw, moved[0] - self._step_frame_pos[0], moved[1] - self._step_frame_pos[1])
        dx, dy = rotate(self._line_yaw, 0.0, sideways)
        self._line_pos = (self._line_pos[0] + dx, self._line_pos[1] + dy)
        self._line_yaw = turned
        self._frame_yaw = target.yaw
        self._frame_pos = _frame_of(target)
        self._landed_closing = self._swing_closing
        # Speed integral: measured CoM advance over the last step against the command.
        position = data.subtree_com[self._pelvis]
        com = (float(position[0]), float(position[1]))
        elapsed = self._time - self._touchdown_time
        # Not while the speed still ramps toward the command: the lag of a ramp is not an error
        # to integrate (it overshot the new pace after a live 0.5 -> 0.8 m/s change).
        if elapsed > 0 and not self._stopping and self._velocity[0] != 0.0 and self._velocity[0] == self._target[0]:
            advance, _ = unrotate(self._frame_yaw, com[0] - self._touchdown_com[0], com[1] - self._touchdown_com[1])
            speed = advance / elapsed
            period = self._timing[0] + self._timing[1]
            correction = self._speed_correction + SPEED_INTEGRAL_GAIN * (self._velocity[0] - speed) * period
            self._speed_correction = min(max(correction, -SPEED_INTEGRAL_LIMIT), SPEED_INTEGRAL_LIMIT)
        elif self._velocity[0] == 0.0:
            self._speed_correction = 0.0
        self._touchdown_com = com
        self._touchdown_time = self._time
        stance = feet[self._stance.index]
        self._zmp_start = (stance.x, stance.y)
        self._stance = target.side
        # After a shortened swing, hurry on to the next step. (Rushing on a large DCM error as well
        # was measured to lock a live 0.5 -> 0.8 m/s change into a slow gait with rushed steps.)
        adapted = self._swing_origin > 0.0
        self._enter(_Phase.DOUBLE, min(self._timing[1], TIMING_RUSHED_DOUBLE) if adapted else self._timing[1])

    # ----- footsteps ----------------------------------------------------------------------
    def _advance_frame(self, frame_pos: Point, frame_yaw: float, swing: Side, velocity: Velocity) -> tuple[Point, float]:
        """The walking frame one step later [m, rad]."""
        period = self._timing[0] + self._timing[1]
        turn = velocity[2] * period
        forward = velocity[0] * period + (self._speed_correction if velocity[0] != 0.0 else 0.0)
        lateral = 2.0 * velocity[1] * period if velocity[1] * swing.sign > 0 else 0.0
        stop = self._stop_point
        if stop is not None and (forward != 0.0 or lateral != 0.0):
            # Never plan the walking frame past the stop point (along its heading, nor sideways).
            ahead, left = unrotate(frame_yaw, stop[0] - frame_pos[0], stop[1] - frame_pos[1])
            forward = min(forward, max(ahead, 0.0)) if forward > 0.0 else max(forward, min(ahead, 0.0))
            lateral = min(lateral, max(left, 0.0)) if lateral > 0.0 else max(lateral, min(left, 0.0))
        heading = self._stop_heading
        if heading is not None and turn != 0.0:
            # Never plan the walking frame's heading past the stop heading.
            remaining = heading - frame_yaw
            turn = min(turn, max(remaining, 0.0)) if turn > 0.0 else max(turn, min(remaining, 0.0))
        dx, dy = rotate(frame_yaw + 0.5 * turn, forward, lateral)
        return (frame_pos[0] + dx, frame_pos[1] + dy), frame_yaw + turn

    def _place(self, frame_pos: Point, frame_yaw: float, swing: Side, stance: Footstep) -> Footstep:
        dx, dy = rotate(frame_yaw, 0.0, swing.sign * HALF_STEP_WIDTH)
        x, y = self._clip_reach(frame_pos[0] + dx, frame_pos[1] + dy, swing, stance)
        return Footstep(swing, x, y, frame_yaw)

    @staticmethod
    def _clip_reach(x: float, y: float, swing: Side, stance: Footstep) -> Point:
        """The nearest sole position to (x, y) within the swing leg's reach box around the stance sole [m]."""
        relative_forward, left = unrotate(stance.yaw, x - stance.x, y - stance.y)
        forward = min(max(relative_forward, REACH_X[0]), REACH_X[1])
        outward = min(max(swing.sign * left, REACH_LATERAL[0]), REACH_LATERAL[1])
        if forward == relative_forward and outward == swing.sign * left:
            return x, y  # within reach: the position itself (not its rotated round trip)
        dx, dy = rotate(stance.yaw, forward, swing.sign * outward)
        return stance.x + dx, stance.y + dy

    def _next_footstep(self, frame_pos: Point, frame_yaw: float, swing: Side, stance: Footstep) -> tuple[Footstep, bool]:
        """The next landing of ``swing`` and whether it is a closing (zero-velocity) step."""
        footstep, closing, _, _ = self._next_footstep_and_frame(frame_pos, frame_yaw, swing, stance)
        return footstep, closing

    def _next_footstep_and_frame(self, frame_pos: Point, frame_yaw: float, swing: Side, stance: Footstep) -> PlannedStep:
        """The next landing of ``swing``, whether it closes the feet, and the walking frame after it."""
        velocity = _ZERO if self._stopping else self._velocity
        new_pos, new_yaw = self._advance_frame(frame_pos, frame_yaw, swing, velocity)
        return self._place(new_pos, new_yaw, swing, stance), velocity == _ZERO, new_pos, new_yaw

    def _plan_after(self, frame_pos: Point, frame_yaw: float, support: Footstep) -> None:
        """Plan (on demand, :meth:`_planned_step`) the footsteps after the planned ``support``.

        They depend only on that footstep, the walking frame it leaves and the filtered command,
        none of them measured: the steps already planned are kept while these are unchanged, which
        at a steady command means for a whole gait phase.
        """
        key = (frame_pos, frame_yaw, support, self._stopping, self._velocity, self._speed_correction,
               self._timing, self._stop_point)
        if key != self._plan_key:
            self._plan_key = key
            self._plan_base = (support, False, frame_pos, frame_yaw)
            self._plan = []

    def _planned_step(self, index: int) -> PlannedStep:
        """The ``index``-th footstep after the support given to :meth:`_plan_after`, planned on demand."""
        plan = self._plan
        while len(plan) <= index:
            footstep, _, frame_pos, frame_yaw = plan[-1] if plan else self._plan_base
            plan.append(self._next_footstep_and_frame(frame_pos, frame_yaw, footstep.side.other, footstep))
        return plan[index]

    def _fill_preview(self, feet: tuple[Footstep, Footstep]) -> None:
        """Refill :attr:`_preview` with the ZMP reference from now to the horizon (or to standing)."""
        preview = self._preview
        preview.clear()
        t_ss, t_ds = self._timing
        stance = feet[self._stance.index]
        here = (stance.x, stance.y)
        phase = self._phase
        if phase is _Phase.BALANCE:
            preview.add(1.0, self._zmp_start, self._zmp_start)
            return
        if phase is _Phase.SETTLE:
            mid = _midpoint((feet[0].x, feet[0].y), (feet[1].x, feet[1].y))
            preview.add(self._phase_duration, self._zmp_start, mid)
            preview.add(1.0, mid, mid)
            return
        if phase is _Phase.SHIFT:
            preview.add(self._phase_duration, self._zmp_start, here)
            preview.add(t_ss, here, here)
            planned = self._phase_duration + t_ss  # the pieces' total duration so far [s]
            frame_pos, frame_yaw = self._frame_pos, self._frame_yaw
            support = stance
            closing = False
        elif phase is _Phase.SINGLE:
            preview.add(self._phase_duration, here, here)
            target = self._swing_target
            landing = (target.x, target.y)
            preview.add(t_ds, here, landing)
            if self._stopping and self._swing_closing:
                mid = _midpoint(here, landing)
                preview.add(SETTLE_DURATION, landing, mid)
                preview.add(1.0, mid, mid)
                return
            preview.add(t_ss, landing, landing)
            planned = self._phase_duration + t_ds + t_ss
            frame_pos, frame_yaw = _frame_of(target), target.yaw
            support = target
            closing = self._swing_closing
        else:  # DOUBLE
            preview.add(self._phase_duration, self._zmp_start, here)
            if self._stopping and self._landed_closing:
                mid = _midpoint(self._zmp_start, here)
                preview.add(SETTLE_DURATION, here, mid)
                preview.add(1.0, mid, mid)
                return
            preview.add(t_ss, here, here)
            planned = self._phase_duration + t_ss
            frame_pos, frame_yaw = self._frame_pos, self._frame_yaw
            support = stance
            closing = False
        total = planned - self._phase_time
        # The first footstep after a measured support (double support, shift) is planned every step;
        # the ones after a planned footstep come from _plan.
        measured = phase is not _Phase.SINGLE
        count = 0
        while total < HORIZON:
            if self._stopping and closing:
                break
            if measured and count == 0:
                step = self._next_footstep_and_frame(frame_pos, frame_yaw, support.side.other, support)
                self._plan_after(step[2], step[3], step[0])
            else:
                if count == 0:
                    self._plan_after(frame_pos, frame_yaw, support)
                step = self._planned_step(count - 1 if measured else count)
            footstep, closing, frame_pos, frame_yaw = step
            count += 1
            landing = (footstep.x, footstep.y)
            preview.add(t_ds, (support.x, support.y), landing)
            preview.add(t_ss, landing, landing)
            total += t_ds + t_ss
            support = footstep
        if self._stopping and closing:
            _, _, _, last_x, last_y = preview.pieces[-1]
            _, before_x, before_y, _, _ = preview.pieces[-2]
            last = (last_x, last_y)
            mid = _midpoint(last, (before_x, before_y))
            preview.add(SETTLE_DURATION, last, mid)
            preview.add(1.0, mid, mid)

    def _adjusted_landing(
        self, stance: Footstep, cop: Point, dcm: Point, planned_dcm: Point, remaining: float
    ) -> tuple[Footstep, float]:
        """Step adjustment: move the landing by the predicted end-of-step DCM error.

        The error is measured against the unadjusted plan (``planned_dcm``, the end-of-swing DCM of
        the preview built from the nominal target), so the adjustment does not cancel itself.

        Args:
            remaining: swing time left [s]; the DCM error grows as exp(omega * remaining).

        Returns:
            The landing, and how far [m] the reach box moved it from where the DCM needs it.
        """
        target = self._swing_target
        growth = math.exp(self._omega * remaining)
        offset_x = cop[0] + growth * (dcm[0] - cop[0]) - planned_dcm[0]
        offset_y = cop[1] + growth * (dcm[1] - cop[1]) - planned_dcm[1]
        size = math.sqrt(offset_x * offset_x + offset_y * offset_y)
        scale = max(size - STEP_ADJUST_DEADBAND, 0.0) / max(size, 1e-9)
        # Landing exactly at the predicted DCM error leaves a sideways error as it is (the DCM walks
        # on, parallel to the path). Landing a little farther out on the side of the error moves
        # the DCM back toward the path line over the next steps.
        away = min(max(LINE_STEP_GAIN * self._line_error, -LINE_STEP_LIMIT), LINE_STEP_LIMIT)
        away_x, away_y = rotate(self._line_yaw, 0.0, away)
        if scale == 0.0 and away == 0.0:
            return target, 0.0
        wanted_x, wanted_y = target.x + offset_x * scale + away_x, target.y + offset_y * scale + away_y
        x, y = self._clip_reach(wanted_x, wanted_y, target.side, stance)
        excess_x, excess_y = unrotate(stance.yaw, wanted_x - x, wanted_y - y)
        if not TIMING_CROSSOVER and excess_y * target.side.sign < 0.0:
            excess_y = 0.0  # a crossover the feet cannot make: landing sooner does not help
        return Footstep(target.side, x, y, target.yaw), math.hypot(excess_x, excess_y)

    def _adapt_timing(self, data: mujoco.MjData, stance: Footstep, cop: Point, dcm: Point, planned_dcm: Point) -> None:
        """Step-timing adaptation: when the landing the DCM needs is out of reach, land sooner.

        The DCM error grows as exp(omega t) until touchdown, so an earlier touchdown needs a
        smaller step. The swing is shortened to the longest remaining time (in steps of 15%, at
        least :data:`TIMING_MIN_REMAINING`) whose landing is within reach, and the swing trajectory
        restarts from where the sole is.
        """
        elapsed = self._phase_time
        remaining = self._phase_duration - elapsed
        shortest = max(TIMING_MIN_REMAINING, TIMING_MIN_SWING - elapsed)
        if remaining - shortest < TIMING_MIN_CHANGE:
            return
        if self._adjusted_landing(stance, cop, dcm, planned_dcm, remaining)[1] <= TIMING_TRIGGER:
            return
        chosen = remaining
        while chosen > shortest:
            chosen = max(chosen * 0.85, shortest)
            if self._adjusted_landing(stance, cop, dcm, planned_dcm, chosen)[1] <= TIMING_TRIGGER:
                break
        if remaining - chosen < TIMING_MIN_CHANGE:
            return
        self._phase_duration = elapsed + chosen
        self._timing_adaptations += 1
        swing = stance.side.other
        position = data.site_xpos[self._sole_site[swing.index]]
        xmat = data.site_xmat[self._sole_site[swing.index]]
        self._swing_start = (float(position[0]), float(position[1]), float(position[2]))
        self._swing_start_yaw = math.atan2(float(xmat[3]), float(xmat[0]))
        self._swing_origin = elapsed
        self._swing_height = max(TIMING_SWING_HEIGHT * self._params.step_height - self._swing_start[2], TIMING_MIN_HEIGHT)

    # ----- tasks ------------------------------------------------------------------------
    def _support_hull(self, data: mujoco.MjData, sides: tuple[int, ...]) -> list[Point]:
        """The support polygon (counter-clockwise), shrunk by the support margin, world frame [m].

        One sole's polygon is its rectangle, already convex and in counter-clockwise order; two soles
        take the convex hull of their eight corners.
        """
        hx, hy = self._sole_half
        points: list[Point] = []
        for side in sides:
            site = self._sole_site[side]
            px, py, _ = data.site_xpos[site].tolist()
            r00, r01, _, r10, r11, _, _, _, _ = data.site_xmat[site].tolist()
            for sx, sy in _CORNER_SIGNS:
                a, b = sx * hx, sy * hy
                points.append((px + (r00 * a + r01 * b), py + (r10 * a + r11 * b)))
        return points if len(sides) == 1 else hull_of(points)

    def _com_jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The CoM Jacobian, shape (3, nv) [m/rad or 1]."""
        mujoco.mj_jacSubtreeCom(model, data, self._jac_com, self._pelvis)
        return self._jac_com

    def _targets(self, model: mujoco.MjModel, data: mujoco.MjData, feet: tuple[Footstep, Footstep]) -> WbcTargets:
        cx, cy, cz = data.subtree_com[self._pelvis].tolist()
        vx, vy, vz = (self._com_jacobian(model, data) @ data.qvel).tolist()
        omega = self._omega
        self._fill_preview(feet)
        first_end_dcm = self._preview.dcm_at_first_end(omega)
        reference = self._preview.reference(self._phase_time, omega, first_end_dcm)
        dcm = (cx + vx / omega, cy + vy / omega)
        gain = 1.0 + DCM_GAIN / omega
        cop_x = reference.zmp_x + gain * (dcm[0] - reference.dcm_x)
        cop_y = reference.zmp_y + gain * (dcm[1] - reference.dcm_y)
        single = self._phase is _Phase.SINGLE
        stance = self._stance
        sides = (stance.index,) if single else (0, 1)
        cop = clip_point(cop_x, cop_y, self._support_hull(data, sides))
        omega2 = omega**2
        acceleration = np.array([
            omega2 * (cx - cop[0]),
            omega2 * (cy - cop[1]),
            HEIGHT_KP * (self._com_height - cz) - HEIGHT_KD * vz,
        ])
        speed = math.sqrt(vx * vx + vy * vy)
        self._still_time = self._still_time + self._dt if speed < HANDOVER_SPEED else 0.0

        load = [1.0, 1.0]
        swing_refs: list[SwingSample | None] = [None, None]
        heading = _mid_angle(feet[0].yaw, feet[1].yaw)
        if single:
            swing = stance.other
            load[swing.index] = 0.0
            if self._phase_time < SWING_FREEZE * self._phase_duration or self._swing_landing is None:
                # The end-of-swing DCM of the plan: the reference at the end of the first piece
                # (the DCM the ZMP plan after this swing needs; it does not depend on the swing's length).
                planned = (first_end_dcm[0], first_end_dcm[1])
                if TIMING_ADAPTATION and self._phase_time < SWING_FREEZE * self._phase_duration:
                    self._adapt_timing(data, feet[stance.index], cop, dcm, planned)
                remaining = max(self._phase_duration - self._phase_time, 0.0)
                self._swing_landing, _ = self._adjusted_landing(feet[stance.index], cop, dcm, planned, remaining)
            origin = self._swing_origin
            sample = swing_sample(
                self._swing_start, self._swing_start_yaw, self._swing_landing, self._swing_height,
                self._phase_time - origin, self._phase_duration - origin,
            )
            swing_refs[swing.index] = sample
            heading = _mid_angle(feet[stance.index].yaw, sample.yaw)
        elif self._phase is _Phase.DOUBLE:
            load[stance.index] = min(1.0, self._phase_time / LOAD_RAMP)
            load[stance.other.index] = max(0.0, 1.0 - self._phase_time / max(self._phase_duration, 1e-6))
        return WbcTargets(
            com_acceleration=acceleration,
            heading=heading,
            load=(load[0], load[1]),
            swing=(swing_refs[0], swing_refs[1]),
            posture=self._posture,
        )
