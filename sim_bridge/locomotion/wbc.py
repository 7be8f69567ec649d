"""Whole-body torque QP: joint accelerations and sole-corner forces that realise the balance tasks.

The QP in full: decision variables x = [f (3 per sole corner, world frame) [N], qacc (nv)
[m/s^2, rad/s^2]]. Equalities: the floating-base rows of M qacc + h = tau + J_c^T f
(h = qfrc_bias - qfrc_passive), and the servo-driven joints' rows with their position servo's own
torque; h also holds the measured contact forces of movable objects on the robot other than at its
soles (:mod:`.external`: a held object). Inequalities: friction pyramids, bounded normal forces (a per-foot
load scale), joint torque limits, a knee-bend limit. Costs: CoM acceleration (through the total contact force), pelvis and
torso orientation, stance soles fixed (soft), swing sole tracking, posture, a small regularisation.

How it is solved (the same optimum, found faster): the equality rows are solved exactly for the
accelerations they determine. With E the base and servo dofs and m the motor dofs,

    qacc_E = K_f f + K_m qacc_m + k0,   [K_f | K_m | k0] = M_EE^-1 [J_c,E^T | -M_Em | tau_E - h_E],

so the QP is posed in z = [f, qacc_m] alone (24 forces + the motor accelerations, no equality
rows) and every cost and constraint row is mapped through qacc = Q z + q0. In single support the
unloaded foot's forces are zero (normal bound 0, tangential pinned by its pyramid), so they and their
pyramid rows are left out. It is solved with DAQP, one model per support (both feet, left, right),
each warm-started from its previous active set (:mod:`.wbc_layout`).
(Posing it in z = [f, tau_m] instead, with qacc from ``mj_solveM``, would make the torque limits
simple bounds, but that Hessian is far worse conditioned.) The motion tasks are in :mod:`.wbc_tasks`.
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

from robot_models.biped import BipedDescription
from sim_bridge.locomotion.external import ExternalContacts
from sim_bridge.locomotion.swing import SwingSample
from sim_bridge.locomotion.wbc_layout import (
    CORNERS_PER_FOOT,
    FORCE_BLOCK,
    N_FRICTION,
    FootLayout,
    JointLayout,
    as_index,
    clip,
    friction_pyramids,
    robot_mass,
    supports,
)
from sim_bridge.locomotion.wbc_tasks import N_TASK, MotionTasks

GRAVITY = 9.81  # [m/s^2]

W_COM = 10.0
W_PELVIS = 5.0
W_TORSO = 2.5
W_POSTURE = 0.05
W_POSTURE_LEG = 0.005
W_REG_QACC = 1e-5
W_REG_FORCE = 1e-7
POSTURE_KP, POSTURE_KD = 100.0, 20.0
KNEE_MIN = 0.05  # the QP keeps the knees at least this bent [rad]
KNEE_HORIZON = 0.05  # look-ahead of the knee limit [s]
UNBOUNDED = 1e9  # stands for "no bound" in the QP's bound vectors
FACTORISATION_FAILED = -100  # ``last_status`` when M_EE could not be factorised (a broken state)

_log = logging.getLogger(__name__)


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


class WholeBodyQP:
    """Builds and solves the torque QP on the current state of a MuJoCo model.

    Every array the QP needs is allocated here, once; :meth:`solve` fills them by slices.

    Args:
        model: the robot model.
        biped: the robot's bodies, sole sites and joints: its motor joints (legs, waist) are driven by
            torque, in the order torques are returned; its servo joints (arms) stay on their position
            servos, whose torque is predicted, not chosen.

    Attributes:
        last_status: DAQP's exit flag of the last step (1 optimal; < 1 failed).
        relaxed_count: steps solved without the torque and knee limits (infeasible with them).
        fallback_count: steps where no QP solved and the previous contact forces were reused.

    Raises:
        ValueError: the floating base, motor and servo joints do not partition the model's dofs, or a
            sole site is not on its foot body.
    """

    def __init__(self, model: mujoco.MjModel, biped: BipedDescription) -> None:
        # scipy.linalg (~0.2 CPU-s to import) comes with the first controller built, not with this module: the action
        # servers import the goal types beside it and never balance a robot (that runs inside /sim).
        from scipy.linalg import lapack

        self._dposv = lapack.dposv  # Cholesky solve of M_EE X = B [LAPACK]
        self.nv = model.nv
        self.pelvis = model.body(biped.base_body).id
        self.mass = robot_mass(model, self.pelvis)  # the objects of the scene are not the robot's
        self.torso = model.body(biped.torso_body).id
        self.joints = joints = JointLayout.of(model, biped)
        self.feet = FootLayout.of(model, biped)
        # Movable objects' contacts on the robot (a held object), measured: see .external.
        self.external = ExternalContacts(model, self.pelvis, self.feet.bodies)
        self.ne, self.nm = len(joints.eliminated), len(joints.motor_dofs)
        self.nz = FORCE_BLOCK + self.nm  # z = [f, qacc_m]
        self.torque_limit = joints.torque_limit
        self._knees = list(zip(joints.knee_z.tolist(), joints.knee_qpos.tolist(), joints.knee_dofs.tolist(), strict=True))
        self._index_views()
        self._allocate_kinematics()
        self._allocate_elimination()
        self._allocate_costs()
        self._allocate_bounds()
        # The arm servos' affine law tau = g ctrl + b0 + b1 q + b2 qd (their gains are not changed at run time).
        self._servo_gain = model.actuator_gainprm[joints.servo_actuators, 0].copy()
        self._servo_bias = [model.actuator_biasprm[joints.servo_actuators, k].copy() for k in range(3)]
        self._servo_torque = np.zeros(len(joints.servo_dofs))
        # One warm-started DAQP model per support: both feet, left only, right only.
        self._supports = supports(self.nz, self.nm)
        self.last_force = np.zeros(FORCE_BLOCK)
        self.last_status = 1
        self.relaxed_count = 0
        self.fallback_count = 0

    def _index_views(self) -> None:
        """Index views of the joint addresses (slices where they are consecutive, as on the G1)."""
        joints = self.joints
        self._motor_dof_index = as_index(joints.motor_dofs)
        self._motor_qpos_index = as_index(joints.motor_qpos)
        self._servo_dof_index = as_index(joints.servo_dofs)
        self._servo_qpos_index = as_index(joints.servo_qpos)
        self._servo_actuator_index = as_index(joints.servo_actuators)
        self._eliminated = joints.eliminated  # base then servo dofs: the rows of the elimination

    def _allocate_kinematics(self) -> None:
        """Buffers of :meth:`_kinematics` and the motion tasks.

        ``_rows`` stacks, in MuJoCo's dof order: the task Jacobians' time derivatives (18), the task
        Jacobians (18) and the motor rows of M (nm); one product with qvel gives the drifts and the
        task velocities, one product with Q maps the task and torque rows to z.
        """
        nv, nm, eliminated = self.nv, self.nm, self.joints.eliminated
        self._mass_matrix = np.zeros((nv, nv))
        self._bias = np.zeros(nv)
        self._contact_jac = np.zeros((FORCE_BLOCK, nv))
        self._corner_jac = self._contact_jac.reshape(2, CORNERS_PER_FOOT, 3, nv)  # [foot, corner, axis, dof]
        self._feet = np.array(self.feet.bodies)
        self._rows = np.zeros((2 * N_TASK + nm, nv))
        self._task_jac_dot = self._rows[:N_TASK]
        self._task_jac = self._rows[N_TASK : 2 * N_TASK]
        self._motor_mass = self._rows[2 * N_TASK :]
        self._tasks = MotionTasks((self.pelvis, self.torso), self.feet.sole_sites)
        self._mass_ee_flat = (eliminated[:, None] * nv + eliminated[None, :]).ravel()  # M[E][:, E], flattened
        self._mass_em_flat = (eliminated[:, None] * nv + self.joints.motor_dofs[None, :]).ravel()  # M[E][:, m]

    def _allocate_elimination(self) -> None:
        """Elimination: [K_f | K_m | k0] = M_EE^-1 [J_c,E^T | -M_Em | tau_E - h_E]; qacc = Q z + q0."""
        ne, nz = self.ne, self.nz
        self._elim_rhs = np.zeros((ne, nz + 1), order="F")  # LAPACK solves it in place
        self._mass_ee = np.zeros((ne, ne), order="F")
        # Q (nv, nz) and q0 (nv) in MuJoCo's dof order: the motor rows of Q select qacc_m.
        self._q_map = np.zeros((self.nv, nz))
        self._q_map[self.joints.motor_dofs, FORCE_BLOCK + np.arange(self.nm)] = 1.0
        self._q_offset = np.zeros(self.nv)
        self._servo_rows = slice(len(self.joints.base_dofs), ne)  # rows of K (and of the elimination) of the servos

    def _allocate_costs(self) -> None:
        """Cost rows on z: CoM (total force / mass), tasks, posture (qacc_m), regularisation of qacc_E."""
        nf, nm, ne, nz = FORCE_BLOCK, self.nm, self.ne, self.nz
        n_cost = 3 + N_TASK + nm + ne
        self._cost_rows = np.zeros((n_cost, nz))
        self._cost_rows[:3, :nf] = np.tile(np.eye(3), (1, 2 * CORNERS_PER_FOOT)) / self.mass
        self._cost_rows[21 : 21 + nm, nf:] = np.eye(nm)
        self._cost_rhs = np.zeros(n_cost)
        posture_weight = np.where(self.joints.leg_motor, W_POSTURE_LEG, W_POSTURE)
        self._cost_weight = np.concatenate([
            [W_COM] * 3, [W_PELVIS] * 3, [W_TORSO] * 3, [0.0] * 12, posture_weight, [W_REG_QACC] * ne
        ])
        self._task_weight = self._cost_weight[3:21]  # the soles' weights are set per step (stance or swing)
        self._hessian_diag = np.concatenate([np.full(nf, W_REG_FORCE), np.full(nm, W_REG_QACC)])
        self._hessian = np.zeros((nz, nz))
        self._weighted = np.zeros((nz, n_cost))
        self._hessian_diagonal = self._hessian.reshape(-1)[:: nz + 1]  # a view of its diagonal
        self._gradient = np.zeros(nz)
        self._mapped = np.zeros((N_TASK + nm, nz))
        self._mapped_offset = np.zeros(N_TASK + nm)

    def _allocate_bounds(self) -> None:
        """Constraints on z: simple bounds on every variable, then friction pyramids and torque limits."""
        nf, nm, nz = FORCE_BLOCK, self.nm, self.nz
        self._constraints = friction_pyramids(nz, nm)
        self._torque_rows = self._constraints[N_FRICTION:]  # tau_m = T z + t0
        self._torque_offset = np.zeros(nm)
        self._upper = np.zeros(nz + N_FRICTION + nm)
        self._lower = np.zeros(nz + N_FRICTION + nm)
        self._upper[:nz] = UNBOUNDED
        self._lower[:nz] = -UNBOUNDED
        self._lower[nz : nz + N_FRICTION] = -UNBOUNDED
        half = 3 * CORNERS_PER_FOOT
        self._normal_index = (slice(2, half, 3), slice(half + 2, nf, 3))  # f_z of the left, right corners
        self._lower[2:nf:3] = 0.0
        self._corner_max = 1.5 * self.mass * GRAVITY

    def reset(self) -> None:
        """Forget the previous step's forces and active set (call when the state jumps, e.g. on reset)."""
        self.last_force[:] = 0.0
        self.last_status = 1
        for support in self._supports:
            support.ready = False

    # ----- kinematics -------------------------------------------------------------------
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
            site, body = self.feet.sole_sites[side], self.feet.bodies[side]
            mujoco.mj_jacSite(model, data, jac[row : row + 3], jac[row + 3 : row + 6], site)
            mujoco.mj_jacDot(model, data, jac_dot[row : row + 3], jac_dot[row + 3 : row + 6], data.site_xpos[site], body)
        sole_jac = jac[6:18].reshape(2, 2, 3, -1)  # [foot, linear/angular, axis, dof]
        rotation = data.xmat[self._feet].reshape(2, 3, 3)
        offsets = self.feet.corner_offsets @ rotation.transpose(0, 2, 1)  # corners - sole centre, world (2, 4, 3) [m]
        cross = (offsets @ self.feet.skew).reshape(2, CORNERS_PER_FOOT, 3, 3) @ sole_jac[:, None, 1]
        np.subtract(sole_jac[:, None, 0], cross, out=self._corner_jac)

    def _servo_torques(self, data: mujoco.MjData) -> np.ndarray:
        """The arm servos' torques at this state, clipped to their joints' limits [N m]."""
        bias0, bias1, bias2 = self._servo_bias
        torque = np.multiply(self._servo_gain, data.ctrl[self._servo_actuator_index], out=self._servo_torque)
        torque += bias0
        torque += bias1 * data.qpos[self._servo_qpos_index]
        torque += bias2 * data.qvel[self._servo_dof_index]
        return clip(torque, self.joints.servo_limit)

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
        external = self.external.update(model, data)
        if external is not None:  # known forces on the robot: M qacc + h - J_ext^T f_ext = tau + J_c^T f
            bias -= external
        contact_jac = self._contact_jac
        self._tasks.fill(data, self._rows[: 2 * N_TASK] @ data.qvel, targets.heading, targets.swing, self._task_weight)
        motor = self._motor_dof_index
        self._motor_mass[:] = mass[motor]

        # Eliminate the equality rows: qacc_E = K z + k0, rows of K ordered base then servo (E).
        # Each block is gathered by one precomputed index (tau_E - h_E as -h_E, then + tau on the servo rows).
        elim, eliminated = self._elim_rhs, self._eliminated
        elim[:, :nf] = contact_jac.take(eliminated, axis=1).T
        np.negative(mass.take(self._mass_em_flat).reshape(ne, self.nm), out=elim[:, nf:nz])
        np.negative(bias.take(eliminated), out=elim[:, nz])
        elim[self._servo_rows, nz] += self._servo_torques(data)
        self._mass_ee[:] = mass.take(self._mass_ee_flat).reshape(ne, ne)
        _, solved, info = self._dposv(self._mass_ee, elim, overwrite_a=1, overwrite_b=1)
        if info != 0:  # M_EE not positive definite: only with a broken state (e.g. NaN)
            return self._fallback(FACTORISATION_FAILED, bias)
        q_map, q_offset = self._q_map, self._q_offset
        q_map[eliminated] = solved[:, :nz]
        q_offset[eliminated] = solved[:, nz]

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
        np.subtract(self._tasks.rhs, offset[:18], out=rhs[3:21])
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
            lower[self.joints.knee_z] = -UNBOUNDED
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
        return clip(tau, self.torque_limit)

    def _fallback(self, status: int, bias: np.ndarray) -> np.ndarray:
        """No solution this step: hold with the previous contact forces and zero joint accelerations [N m]."""
        self.last_status = status
        self.fallback_count += 1
        if self.fallback_count % 100 == 1:
            _log.warning("torque QP failed (status %d, %d times so far): reusing the previous contact forces",
                         status, self.fallback_count)
        motor = self._motor_dof_index
        tau = bias[motor] - self._contact_jac[:, motor].T @ self.last_force
        return clip(tau, self.torque_limit)
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
