"""One arm's differential IK: the mink problem, and its solve with the frozen DoFs eliminated.

Nothing here writes the simulation's ``MjData``: every IK problem runs on its own
:class:`mink.Configuration`. For a robot with more DoFs than the arm (floating base, legs, other
arm, gripper, free objects) every DoF but the arm's is frozen by an equality constraint.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import daqp
import mujoco
import numpy as np

from sim_bridge.arm.collision_rows import CollisionRows
from sim_bridge.arm.description import ArmInfo
from sim_bridge.arm.poses import mat_to_quat
from sim_bridge.arm.types import ArmControllerConfig
from sim_bridge.errors import SimError
from sim_bridge.state import Pose

if TYPE_CHECKING:
    import mink

OFFLINE_DT = 0.1  # [s] step length of offline solves
OFFLINE_STEP = 0.04  # [rad] largest joint change per offline step


def _se3(pose: Pose) -> mink.SE3:
    """The pose as a mink transform (its quaternion is already normalised by :func:`~sim_bridge.arm.poses.validate_pose`)."""
    import mink

    return mink.SE3(np.concatenate((np.asarray(pose.orientation_wxyz, dtype=float), np.asarray(pose.position, dtype=float))))


class IKProblem:
    """mink differential IK of one arm's tool site on a private :class:`mink.Configuration`.

    The problem is the one ``mink.solve_ik(configuration, [frame_task, posture_task], dt, "daqp",
    damping=1e-9, limits=limits, constraints=constraints)`` builds, where ``constraints`` freezes
    every DoF but the arm's. Each step solves it with those frozen DoFs eliminated exactly: the QP
    has only the arm's n variables (7 instead of up to 35), the configuration and velocity limits
    become its box bounds, and only collision rows within the detection distance are kept. The
    numbers come from the mink task and limit objects, so the solution is mink's (a test checks
    it), at a fraction of the cost of assembling and solving the full (nv,) problem.

    Args:
        model: the IK model (see :func:`sim_bridge.arm.ik_model.build_ik_model`).
        info: the arm.
        collision_pairs: mink collision pairs of this arm.
        posture_qpos: posture target, a full qpos (nq,).
        config: tuning.
        velocity_limited: the joint velocity limit of tracking, or the step limit of offline solves.

    Raises:
        SimError: an arm joint that is not a hinge or slide joint.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        info: ArmInfo,
        collision_pairs: list[tuple[list[int], list[int]]],
        posture_qpos: np.ndarray,
        config: ArmControllerConfig,
        velocity_limited: bool,
    ) -> None:
        # mink (with qpsolvers and scipy.sparse, ~0.35 CPU-s) is imported by the first problem built, not with this
        # module: the action servers import the goal types beside it and never solve IK (it runs inside /sim).
        import mink

        self.info = info
        self.config = config
        self.model = model
        self.configuration = mink.Configuration(model)
        self.frame_task = mink.FrameTask(
            info.site, "site", position_cost=config.frame_position_cost,
            orientation_cost=config.frame_orientation_cost, lm_damping=config.lm_damping,
        )
        self._position_only = False
        posture_cost = np.zeros(model.nv)
        posture_cost[info.dof_adr] = config.posture_cost
        self.posture_task = mink.PostureTask(model, cost=posture_cost)
        self.posture_task.set_target(posture_qpos)
        self.configuration_limit = mink.ConfigurationLimit(model)
        # Offline solves take steps of dt = OFFLINE_DT: their velocity limit bounds each step to
        # OFFLINE_STEP rad so the collision limit cannot be tunnelled through in one big step.
        speed = config.joint_velocity_limit if velocity_limited else OFFLINE_STEP / OFFLINE_DT
        self.velocity_limit = mink.VelocityLimit(model, {j: speed for j in info.joints})
        self.collision_limit = mink.CollisionAvoidanceLimit(
            model, collision_pairs,
            minimum_distance_from_collisions=config.collision_min_distance,
            collision_detection_distance=config.collision_detection_distance,
        ) if collision_pairs else None
        self.limits: list[mink.Limit] = [self.configuration_limit, self.velocity_limit]
        if self.collision_limit is not None:
            self.limits.append(self.collision_limit)
        frozen = sorted(set(range(model.nv)) - set(int(d) for d in info.dof_adr))
        self.constraints: list[mink.Task] = [mink.DofFreezingTask(model, dof_indices=frozen)] if frozen else []
        self._pairs = [(a, b) for group_a, group_b in collision_pairs for a in group_a for b in group_b]
        joint_ids = [model.joint(j).id for j in info.joints]
        self._lower = model.jnt_range[joint_ids, 0].copy()
        self._upper = model.jnt_range[joint_ids, 1].copy()
        self._reduced = _ReducedQP(self, joint_ids)

    def set_configuration(self, qpos: np.ndarray, arm_q: np.ndarray | None = None) -> None:
        """Load a full qpos (nq,), optionally replacing the arm's joints [rad] (clipped to limits)."""
        q = self.configuration.data.qpos
        q[:] = qpos
        if arm_q is not None:
            q[self.info.qpos_adr] = arm_q
        q[self.info.qpos_adr] = np.clip(q[self.info.qpos_adr], self._lower, self._upper)
        self._reduced.forward()

    def clearance(self) -> float:
        """Smallest distance between the arm links and the obstacles in the IK configuration [m] (inf if none)."""
        fromto = np.empty(6)
        model, data = self.configuration.model, self.configuration.data
        distances = [mujoco.mj_geomDistance(model, data, a, b, 0.1, fromto) for a, b in self._pairs]
        return min(distances, default=math.inf)

    @property
    def arm_q(self) -> np.ndarray:
        """The arm's joint positions in the IK configuration [rad], shape (n,)."""
        return self.configuration.data.qpos[self.info.qpos_adr]

    def tool_pose(self) -> Pose:
        """Tool site pose of the IK configuration, world frame."""
        data = self.configuration.data
        return Pose(data.site_xpos[self.info.site_id].copy(), mat_to_quat(data.site_xmat[self.info.site_id]))

    def errors(self, target: Pose, position_only: bool) -> tuple[float, float]:
        """Position [m] and orientation [rad] error of the IK configuration's tool."""
        return self._reduced.errors(np.asarray(target.position), None if position_only else np.asarray(target.orientation_wxyz))

    def set_target(self, target: Pose, position_only: bool) -> None:
        """Aim the frame task at ``target`` (world frame), with or without its orientation."""
        self.frame_task.set_target(_se3(target))
        if position_only != self._position_only:
            self.frame_task.set_orientation_cost(0.0 if position_only else self.config.frame_orientation_cost)
            self._position_only = position_only

    def velocity(self, dt: float) -> np.ndarray | None:
        """One IK step of length ``dt`` [s] toward the frame task's target from the current configuration.

        Returns:
            The arm's joint velocities [rad/s], shape (n,), or None if the QP has no solution.
        """
        return self._reduced.solve(dt)

    def iterate(
        self, target: Pose, position_only: bool, dt: float, iterations: int, tolerance: tuple[float, float],
        stall_window: int = 0,
    ) -> int:
        """Run up to ``iterations`` IK steps of length ``dt`` [s] toward ``target``; returns steps used.

        With ``stall_window`` > 0, stop when the error shrank by less than 1 um (+ 1e-5 rad) over
        that many steps (converged as far as the limits allow).
        """
        self.set_target(target, position_only)
        target_position = np.asarray(target.position)
        target_quat = None if position_only else np.asarray(target.orientation_wxyz)
        reduced = self._reduced
        history: list[float] = []
        for step in range(iterations):
            position_error, orientation_error = reduced.errors(target_position, target_quat)
            if position_error <= tolerance[0] and orientation_error <= tolerance[1]:
                return step
            history.append(position_error + 0.1 * orientation_error)
            if stall_window and len(history) > stall_window and history[-1 - stall_window] - history[-1] < 1e-6:
                return step
            velocity = reduced.solve(dt)
            if velocity is None:
                return step  # keep the last configuration; the caller sees the remaining error
            if float(np.max(np.abs(velocity))) * dt < 1e-9:
                return step + 1
            reduced.integrate(velocity, dt)
        return iterations


