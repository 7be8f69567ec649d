"""Whole-body torque QP: joint accelerations and sole-corner forces that realise the balance tasks.

The QP in full: decision variables x = [f (3 per sole corner, world frame) [N], qacc (nv)
[m/s^2, rad/s^2]]. Equalities: the floating-base rows of M qacc + h = tau + J_c^T f
(h = qfrc_bias - qfrc_passive), and the servo-driven joints' rows with their position servo's own
torque. Inequalities: friction pyramids, bounded normal forces (a per-foot load scale), joint torque
limits, a knee-bend limit. Costs: CoM acceleration (through the total contact force), pelvis and
torso orientation, stance soles fixed (soft), swing sole tracking, posture, a small regularisation.

How it is solved (the same optimum, found faster): the equality rows are solved exactly for the
accelerations they determine. With E the base and servo dofs and m the motor dofs,

    qacc_E = K_f f + K_m qacc_m + k0,   [K_f | K_m | k0] = M_EE^-1 [J_c,E^T | -M_Em | tau_E - h_E],

so the QP is posed in z = [f, qacc_m] alone (24 + 15 variables, no equality rows) and every cost
and constraint row is mapped through qacc = Q z + q0. In single support the unloaded foot's forces
are zero (normal bound 0, tangential pinned by its pyramid), so they and their pyramid rows are left
out (27 variables, 31 rows). It is solved with DAQP, one model per support (both feet, left, right),
each warm-started from its previous active set.
(Posing it in z = [f, tau_m] instead, with qacc from ``mj_solveM``, would make the torque limits
simple bounds, but that Hessian's condition number is ~1e14 and its optimum came out ~0.5 N m off.)
M_EE^-1 is applied with LAPACK's Cholesky solver (``dposv``, from SciPy, which the QP stack already
depends on).
"""

from __future__ import annotations

import logging
import math
from typing import NamedTuple

import daqp
import mujoco
import numpy as np
from scipy.linalg import lapack

from robot_models import g1_constants as names
from sim_bridge.locomotion.planner import SwingSample

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
UNBOUNDED = 1e9  # stands for "no bound" in the QP's bound vectors
FACTORISATION_FAILED = -100  # ``last_status`` when M_EE could not be factorised (a broken state)

_log = logging.getLogger(__name__)


def as_index(indices: np.ndarray) -> slice | np.ndarray:
    """A slice when the indices are consecutive (indexing then gives a view, not a copy), else the indices."""
    if len(indices) and np.array_equal(indices, np.arange(indices[0], indices[0] + len(indices))):
        return slice(int(indices[0]), int(indices[0]) + len(indices))
    return indices


class WbcTargets(NamedTuple):
    """What the QP should realise this control step.

    Attributes:
        com_acceleration: desired CoM acceleration in world, shape (3,) [m/s^2].
        heading: desired pelvis and torso yaw [rad] (roll and pitch are zero).
        load: (left, right) upper bound on each foot's normal force as a fraction of full load, in [0, 1].
        swing: (left, right) swing reference of each foot, or None for a foot that must stay put.
        posture: target position of every motor joint, in ``motor_joints`` order [rad].
    """

    com_acceleration: np.ndarray
    heading: float
    load: tuple[float, float]
    swing: tuple[SwingSample | None, SwingSample | None]
    posture: np.ndarray


def _block(matrix: np.ndarray, rows: slice | np.ndarray, columns: slice | np.ndarray) -> np.ndarray:
    """``matrix[rows][:, columns]`` (a view when both are slices)."""
    if isinstance(rows, slice) and isinstance(columns, slice):
        return matrix[rows, columns]
    return matrix[np.ix_(np.arange(matrix.shape[0])[rows], np.arange(matrix.shape[1])[columns])]


