"""Whole-body torque QP: joint accelerations and sole-corner forces that realise the balance tasks.

Decision variables x = [f (3 per sole corner, world frame) [N], qacc (nv) [m/s^2, rad/s^2]].
Equalities: the floating-base rows of M qacc + h = tau + J_c^T f (h = qfrc_bias - qfrc_passive),
and the servo-driven joints' rows with their position servo's own torque. Inequalities: friction
pyramids, bounded normal forces (a per-foot load scale), joint torque limits. Costs: CoM acceleration
(through the total contact force), pelvis and torso orientation, stance soles fixed (soft), swing sole
tracking, posture. Solved with DAQP.
"""

from __future__ import annotations

from dataclasses import dataclass

import daqp
import mujoco
import numpy as np

from robot_models import g1_constants as names
from sim_bridge.locomotion.planner import Side, SwingSample

GRAVITY = 9.81
FRICTION = 0.6  # pyramid coefficient used by the QP (the floor has 1.0)
CORNERS_PER_FOOT = 4
FORCE_BLOCK = 2 * CORNERS_PER_FOOT * 3

W_COM = 10.0
W_PELVIS = 5.0
W_TORSO = 2.5
W_STANCE = 1000.0
W_SWING = 10.0
W_POSTURE = 0.05
W_POSTURE_LEG = 0.005
W_REG_QACC = 1e-5
W_REG_FORCE = 1e-7
ORIENTATION_KP, ORIENTATION_KD = 150.0, 25.0
SWING_KP, SWING_KD = 400.0, 40.0
POSTURE_KP, POSTURE_KD = 100.0, 20.0
STANCE_KD = 10.0
KNEE_MIN = 0.05  # the QP keeps the knees at least this bent [rad]
KNEE_HORIZON = 0.05  # look-ahead of the knee limit [s]


@dataclass(frozen=True)
class WbcTargets:
    """What the QP should realise this control step.

    Attributes:
        com_acceleration: desired CoM acceleration in world, shape (3,) [m/s^2].
        heading: desired pelvis and torso yaw [rad] (roll and pitch are zero).
        load: per foot, the upper bound on its normal force as a fraction of full load, in [0, 1].
        swing: per foot, the swing reference, or None for a foot that must stay put.
        posture: target position of every motor joint, in ``motor_joints`` order [rad].
    """

    com_acceleration: np.ndarray
    heading: float
    load: dict[Side, float]
    swing: dict[Side, SwingSample | None]
    posture: np.ndarray


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