def _index(addresses: np.ndarray) -> slice | np.ndarray:
    """A slice for consecutive addresses (a view, cheaper than gathering), else the addresses."""
    first = int(addresses[0])
    if np.array_equal(addresses, np.arange(first, first + len(addresses))):
        return slice(first, first + len(addresses))
    return addresses


class _ReducedQP:
    """The arm-only QP of an :class:`IKProblem` (private; see its docstring).

    With x = the arm's joint displacement (n,), W_f, e_f, mu the frame task's weighted Jacobian
    columns of the arm, weighted error and Levenberg-Marquardt term, and c_p the posture cost:

        min 1/2 x' (W_f' W_f + diag(c_p^2) + (damping + mu) I) x + (-e_f' W_f + c_p^2 (q - q_posture))' x
        s.t. max(-v dt, g (q_min - q)) <= x <= min(v dt, g (q_max - q))      (velocity, configuration)
             G_c x <= h_c                        (collision rows within the detection distance)

    which is mink's QP over every DoF with the frozen ones (x = 0 there) substituted.
    """

    DAMPING = 1e-9  # the global damping mink.solve_ik is called with
    INFINITY = 1e30  # daqp's "no bound"

    def __init__(self, problem: IKProblem, joint_ids: list[int]) -> None:
        model = problem.model
        info = problem.info
        for joint_id in joint_ids:
            if int(model.jnt_type[joint_id]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
                raise SimError(f"arm joint {model.joint(joint_id).name!r} is not a hinge or slide joint")
        self.model = model
        self.data = problem.configuration.data
        self.configuration = problem.configuration
        self.frame_task = problem.frame_task
        self.collision_rows = None if problem.collision_limit is None else CollisionRows(
            problem.collision_limit, problem.configuration.data, info.dof_adr)
        self.site_id = info.site_id
        self.qpos_adr = _index(info.qpos_adr)
        self.dof_adr = _index(info.dof_adr)
        n = len(joint_ids)
        posture_cost = problem.posture_task.cost[info.dof_adr]
        self.posture_weight = posture_cost * posture_cost  # c_p^2, shape (n,)
        self.posture_q = np.asarray(problem.posture_task.target_q)[info.qpos_adr].copy()
        self.regularization = np.diag(self.posture_weight + self.DAMPING)  # (n, n)
        # Box bounds from the mink limits, in the arm's joint order.
        limit = problem.configuration_limit
        limited = {int(d) for d in limit.indices}
        self.limit_gain = limit.gain
        # An unlimited joint gets a bound so large it is never active (daqp reads >= 1e30 as none).
        adrs = list(zip(info.qpos_adr, info.dof_adr, strict=True))
        self.q_min = np.array([limit.lower[a] if d in limited else -self.INFINITY for a, d in adrs])
        self.q_max = np.array([limit.upper[a] if d in limited else self.INFINITY for a, d in adrs])
        speed = dict(zip((int(i) for i in problem.velocity_limit.indices), problem.velocity_limit.limit, strict=True))
        self.speed = np.array([speed.get(int(d), self.INFINITY) for d in info.dof_adr])
        self.sense = np.zeros(n, dtype=np.int32)
        self.no_rows = np.zeros((0, n))
        self._quat = np.empty(4)
        self._diff = np.empty(3)

    def forward(self) -> None:
        """Kinematics of the configuration's qpos: what the frame Jacobian and the distances need."""
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)

    def integrate(self, velocity: np.ndarray, dt: float) -> None:
        """Move the arm's joints by ``velocity * dt`` (hinge and slide joints: plain addition)."""
        self.data.qpos[self.qpos_adr] += velocity * dt
        self.forward()

    def errors(self, target_position: np.ndarray, target_quat: np.ndarray | None) -> tuple[float, float]:
        """Tool position error [m] and orientation error [rad] (0 when ``target_quat`` is None)."""
        offset = self.data.site_xpos[self.site_id] - target_position
        position_error = math.sqrt(float(offset @ offset))
        if target_quat is None:
            return position_error, 0.0
        mujoco.mju_mat2Quat(self._quat, self.data.site_xmat[self.site_id])
        mujoco.mju_subQuat(self._diff, target_quat, self._quat)
        return position_error, math.sqrt(float(self._diff @ self._diff))

    def solve(self, dt: float) -> np.ndarray | None:
        """The arm's joint velocities [rad/s] (n,) of one step of length ``dt`` [s], or None (no solution)."""
        jacobian, error, mu = self.frame_task.compute_qp_residual(self.configuration)
        jacobian = jacobian[:, self.dof_adr]
        q = self.data.qpos[self.qpos_adr]
        hessian = jacobian.T @ jacobian + self.regularization
        hessian.flat[:: len(q) + 1] += mu
        linear = self.posture_weight * (q - self.posture_q) - error @ jacobian
        step = self.speed * dt
        upper = np.minimum(step, self.limit_gain * (self.q_max - q))
        lower = np.maximum(-step, self.limit_gain * (self.q_min - q))
        rows, bounds = self._collision_rows(dt)
        sense = self.sense
        if rows.shape[0]:
            upper = np.concatenate((upper, bounds))
            lower = np.concatenate((lower, np.full(bounds.shape, -self.INFINITY)))
            sense = np.zeros(upper.shape, dtype=np.int32)
        x, _, exitflag, _ = daqp.solve(hessian, linear, rows, upper, lower, sense)
        if exitflag <= 0:
            return None
        velocity: np.ndarray = x / dt
        return velocity

    def _collision_rows(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Rows (m, n) and bounds (m,) of the collision limit that are active (pairs within the detection distance)."""
        if self.collision_rows is None:
            return self.no_rows, np.zeros(0)
        return self.collision_rows.compute(dt)
