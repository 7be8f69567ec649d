"""DCM walking with a whole-body torque QP, as the simulation's ``Slot.LOCOMOTION`` controller.

Every control step: the command is filtered (:mod:`.command`); the phase machine (:mod:`.phases`)
moves the gait on, planning each swing's landing from the measured footholds, the filtered command
and a line-keeping pull toward the path (:mod:`.footsteps`, :mod:`.path`, :mod:`.stopping`); the
footstep plan gives a ZMP reference, whose DCM reference comes from closed-form backward
integration (:mod:`.preview`); DCM tracking gives a desired CoP, hence a CoM acceleration
(:mod:`.tracking`); the predicted DCM error moves and times the landing (:mod:`.adjustment`); the
torque QP (:mod:`.wbc`) turns it all into leg and waist torques.

While walking, the leg and waist actuators are switched from position servos to torque motors
(:mod:`.actuation`; their gains are restored when the robot stands still again, holding the pose it
stopped in). The floating base is never written: the robot moves only through its feet pushing on
the floor.

The controller knows no robot: the robot's names, crouch, step geometry and limits come in a
:class:`~robot_models.biped.BipedDescription`.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from robot_models.biped import BipedDescription
from robot_models.spec import RobotModelError
from sim_bridge.errors import InvalidGoalError
from sim_bridge.locomotion.actuation import Actuation, HandOver
from sim_bridge.locomotion.adjustment import DcmState, StepAdjuster
from sim_bridge.locomotion.command import ZERO, CommandFilter
from sim_bridge.locomotion.estimation import Estimator
from sim_bridge.locomotion.external import ExternalContacts
from sim_bridge.locomotion.footsteps import FootstepPlanner, Reach
from sim_bridge.locomotion.geometry import Footstep, Point, mid_angle, midpoint
from sim_bridge.locomotion.params import GaitParameters
from sim_bridge.locomotion.path import PathState
from sim_bridge.locomotion.phases import GaitMachine, GaitState, Phase
from sim_bridge.locomotion.preview import ZmpPreview, fill_preview
from sim_bridge.locomotion.stopping import StopLimits
from sim_bridge.locomotion.swing import SwingSample, SwingState
from sim_bridge.locomotion.tracking import DcmTracking, foot_loads
from sim_bridge.locomotion.types import GaitPhase, LocomotionMode, LocomotionStatus, Twist2D
from sim_bridge.locomotion.wbc import WbcTargets, WholeBodyQP


class WalkingController:
    """Velocity-commanded walking for a biped, run inside the simulation's control step.

    Args:
        model: the robot model (from ``robot_models.load``); the leg and waist actuators are
            switched to torque mode while walking and restored afterwards.
        biped: the robot's walking facts, its spec's ``biped`` (e.g. ``robot_models.g1_gait.BIPED``).
        params: gait parameters (defaults: 0.35 s swing, 0.10 s double support, 6 cm swing height).

    Raises:
        RobotModelError: ``biped`` is None (the robot does not walk).
        TypeError: ``biped`` is not a :class:`~robot_models.biped.BipedDescription`.
    """

    def __init__(self, model: mujoco.MjModel, biped: BipedDescription | None,
                 params: GaitParameters | None = None) -> None:
        if biped is None:
            raise RobotModelError("this robot has no biped description (RobotSpec.biped): it cannot walk")
        if not isinstance(biped, BipedDescription):
            raise TypeError(f"biped must be a BipedDescription, got {type(biped).__name__} (params come third)")
        self._biped = biped
        self._params = params or GaitParameters()
        self._wbc = WholeBodyQP(model, biped)
        self._actuation = Actuation(model, biped.motor_joints)
        self._estimator = Estimator(model, biped)
        self._posture = np.array([biped.walk_posture.get(joint, 0.0) for joint in biped.motor_joints])
        com_height = self._estimator.com_height_in_pose(model, biped.stand_keyframe, self._actuation.qpos, self._posture)
        self._tracking = DcmTracking(com_height)
        self._reach = Reach.of(biped)
        self._adjuster = StepAdjuster(self._tracking.omega, self._reach)
        self._preview = ZmpPreview()
        self._command = CommandFilter(biped.steps, self._params)
        self._stop = StopLimits()
        self._data: mujoco.MjData | None = None
        self._holding_balance = False
        self._init_state()

    # ----- public API -------------------------------------------------------------------
    def hold_balance(self, on: bool) -> None:
        """While on, a standing robot keeps balancing on both feet with the torque QP instead of handing its
        legs back to the position servos: for work with the arms, whose swings would rock a robot standing on
        stiff servos. Off: the usual hand-over once the CoM is still. A reset turns it off."""
        self._holding_balance = on

    @property
    def holding_balance(self) -> bool:
        return self._holding_balance

    @property
    def params(self) -> GaitParameters:
        return self._params

    @property
    def com_height(self) -> float:
        """CoM height the walk keeps above the floor [m]."""
        return self._tracking.com_height

    @property
    def active(self) -> bool:
        # Called every control step by the simulation: plain comparisons only.
        phase = self._gait.phase
        if phase is Phase.IDLE:
            return self._holding_balance or self._command.target != ZERO
        return phase is not Phase.FALLEN

    @property
    def qp_fallback_count(self) -> int:
        """Control steps in which the torque QP failed and the previous contact forces were reused."""
        return self._wbc.fallback_count

    @property
    def external_contacts(self) -> ExternalContacts:
        """Movable objects' contact forces on the robot besides its soles (a held object), as the QP last took them in."""
        return self._wbc.external

    def set_velocity_command(self, vx: float, vy: float, wz: float) -> None:
        """Command a walking velocity in the base heading frame; zero stops and stands with the feet together.

        Args:
            vx: forward speed [m/s], clamped to [-max_backward_speed, max_forward_speed].
            vy: leftward speed [m/s], clamped to +-max_lateral_speed.
            wz: turning rate [rad/s], clamped to +-max_yaw_rate.
            All limits are further reduced to what one step can reach
            (:meth:`GaitParameters.speed_limits`).

        Raises:
            InvalidGoalError: a component is not a finite number.
        """
        self._command.set_target(vx, vy, wz, self._params)

    def set_stop_point(self, point: Point | None) -> None:
        """Walk no farther than ``point`` (world x, y [m]) along the walking heading; None lifts the limit.

        Footsteps are shortened so that the walking frame (the midpoint between the feet) lands on
        the point instead of passing it: a goal-directed walk plans its last steps onto its goal and
        then commands zero (:meth:`stop_point_remaining` says how far the planned frame still is).
        """
        self._stop.set_point(point)

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
        self._stop.set_heading(heading)

    def stop_heading_remaining(self) -> float:
        """Signed turn [rad] from the planned walking frame's heading to the stop heading (0 without one)."""
        return self._stop.heading_remaining(self._path.frame_yaw)

    def stop_point_reached(self, tolerance: float = 0.005) -> bool:
        """True when the planned walking frame stands within ``tolerance`` [m] of the stop point (or there is none)."""
        return self._stop.point_reached(self._path.frame_pos, tolerance)

    def gait_phase(self) -> GaitPhase:
        """The phase of the gait: its kind (idle, shift, single, double, settle, balance, fallen), the
        time spent in it and its planned duration [s]."""
        gait = self._gait
        return GaitPhase(gait.phase.value, gait.elapsed, gait.duration)

    def feet_midpoint(self, data: mujoco.MjData) -> Point:
        """The measured midpoint between the sole centres, world (x, y) [m]: where the walking frame stands."""
        left, right = self._estimator.feet(data)
        return midpoint((left.x, left.y), (right.x, right.y))

    def planned_footsteps(self) -> list[tuple[float, float, float]]:
        """The footsteps planned ahead, (x [m], y [m], yaw [rad]) of each sole in world, next first (empty standing)."""
        planner = getattr(self, "_planner", None)
        return [] if planner is None else [(step.x, step.y, step.yaw) for step in planner.planned()]

    def stop_point_remaining(self) -> float:
        """Distance [m] along the walking heading from the planned walking frame to the stop point.

        The planned frame is the one the last footstep landed in; positive while the stop point is
        ahead, 0 without a stop point.
        """
        return self._stop.point_remaining(self._path.frame_pos, self._path.frame_yaw)

    def set_gait_parameters(self, params: GaitParameters) -> None:
        """Apply new gait parameters; they take effect from the next phase of the gait.

        Raises:
            InvalidGoalError: ``params`` is not a :class:`GaitParameters` (values are validated when it is built).
        """
        if not isinstance(params, GaitParameters):
            raise InvalidGoalError(f"expected GaitParameters, got {type(params).__name__}")
        self._params = params
        self.set_velocity_command(*self._command.target)

    def status(self) -> LocomotionStatus:
        """The current mode, step count, command and measured velocity."""
        gait, data = self._gait, self._data
        if gait.phase is not Phase.FALLEN and data is not None and self._estimator.has_fallen(data):
            self._fall_message = "fell while holding the stance"
            gait.phase = Phase.FALLEN
        if not self.active and data is not None:
            self._estimator.measured = self._estimator.instant_velocity(data)
        target = self._command.target
        if gait.phase is Phase.FALLEN:
            mode, message = LocomotionMode.FALLEN, self._fall_message + "; reset the simulation"
        elif gait.phase is Phase.IDLE or gait.phase is Phase.BALANCE:
            mode, message = LocomotionMode.STANDING, "standing"
        elif target == ZERO:
            mode, message = LocomotionMode.STOPPING, "stopping: closing the feet"
        else:
            mode, message = LocomotionMode.WALKING, "walking"
        return LocomotionStatus(
            mode=mode,
            steps_taken=gait.steps,
            commanded=Twist2D(*target),
            measured=Twist2D(*self._estimator.measured),
            fallen=gait.phase is Phase.FALLEN,
            message=message,
        )

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Forget the gait, restore the position servos (the keyframe's ctrl holds the stance), zero the command."""
        self._actuation.restore_servos(model)
        self._data = data
        self._command.target = ZERO
        self._stop.clear()
        self._wbc.reset()
        self._holding_balance = False
        self._init_state()

    def release(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Give the legs back to their position servos, holding the current pose, and stop.

        Call this before removing the controller from the simulation while it is active;
        otherwise the leg actuators would stay in torque mode.
        """
        if self._gait.phase is not Phase.IDLE and self._gait.phase is not Phase.FALLEN:
            self._actuation.hold_current_pose(model, data)
        self._command.target = ZERO
        self._init_state()

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        """One control step: fall check, gait state machine, DCM tracking, torque QP, write torques."""
        self._data = data
        gait = self._gait
        if gait.phase is Phase.FALLEN:
            return
        if self._estimator.has_fallen(data):
            self._fall_message = f"fell at t={data.time:.2f} s"
            gait.phase = Phase.FALLEN
            self._actuation.hold_current_pose(model, data)
            return
        if gait.phase is Phase.IDLE:
            self._take_over(model, data)
        self._command.step(control_dt, self._params)
        self._estimator.filter_velocity(data, control_dt)
        feet = self._estimator.feet(data)
        self._machine.advance(data, feet, control_dt, self._params)
        if gait.phase is Phase.IDLE:
            return
        self._actuation.write_torque(data, self._wbc.solve(model, data, self._targets(model, data, feet, control_dt)))
        if gait.phase is Phase.BALANCE and self._command.target == ZERO and self._hand_over.due and not self._holding_balance:
            self._actuation.hand_over(model, data)
            gait.phase = Phase.IDLE

    # ----- composition ------------------------------------------------------------------
    def _init_state(self) -> None:
        """A new walk's state (the command target and the stop limits are kept)."""
        self._gait = GaitState()
        self._swing = SwingState()
        self._path = PathState()
        self._hand_over = HandOver()
        self._command.restart(self._params)
        self._estimator.measured = ZERO
        self._planner = FootstepPlanner(self._biped.half_step_width_m, self._reach, self._command, self._path, self._stop)
        self._machine = GaitMachine(self._gait, self._swing, self._path, self._planner, self._command, self._estimator,
                                    self._hand_over)
        self._fall_message = ""

    def _take_over(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Switch the actuators to torque and start balancing on both feet."""
        self._actuation.to_torque(model)
        self._machine.balance(self._estimator.feet(data))
        self._command.velocity = ZERO

    def _com_jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The CoM Jacobian, shape (3, nv) [m/rad or 1]."""
        return self._estimator.com_jacobian(model, data)

    def _targets(self, model: mujoco.MjModel, data: mujoco.MjData, feet: tuple[Footstep, Footstep],
                 control_dt: float) -> WbcTargets:
        """What the QP realises this step: the CoM acceleration of DCM tracking, the swing sole's
        reference toward its adjusted landing, the pelvis heading and the feet's loads."""
        gait, swing, estimator = self._gait, self._swing, self._estimator
        cx, cy, cz = data.subtree_com[estimator.pelvis].tolist()
        vx, vy, vz = (self._com_jacobian(model, data) @ data.qvel).tolist()
        omega = self._tracking.omega
        fill_preview(self._preview, feet, gait, swing, self._path, self._command, self._planner)
        first_end_dcm = self._preview.dcm_at_first_end(omega)
        reference = self._preview.reference(gait.elapsed, omega, first_end_dcm)
        dcm = (cx + vx / omega, cy + vy / omega)
        single = gait.phase is Phase.SINGLE
        stance = gait.stance
        cop = self._tracking.cop(reference, dcm, estimator.support_hull(data, (stance.index,) if single else (0, 1)))
        acceleration = self._tracking.com_acceleration((cx, cy, cz), vz, cop)
        self._hand_over.track(math.sqrt(vx * vx + vy * vy), control_dt)

        swing_refs: list[SwingSample | None] = [None, None]
        heading = mid_angle(feet[0].yaw, feet[1].yaw)
        if single:
            landing = swing.landing
            if gait.swing_adjustable or landing is None:
                # The end-of-swing DCM of the plan: the reference at the end of the first piece
                # (the DCM the ZMP plan after this swing needs; it does not depend on the swing's length).
                state = DcmState(cop, dcm, (first_end_dcm[0], first_end_dcm[1]))
                landing = swing.landing = self._adjuster.update(
                    data, estimator, gait, swing, self._path, feet[stance.index], state, self._params
                )
            sample = swing.sample(landing, gait.elapsed, gait.duration)
            swing_refs[stance.other.index] = sample
            heading = mid_angle(feet[stance.index].yaw, sample.yaw)
        return WbcTargets(
            com_acceleration=acceleration,
            heading=heading,
            load=foot_loads(gait),
            swing=(swing_refs[0], swing_refs[1]),
            posture=self._posture,
        )