class WholeBodyQP:
    """Builds and solves the torque QP on the current state of a MuJoCo model.

    Args:
        model: the robot model.
        motor_joints: joints driven by torque (legs, waist), in the order torques are returned.
        servo_joints: joints left on their position servos (arms); their torque is predicted, not chosen.
    """

    def __init__(self, model: mujoco.MjModel, motor_joints: tuple[str, ...], servo_joints: tuple[str, ...]) -> None:
        self.nv = model.nv
        self.n = FORCE_BLOCK + self.nv
        self.mass = float(np.sum(model.body_mass))
        self.motor_dofs = np.array([model.joint(j).dofadr[0] for j in motor_joints])
        self.servo_dofs = np.array([model.joint(j).dofadr[0] for j in servo_joints])
        self.servo_qpos = np.array([model.joint(j).qposadr[0] for j in servo_joints])
        self.servo_actuators = np.array([model.actuator(j).id for j in servo_joints])
        self.motor_qpos = np.array([model.joint(j).qposadr[0] for j in motor_joints])
        knees = [j for j in names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS if j.endswith("_knee_joint")]
        self.knee_dofs = np.array([model.joint(j).dofadr[0] for j in knees])
        self.knee_qpos = np.array([model.joint(j).qposadr[0] for j in knees])
        self.torque_limit = np.array([model.jnt_actfrcrange[model.joint(j).id] for j in motor_joints])
        self.servo_limit = np.array([model.jnt_actfrcrange[model.joint(j).id] for j in servo_joints])
        leg = set(names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS)
        self.posture_weight = np.array([W_POSTURE_LEG if j in leg else W_POSTURE for j in motor_joints])
        self.foot_body = {Side.LEFT: model.body(names.LEFT_FOOT_BODY).id, Side.RIGHT: model.body(names.RIGHT_FOOT_BODY).id}
        self.sole_site = {Side.LEFT: model.site(names.LEFT_SOLE_SITE).id, Side.RIGHT: model.site(names.RIGHT_SOLE_SITE).id}
        self.pelvis = model.body(names.ROOT_BODY).id
        self.torso = model.body(names.TORSO_BODY).id
        cx, cy, cz = names.SOLE_CENTER_IN_FOOT
        hx, hy, hz = names.SOLE_HALF_SIZE
        self.corners_in_foot = np.array([[cx + sx * hx, cy + sy * hy, cz - hz] for sx in (1, -1) for sy in (1, -1)])
        self._mass_matrix = np.zeros((self.nv, self.nv))
        self._jac = np.zeros((3, self.nv))
        self._jac_rot = np.zeros((3, self.nv))
        self._jac_dot = np.zeros((3, self.nv))
        self._jac_dot_rot = np.zeros((3, self.nv))
        self.last_force = np.zeros(FORCE_BLOCK)
        self.last_status = 1
        base_dof = model.jnt_dofadr[model.body_jntadr[self.pelvis]]
        self.base_dofs = np.arange(base_dof, base_dof + 6)
        # Constant rows: |f_x|, |f_y| <= mu f_z per corner; total force / mass; posture and knee selectors.
        nf = FORCE_BLOCK
        self._friction_rows = np.zeros((4 * 2 * CORNERS_PER_FOOT, self.n))
        for c in range(2 * CORNERS_PER_FOOT):
            for k, (axis, sign) in enumerate(((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0))):
                self._friction_rows[4 * c + k, 3 * c + axis] = sign
                self._friction_rows[4 * c + k, 3 * c + 2] = -FRICTION
        self._com_rows = np.zeros((3, self.n))
        self._com_rows[:, :nf] = np.tile(np.eye(3), (1, 2 * CORNERS_PER_FOOT)) / self.mass
        self._posture_rows = np.zeros((len(self.motor_dofs), self.n))
        self._posture_rows[np.arange(len(self.motor_dofs)), nf + self.motor_dofs] = 1.0
        self._knee_rows = np.zeros((len(self.knee_dofs), self.n))
        self._knee_rows[np.arange(len(self.knee_dofs)), nf + self.knee_dofs] = 1.0

    # ----- kinematics helpers -----------------------------------------------------------
    def corners(self, data: mujoco.MjData, side: Side) -> np.ndarray:
        """World positions of the four sole corners of a foot, shape (4, 3) [m]."""
        body = self.foot_body[side]
        return data.xpos[body] + self.corners_in_foot @ data.xmat[body].reshape(3, 3).T

    def _body_rot_task(self, model: mujoco.MjModel, data: mujoco.MjData, body: int, yaw: float) -> tuple[np.ndarray, np.ndarray]:
        mujoco.mj_jacBody(model, data, None, self._jac_rot, body)
        mujoco.mj_jacDot(model, data, None, self._jac_dot_rot, data.xpos[body], body)
        error_local = np.zeros(3)
        mujoco.mju_subQuat(error_local, _yaw_quat(yaw), data.xquat[body])
        rot = data.xmat[body].reshape(3, 3)
        error = rot @ error_local
        omega = self._jac_rot @ data.qvel
        target = ORIENTATION_KP * error - ORIENTATION_KD * omega - self._jac_dot_rot @ data.qvel
        return self._jac_rot.copy(), target

    def _site_jacobians(self, model: mujoco.MjModel, data: mujoco.MjData, side: Side) -> tuple[np.ndarray, np.ndarray]:
        site = self.sole_site[side]
        jac = np.zeros((6, self.nv))
        jac_dot = np.zeros((6, self.nv))
        mujoco.mj_jacSite(model, data, jac[:3], jac[3:], site)
        mujoco.mj_jacDot(model, data, jac_dot[:3], jac_dot[3:], data.site_xpos[site], self.foot_body[side])
        return jac, jac_dot @ data.qvel

    # ----- the QP -----------------------------------------------------------------------
    def solve(self, model: mujoco.MjModel, data: mujoco.MjData, targets: WbcTargets) -> np.ndarray:
        """Motor torques for this control step, in ``motor_joints`` order [N m]."""
        nv, nf = self.nv, FORCE_BLOCK
        mujoco.mj_fullM(model, data, self._mass_matrix)
        mass_matrix = self._mass_matrix
        bias = data.qfrc_bias - data.qfrc_passive
        qvel = data.qvel

        contact_jac = np.zeros((nf, nv))
        corner_index = 0
        for side in (Side.LEFT, Side.RIGHT):
            for corner in self.corners(data, side):
                mujoco.mj_jac(model, data, self._jac, None, corner, self.foot_body[side])
                contact_jac[3 * corner_index : 3 * corner_index + 3] = self._jac
                corner_index += 1

        rows: list[np.ndarray] = []
        rhs: list[np.ndarray] = []
        weights: list[np.ndarray] = []

        def add(a: np.ndarray, b: np.ndarray, w: float | np.ndarray) -> None:
            rows.append(a)
            rhs.append(b)
            weights.append(np.broadcast_to(np.asarray(w, dtype=float), (a.shape[0],)))

        add(self._com_rows, targets.com_acceleration + np.array([0.0, 0.0, GRAVITY]), W_COM)

        for body, weight in ((self.pelvis, W_PELVIS), (self.torso, W_TORSO)):
            jac, target = self._body_rot_task(model, data, body, targets.heading)
            a = np.zeros((3, self.n))
            a[:, nf:] = jac
            add(a, target, weight)

        for side in (Side.LEFT, Side.RIGHT):
            jac, drift = self._site_jacobians(model, data, side)
            a = np.zeros((6, self.n))
            a[:, nf:] = jac
            swing = targets.swing.get(side)
            if swing is None:
                add(a, -drift - STANCE_KD * (jac @ qvel), W_STANCE)
                continue
            site = self.sole_site[side]
            position = data.site_xpos[site]
            velocity = jac[:3] @ qvel
            linear = swing.acceleration + SWING_KP * (swing.position - position) + SWING_KD * (swing.velocity - velocity)
            error_local = np.zeros(3)
            site_quat = np.zeros(4)
            mujoco.mju_mat2Quat(site_quat, data.site_xmat[site])
            mujoco.mju_subQuat(error_local, _yaw_quat(swing.yaw), site_quat)
            error = data.site_xmat[site].reshape(3, 3) @ error_local
            angular = SWING_KP * error + SWING_KD * (np.array([0.0, 0.0, swing.yaw_rate]) - jac[3:] @ qvel)
            add(a, np.concatenate([linear, angular]) - drift, W_SWING)

        posture_rows = self._posture_rows
        q = data.qpos[self.motor_qpos]
        qd = qvel[self.motor_dofs]
        add(posture_rows, POSTURE_KP * (targets.posture - q) - POSTURE_KD * qd, self.posture_weight)

        a_cost = np.vstack(rows)
        b_cost = np.concatenate(rhs)
        w_cost = np.concatenate(weights)
        hessian = a_cost.T @ (a_cost * w_cost[:, None])
        gradient = -a_cost.T @ (w_cost * b_cost)
        hessian[np.arange(nf), np.arange(nf)] += W_REG_FORCE
        hessian[np.arange(nf, self.n), np.arange(nf, self.n)] += W_REG_QACC

        # Equalities: floating base, and servo joints (their torque is the position servo's).
        base = self.base_dofs
        eq_base = np.hstack([-contact_jac[:, base].T, mass_matrix[base]])
        servo = self.servo_dofs
        servo_act = self.servo_actuators
        servo_torque = (
            model.actuator_gainprm[servo_act, 0] * data.ctrl[servo_act]
            + model.actuator_biasprm[servo_act, 0]
            + model.actuator_biasprm[servo_act, 1] * data.qpos[self.servo_qpos]
            + model.actuator_biasprm[servo_act, 2] * qvel[servo]
        )
        servo_torque = np.clip(servo_torque, self.servo_limit[:, 0], self.servo_limit[:, 1])
        eq_servo = np.hstack([-contact_jac[:, servo].T, mass_matrix[servo]])
        motor = self.motor_dofs
        torque_rows = np.hstack([-contact_jac[:, motor].T, mass_matrix[motor]])
        friction_rows = self._friction_rows

        upper_bounds = np.full(nf, 1e9)
        lower_bounds = np.full(nf, -1e9)
        corner_max = 1.5 * self.mass * GRAVITY
        for i, side in enumerate((Side.LEFT, Side.RIGHT)):
            load = float(np.clip(targets.load.get(side, 0.0), 0.0, 1.0))
            for c in range(CORNERS_PER_FOOT):
                z = 3 * (i * CORNERS_PER_FOOT + c) + 2
                upper_bounds[z] = load * corner_max
                lower_bounds[z] = 0.0
        n_friction = friction_rows.shape[0]
        knee_rows = self._knee_rows
        knee_q = data.qpos[self.knee_qpos]
        knee_min_acc = 2.0 * (KNEE_MIN - knee_q - qvel[self.knee_dofs] * KNEE_HORIZON) / KNEE_HORIZON**2

        def attempt(with_torque_limits: bool) -> tuple[np.ndarray, int]:
            blocks = [eq_base, eq_servo, friction_rows]
            upper = [-bias[base], servo_torque - bias[servo], np.zeros(n_friction)]
            lower = [-bias[base], servo_torque - bias[servo], np.full(n_friction, -1e9)]
            if with_torque_limits:
                blocks += [torque_rows, knee_rows]
                upper += [self.torque_limit[:, 1] - bias[motor], np.full(len(knee_q), 1e9)]
                lower += [self.torque_limit[:, 0] - bias[motor], knee_min_acc]
            a_con = np.vstack(blocks)
            b_up = np.concatenate([upper_bounds, *upper])
            b_lo = np.concatenate([lower_bounds, *lower])
            sense = np.zeros(len(b_up), dtype=np.int32)
            sense[nf : nf + len(base) + len(servo)] = 5
            x, _, status, _ = daqp.solve(hessian, gradient, a_con, b_up, b_lo, sense)
            return np.asarray(x), int(status)

        x, status = attempt(True)
        if status < 1:
            x, status = attempt(False)
        self.last_status = status
        if status < 1 or not np.all(np.isfinite(x)):
            force = self.last_force
            qacc = np.zeros(nv)
        else:
            force, qacc = x[:nf], x[nf:]
            self.last_force = force.copy()
        tau = mass_matrix[motor] @ qacc + bias[motor] - contact_jac[:, motor].T @ force
        return np.clip(tau, self.torque_limit[:, 0], self.torque_limit[:, 1])