def _clip(values: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """``values`` clipped in place to ``limits[:, 0]`` .. ``limits[:, 1]``."""
    np.maximum(values, limits[:, 0], out=values)
    return np.minimum(values, limits[:, 1], out=values)


class _Support:
    """The QP of one support (both feet, or one foot): which z columns, constraint rows and bounds it
    keeps (flat indices into the full arrays; ``full`` when it keeps everything) and its DAQP model."""

    def __init__(self, keep: np.ndarray, hessian_index: np.ndarray, constraint_index: np.ndarray,
                 bound_index: np.ndarray, full: bool = False) -> None:
        self.full = full
        self.keep = keep
        self.hessian_index = hessian_index
        self.constraint_index = constraint_index
        self.bound_index = bound_index
        self.model = daqp.Model()
        self.ready = False


class WholeBodyQP:
    """Builds and solves the torque QP on the current state of a MuJoCo model.

    Every array the QP needs is allocated here, once; :meth:`solve` fills them by slices.

    Args:
        model: the robot model.
        motor_joints: joints driven by torque (legs, waist), in the order torques are returned.
        servo_joints: joints left on their position servos (arms); their torque is predicted, not chosen.

    Attributes:
        last_status: DAQP's exit flag of the last step (1 optimal; < 1 failed).
        relaxed_count: steps solved without the torque and knee limits (infeasible with them).
        fallback_count: steps where no QP solved and the previous contact forces were reused.

    Raises:
        ValueError: the floating base, motor and servo joints do not partition the model's dofs, or a
            sole site is not on its foot body.
    """

    def __init__(self, model: mujoco.MjModel, motor_joints: tuple[str, ...], servo_joints: tuple[str, ...]) -> None:
        nv = self.nv = model.nv
        nf = FORCE_BLOCK
        self.mass = float(np.sum(model.body_mass))
        self.motor_dofs = np.array([model.joint(j).dofadr[0] for j in motor_joints])
        self.servo_dofs = np.array([model.joint(j).dofadr[0] for j in servo_joints])
        self.servo_qpos = np.array([model.joint(j).qposadr[0] for j in servo_joints])
        self.servo_actuators = np.array([model.actuator(j).id for j in servo_joints])
        self.motor_qpos = np.array([model.joint(j).qposadr[0] for j in motor_joints])
        self.pelvis = model.body(names.ROOT_BODY).id
        self.torso = model.body(names.TORSO_BODY).id
        base_dof = int(model.jnt_dofadr[model.body_jntadr[self.pelvis]])
        self.base_dofs = np.arange(base_dof, base_dof + 6)
        # z = [f, qacc_m]; E = base + servo dofs, whose accelerations are eliminated.
        eliminated = np.concatenate([self.base_dofs, self.servo_dofs])
        if sorted(np.concatenate([eliminated, self.motor_dofs]).tolist()) != list(range(nv)):
            raise ValueError("the floating base, motor and servo joints must cover every dof exactly once")
        ne, nm = len(eliminated), len(self.motor_dofs)
        self.ne, self.nm, self.nz = ne, nm, nf + nm
        self._base_index = as_index(self.base_dofs)

        knees = [j for j in names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS if j.endswith("_knee_joint")]
        self.knee_qpos = np.array([model.joint(j).qposadr[0] for j in knees])
        self.knee_dofs = np.array([model.joint(j).dofadr[0] for j in knees])
        self._knee_z = np.array([nf + motor_joints.index(j) for j in knees])  # their column in z
        self._knees = list(zip(self._knee_z.tolist(), self.knee_qpos.tolist(), self.knee_dofs.tolist(), strict=True))
        self.torque_limit = np.array([model.jnt_actfrcrange[model.joint(j).id] for j in motor_joints])
        self.servo_limit = np.array([model.jnt_actfrcrange[model.joint(j).id] for j in servo_joints])
        leg = set(names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS)
        self.posture_weight = np.array([W_POSTURE_LEG if j in leg else W_POSTURE for j in motor_joints])
        self.foot_body = (model.body(names.LEFT_FOOT_BODY).id, model.body(names.RIGHT_FOOT_BODY).id)
        self.sole_site = (model.site(names.LEFT_SOLE_SITE).id, model.site(names.RIGHT_SOLE_SITE).id)
        cx, cy, cz = names.SOLE_CENTER_IN_FOOT
        hx, hy, hz = names.SOLE_HALF_SIZE
        self.corners_in_foot = np.array([[cx + sx * hx, cy + sy * hy, cz - hz] for sx in (1, -1) for sy in (1, -1)])

        # Kinematics. Task rows: pelvis rotation, torso rotation, left sole (lin, ang), right sole.
        # ``_rows`` stacks, in MuJoCo's dof order: the task Jacobians' time derivatives (18), the task
        # Jacobians (18) and the motor rows of M (nm); one product with qvel gives the drifts and the
        # task velocities, one product with Q maps the task and torque rows to z.
        self._mass_matrix = np.zeros((nv, nv))
        self._bias = np.zeros(nv)
        self._contact_jac = np.zeros((nf, nv))
        # Corner Jacobians from the sole site's: J_corner = J_site - [r]x J_site_rot, r = corner - site
        # (all on the foot body). ``_skew`` maps r (3,) to the flattened [r]x (9,).
        self._corner_offsets = np.array([self.corners_in_foot - model.site_pos[site] for site in self.sole_site])
        self._feet = np.array(self.foot_body)
        for side in (0, 1):
            if model.site_bodyid[self.sole_site[side]] != self.foot_body[side]:
                raise ValueError("each sole site must be on its foot body")
        self._skew = np.zeros((3, 9))
        for axis, (row, column, sign) in enumerate(((2, 1, 1.0), (0, 2, 1.0), (1, 0, 1.0))):
            self._skew[axis, 3 * row + column] = sign  # [r]x[row, column] = +r_axis
            self._skew[axis, 3 * column + row] = -sign
        self._corner_jac = self._contact_jac.reshape(2, CORNERS_PER_FOOT, 3, nv)  # [foot, corner, axis, dof]
        self._rows = np.zeros((36 + nm, nv))
        self._task_jac_dot = self._rows[:18]
        self._task_jac = self._rows[18:36]
        self._motor_mass = self._rows[36:]
        self._task_rhs = np.zeros(18)
        self._error_local = np.zeros(3)
        self._upper_body_error = np.zeros((2, 3, 1))  # local rotation errors of the pelvis and torso [rad]
        self._upper_bodies = np.array([self.pelvis, self.torso])
        self._yaw_quat = np.zeros(4)
        self._site_quat = np.zeros(4)
        self._mass_ee_flat = (eliminated[:, None] * nv + eliminated[None, :]).ravel()  # M[E][:, E], flattened
        # Index views (slices where the indices are consecutive, as they are on the G1).
        self._motor_dof_index = as_index(self.motor_dofs)
        self._motor_qpos_index = as_index(self.motor_qpos)
        self._servo_dof_index = as_index(self.servo_dofs)
        self._servo_qpos_index = as_index(self.servo_qpos)
        self._servo_actuator_index = as_index(self.servo_actuators)
        # The arm servos' affine law tau = g ctrl + b0 + b1 q + b2 qd (their gains are not changed at run time).
        self._servo_gain = model.actuator_gainprm[self.servo_actuators, 0].copy()
        self._servo_bias = [model.actuator_biasprm[self.servo_actuators, k].copy() for k in range(3)]
        self._servo_torque = np.zeros(len(self.servo_dofs))

        # Elimination: [K_f | K_m | k0] = M_EE^-1 [J_c,E^T | -M_Em | tau_E - h_E]; qacc = Q z + q0.
        self._elim_rhs = np.zeros((ne, self.nz + 1), order="F")  # LAPACK solves it in place
        self._mass_ee = np.zeros((ne, ne), order="F")
        # Q (nv, nz) and q0 (nv) in MuJoCo's dof order: the motor rows of Q select qacc_m.
        self._q_map = np.zeros((nv, self.nz))
        self._q_map[self.motor_dofs, nf + np.arange(nm)] = 1.0
        self._q_offset = np.zeros(nv)
        n_base = len(self.base_dofs)
        self._base_rows = slice(0, n_base)  # rows of K (and of the elimination) that belong to the base
        self._servo_rows = slice(n_base, ne)

        # Cost rows on z: CoM (total force / mass), tasks, posture (qacc_m), regularisation of qacc_E.
        n_cost = 3 + 18 + nm + ne
        self._cost_rows = np.zeros((n_cost, self.nz))
        self._cost_rows[:3, :nf] = np.tile(np.eye(3), (1, 2 * CORNERS_PER_FOOT)) / self.mass
        self._cost_rows[21 : 21 + nm, nf:] = np.eye(nm)
        self._cost_rhs = np.zeros(n_cost)
        self._cost_weight = np.concatenate([
            [W_COM] * 3, [W_PELVIS] * 3, [W_TORSO] * 3, [0.0] * 12, self.posture_weight, [W_REG_QACC] * ne
        ])
        self._task_weight = self._cost_weight[3:21]  # the soles' weights are set per step (stance or swing)
        self._task_rows = self._cost_rows[3:21]
        self._hessian_diag = np.concatenate([np.full(nf, W_REG_FORCE), np.full(nm, W_REG_QACC)])
        self._hessian = np.zeros((self.nz, self.nz))
        self._weighted = np.zeros((self.nz, n_cost))
        self._hessian_diagonal = self._hessian.reshape(-1)[:: self.nz + 1]  # a view of its diagonal
        self._gradient = np.zeros(self.nz)
        self._mapped = np.zeros((18 + nm, self.nz))
        self._mapped_offset = np.zeros(18 + nm)

        # Constraints on z: simple bounds on every variable, then friction pyramids and torque limits.
        n_friction = 4 * 2 * CORNERS_PER_FOOT
        self._constraints = np.zeros((n_friction + nm, self.nz))
        for c in range(2 * CORNERS_PER_FOOT):
            for k, (axis, sign) in enumerate(((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0))):
                self._constraints[4 * c + k, 3 * c + axis] = sign
                self._constraints[4 * c + k, 3 * c + 2] = -FRICTION
        self._torque_rows = self._constraints[n_friction:]  # tau_m = T z + t0
        self._torque_offset = np.zeros(nm)
        self._upper = np.zeros(self.nz + n_friction + nm)
        self._lower = np.zeros(self.nz + n_friction + nm)
        self._upper[: self.nz] = UNBOUNDED
        self._lower[: self.nz] = -UNBOUNDED
        self._lower[self.nz : self.nz + n_friction] = -UNBOUNDED
        half = 3 * CORNERS_PER_FOOT
        self._normal_index = (slice(2, half, 3), slice(half + 2, nf, 3))  # f_z of the left, right corners
        self._lower[2:nf:3] = 0.0
        self._corner_max = 1.5 * self.mass * GRAVITY
        # One warm-started DAQP model per support: both feet, left only, right only. A foot with no
        # load has zero forces (normal bound 0, hence tangential 0 through its pyramid), so in single
        # support the QP drops its 12 forces and 16 pyramid rows: the same optimum, a smaller problem.
        force_columns = (np.arange(0, half), np.arange(half, nf))
        pyramid_rows = (np.arange(0, n_friction // 2), np.arange(n_friction // 2, n_friction))
        torque_rows = np.arange(n_friction, n_friction + nm)
        motor_columns = np.arange(nf, self.nz)
        nothing = np.zeros(0, dtype=int)
        self._supports = [_Support(nothing, nothing, nothing, nothing, full=True)]
        for side in (0, 1):
            keep = np.concatenate([force_columns[side], motor_columns])
            rows = np.concatenate([pyramid_rows[side], torque_rows])
            self._supports.append(_Support(
                keep,
                (keep[:, None] * self.nz + keep[None, :]).ravel(),
                (rows[:, None] * self.nz + keep[None, :]).ravel(),
                np.concatenate([keep, self.nz + rows]),
            ))

        self.last_force = np.zeros(FORCE_BLOCK)
        self.last_status = 1
        self.relaxed_count = 0  # steps solved without the torque and knee limits (infeasible with them)
        self.fallback_count = 0  # steps where no QP solved and the previous forces were reused

    def reset(self) -> None:
        """Forget the previous step's forces and active set (call when the state jumps, e.g. on reset)."""
        self.last_force[:] = 0.0
        self.last_status = 1
        for support in self._supports:
            support.ready = False

    # ----- kinematics -------------------------------------------------------------------
    def corners(self, data: mujoco.MjData, side: int) -> np.ndarray:
        """World positions of the four sole corners of a foot (0 left, 1 right), shape (4, 3) [m]."""
        body = self.foot_body[side]
        return data.xpos[body] + self.corners_in_foot @ data.xmat[body].reshape(3, 3).T

    def _set_yaw_quat(self, yaw: float) -> None:
        half = 0.5 * yaw
        self._yaw_quat[0] = math.cos(half)
        self._yaw_quat[3] = math.sin(half)

    def _kinematics(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """The MuJoCo quantities of this step: M (nv, nv), the task Jacobians (18, nv) and their time
        derivatives, and from the soles' Jacobians the sole-corner Jacobians (nf, nv), in MuJoCo's dof order."""
        mujoco.mj_fullM(model, data, self._mass_matrix)
        jac, jac_dot = self._task_jac, self._task_jac_dot
        for row, body in ((0, self.pelvis), (3, self.torso)):
            mujoco.mj_jacBody(model, data, None, jac[row : row + 3], body)
            mujoco.mj_jacDot(model, data, None, jac_dot[row : row + 3], data.xpos[body], body)
        for side in (0, 1):
            row = 6 + 6 * side
            site, body = self.sole_site[side], self.foot_body[side]
            mujoco.mj_jacSite(model, data, jac[row : row + 3], jac[row + 3 : row + 6], site)
            mujoco.mj_jacDot(model, data, jac_dot[row : row + 3], jac_dot[row + 3 : row + 6], data.site_xpos[site], body)
        sole_jac = jac[6:18].reshape(2, 2, 3, -1)  # [foot, linear/angular, axis, dof]
        rotation = data.xmat[self._feet].reshape(2, 3, 3)
        offsets = self._corner_offsets @ rotation.transpose(0, 2, 1)  # corners - sole centre, world (2, 4, 3) [m]
        cross = (offsets @ self._skew).reshape(2, CORNERS_PER_FOOT, 3, 3) @ sole_jac[:, None, 1]
        np.subtract(sole_jac[:, None, 0], cross, out=self._corner_jac)

    def _fill_tasks(self, data: mujoco.MjData, targets: WbcTargets) -> None:
        """Task weights and right-hand sides [m/s^2, rad/s^2] from the Jacobians of :meth:`_kinematics`."""
        drift_velocity = self._rows[:36] @ data.qvel
        velocity = drift_velocity[18:]
        rhs = self._task_rhs
        # Pelvis and torso: PD toward the heading (rotation errors in world = R_body @ local error).
        self._set_yaw_quat(targets.heading)
        errors = self._upper_body_error
        mujoco.mju_subQuat(errors[0, :, 0], self._yaw_quat, data.xquat[self.pelvis])
        mujoco.mju_subQuat(errors[1, :, 0], self._yaw_quat, data.xquat[self.torso])
        orientation = rhs[:6].reshape(2, 3, 1)
        np.matmul(data.xmat[self._upper_bodies].reshape(2, 3, 3), errors, out=orientation)
        rhs[:6] *= ORIENTATION_KP
        rhs[:6] -= ORIENTATION_KD * velocity[:6]
        weight = self._task_weight
        for side in (0, 1):
            row = 6 + 6 * side
            swing = targets.swing[side]
            if swing is None:
                np.multiply(velocity[row : row + 6], -STANCE_KD, out=rhs[row : row + 6])
                weight[row : row + 6] = W_STANCE
            else:
                site = self.sole_site[side]
                rhs[row : row + 3] = (
                    swing.acceleration
                    + SWING_KP * (swing.position - data.site_xpos[site])
                    + SWING_KD * (swing.velocity - velocity[row : row + 3])
                )
                mujoco.mju_mat2Quat(self._site_quat, data.site_xmat[site])
                self._set_yaw_quat(swing.yaw)
                mujoco.mju_subQuat(self._error_local, self._yaw_quat, self._site_quat)
                angular = rhs[row + 3 : row + 6]
                np.matmul(data.site_xmat[site].reshape(3, 3), self._error_local, out=angular)
                angular *= SWING_KP
                angular[2] += SWING_KD * swing.yaw_rate
                angular -= SWING_KD * velocity[row + 3 : row + 6]
                weight[row : row + 6] = W_SWING
        rhs -= drift_velocity[:18]

    def _servo_torques(self, data: mujoco.MjData) -> np.ndarray:
        """The arm servos' torques at this state, clipped to their joints' limits [N m]."""
        bias0, bias1, bias2 = self._servo_bias
        torque = np.multiply(self._servo_gain, data.ctrl[self._servo_actuator_index], out=self._servo_torque)
        torque += bias0
        torque += bias1 * data.qpos[self._servo_qpos_index]
        torque += bias2 * data.qvel[self._servo_dof_index]
        return _clip(torque, self.servo_limit)

    # ----- the QP -----------------------------------------------------------------------
    def solve(self, model: mujoco.MjModel, data: mujoco.MjData, targets: WbcTargets) -> np.ndarray:
        """Motor torques for this control step, in ``motor_joints`` order [N m].

        If the QP is infeasible with the torque and knee limits it is solved without them
        (:attr:`relaxed_count` counts such steps); if that fails too, the previous step's contact
        forces are reused with zero joint accelerations, tau = h_m - J_c,m^T f_prev (a safe hold
        for one step; :attr:`fallback_count` counts such steps, and the first one and every 100th
        are logged as warnings).
        """
        nf, ne, nz = FORCE_BLOCK, self.ne, self.nz
        qvel = data.qvel
        self._kinematics(model, data)
        mass = self._mass_matrix
        bias = np.subtract(data.qfrc_bias, data.qfrc_passive, out=self._bias)
        contact_jac = self._contact_jac
        self._fill_tasks(data, targets)
        motor, base, servo = self._motor_dof_index, self._base_index, self._servo_dof_index
        self._motor_mass[:] = mass[motor]

        # Eliminate the equality rows: qacc_E = K z + k0, rows of K ordered base then servo.
        elim, base_rows, servo_rows = self._elim_rhs, self._base_rows, self._servo_rows
        elim[base_rows, :nf] = contact_jac[:, base].T
        elim[servo_rows, :nf] = contact_jac[:, servo].T
        np.negative(_block(mass, base, motor), out=elim[base_rows, nf:nz])
        np.negative(_block(mass, servo, motor), out=elim[servo_rows, nf:nz])
        np.negative(bias[base], out=elim[base_rows, nz])
        np.subtract(self._servo_torques(data), bias[servo], out=elim[servo_rows, nz])
        self._mass_ee[:] = mass.take(self._mass_ee_flat).reshape(ne, ne)
        _, solved, info = lapack.dposv(self._mass_ee, elim, overwrite_a=1, overwrite_b=1)
        if info != 0:  # M_EE not positive definite: only with a broken state (e.g. NaN)
            return self._fallback(FACTORISATION_FAILED, bias)
        q_map, q_offset = self._q_map, self._q_offset
        q_map[base] = solved[base_rows, :nz]
        q_map[servo] = solved[servo_rows, :nz]
        q_offset[base] = solved[base_rows, nz]
        q_offset[servo] = solved[servo_rows, nz]

        # Task and torque rows on z: [J_task; M_m] qacc = [J_task; M_m] (Q z + q0).
        task_and_motor = self._rows[18:]
        mapped = np.matmul(task_and_motor, q_map, out=self._mapped)
        offset = np.matmul(task_and_motor, q_offset, out=self._mapped_offset)

        # Costs: H = C^T W C + diag, g = -C^T W r.
        rows, rhs = self._cost_rows, self._cost_rhs
        rows[3:21] = mapped[:18]
        rows[21 + self.nm :] = solved[:, :nz]  # the eliminated accelerations' regularisation
        rhs[:3] = targets.com_acceleration
        rhs[2] += GRAVITY
        np.subtract(self._task_rhs, offset[:18], out=rhs[3:21])
        posture = rhs[21 : 21 + self.nm]
        np.subtract(targets.posture, data.qpos[self._motor_qpos_index], out=posture)
        posture *= POSTURE_KP
        posture -= POSTURE_KD * qvel[self._motor_dof_index]
        np.negative(solved[:, nz], out=rhs[21 + self.nm :])
        weighted = np.multiply(rows.T, self._cost_weight, out=self._weighted)
        hessian = np.matmul(weighted, rows, out=self._hessian)
        self._hessian_diagonal += self._hessian_diag
        gradient = np.matmul(weighted, rhs, out=self._gradient)
        np.negative(gradient, out=gradient)

        # Torque rows: tau_m = M_m qacc + h_m - J_c,m^T f = T z + t0.
        torque_rows = self._torque_rows
        np.subtract(mapped[18:, :nf], contact_jac[:, motor].T, out=torque_rows[:, :nf])
        torque_rows[:, nf:] = mapped[18:, nf:]
        torque_offset = np.add(offset[18:], bias[motor], out=self._torque_offset)

        upper, lower = self._upper, self._lower
        left, right = targets.load
        normal = self._normal_index
        upper[normal[0]] = min(max(left, 0.0), 1.0) * self._corner_max
        upper[normal[1]] = min(max(right, 0.0), 1.0) * self._corner_max
        qpos = data.qpos
        for column, qpos_adr, dof in self._knees:
            lower[column] = 2.0 * (KNEE_MIN - qpos[qpos_adr] - qvel[dof] * KNEE_HORIZON) / KNEE_HORIZON**2
        n_torque = self.nm
        np.subtract(self.torque_limit[:, 1], torque_offset, out=upper[-n_torque:])
        np.subtract(self.torque_limit[:, 0], torque_offset, out=lower[-n_torque:])

        z, status = self._solve_qp(hessian, gradient, 2 if left <= 0.0 else 1 if right <= 0.0 else 0)
        if status < 1:
            # Without the torque and knee limits (as if those rows were absent).
            lower[self._knee_z] = -UNBOUNDED
            count = len(upper) - n_torque
            z, _, status, _ = daqp.solve(hessian, gradient, self._constraints[:-n_torque], upper[:count], lower[:count])
            z, status = np.asarray(z), int(status)
            self.relaxed_count += 1
        self.last_status = status
        if status < 1 or not math.isfinite(float(z @ z)):
            return self._fallback(status, bias)
        self.last_force[:] = z[:nf]
        tau = torque_rows @ z
        tau += torque_offset
        return _clip(tau, self.torque_limit)

    def _fallback(self, status: int, bias: np.ndarray) -> np.ndarray:
        """No solution this step: hold with the previous contact forces and zero joint accelerations [N m]."""
        self.last_status = status
        self.fallback_count += 1
        if self.fallback_count % 100 == 1:
            _log.warning("torque QP failed (status %d, %d times so far): reusing the previous contact forces",
                         status, self.fallback_count)
        motor = self._motor_dof_index
        tau = bias[motor] - self._contact_jac[:, motor].T @ self.last_force
        return _clip(tau, self.torque_limit)
    def _solve_qp(self, hessian: np.ndarray, gradient: np.ndarray, support_index: int) -> tuple[np.ndarray, int]:
        """Solve the QP (for support 0 both feet, 1 left only, 2 right only), warm-started from that
        support's previous active set when there is one; returns z in full (nz,) and DAQP's status."""
        support = self._supports[support_index]
        if support.full:
            problem = (hessian, gradient, self._constraints, self._upper, self._lower)
        else:
            n = len(support.keep)
            problem = (
                hessian.take(support.hessian_index).reshape(n, n),
                gradient.take(support.keep),
                self._constraints.take(support.constraint_index).reshape(-1, n),
                self._upper.take(support.bound_index),
                self._lower.take(support.bound_index),
            )
        if support.ready:
            h, f, a, upper, lower = problem
            support.model.update(H=h, f=f, A=a, bupper=upper, blower=lower)
        else:
            support.model.setup(*problem)
            support.ready = True
        solution, _, status, _ = support.model.solve()
        status = int(status)
        if status < 1:
            support.ready = False  # start the next step from scratch
        if support.full:
            return np.asarray(solution), status
        z = np.zeros(self.nz)
        z[support.keep] = solution
        return z, status
