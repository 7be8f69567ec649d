"""Arm kinematics on a private copy of the model: arm descriptions, mink IK problems, ``solve_ik``.

Nothing here writes the simulation's ``MjData``: every IK problem runs on its own
:class:`mink.Configuration`. For a robot with more DoFs than the arm (floating base, legs, other
arm, gripper, free objects) every DoF but the arm's is frozen by an equality constraint.
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import daqp
import mink
import mujoco
import numpy as np

from robot_models import ArmScene, RobotSpec
from sim_bridge.arm.types import ArmControllerConfig, IKResult
from sim_bridge.errors import InvalidGoalError, SimError, UnknownNameError
from sim_bridge.state import Pose

OFFLINE_DT = 0.1  # [s] step length of offline solves
OFFLINE_STEP = 0.04  # [rad] largest joint change per offline step


# ----- small pose helpers ------------------------------------------------------------------------
def quat_to_mat(quat_wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z)."""
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat_wxyz, dtype=float))
    return mat.reshape(3, 3)


def mat_to_quat(mat: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (3, 3) or (9,)."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.asarray(mat, dtype=float).reshape(9))
    return quat


def rotation_error(quat_a: np.ndarray, quat_b: np.ndarray) -> float:
    """Angle of the rotation between two orientations [rad]."""
    diff = np.empty(3)
    mujoco.mju_subQuat(diff, np.asarray(quat_a, dtype=float), np.asarray(quat_b, dtype=float))
    return float(np.linalg.norm(diff))


def interpolate_quat(quat_from: np.ndarray, quat_to: np.ndarray, fraction: float) -> np.ndarray:
    """Geodesic interpolation (slerp) between two unit quaternions; ``fraction`` in [0, 1]."""
    delta = np.empty(3)
    mujoco.mju_subQuat(delta, np.asarray(quat_to, dtype=float), np.asarray(quat_from, dtype=float))
    quat = np.array(quat_from, dtype=float)
    mujoco.mju_quatIntegrate(quat, delta, float(fraction))
    return quat


def validate_pose(pose: Pose) -> Pose:
    """A copy of ``pose`` with a normalised quaternion.

    Raises:
        InvalidGoalError: wrong shapes, non-finite values or a zero quaternion.
    """
    position = np.asarray(pose.position, dtype=float).reshape(-1)
    quat = np.asarray(pose.orientation_wxyz, dtype=float).reshape(-1)
    if position.shape != (3,) or quat.shape != (4,):
        raise InvalidGoalError(f"a pose needs 3 position and 4 quaternion values, got {position.size} and {quat.size}")
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quat))):
        raise InvalidGoalError("pose values must be finite numbers")
    norm = float(np.linalg.norm(quat))
    if norm < 1e-9:
        raise InvalidGoalError("the orientation quaternion (w, x, y, z) has zero norm")
    return Pose(position.copy(), quat / norm)


def _se3(pose: Pose) -> mink.SE3:
    """The pose as a mink transform (its quaternion is already normalised by :func:`validate_pose`)."""
    return mink.SE3(np.concatenate((np.asarray(pose.orientation_wxyz, dtype=float), np.asarray(pose.position, dtype=float))))


# ----- arm description ---------------------------------------------------------------------------
@dataclass(frozen=True)
class ArmInfo:
    """Indices of one arm, resolved once from names.

    Attributes:
        name: arm name (a joint group of the robot spec).
        joints: arm joint names, shoulder to wrist.
        qpos_adr: qpos address of each arm joint, shape (n,).
        dof_adr: qvel address of each arm joint, shape (n,).
        actuator_ids: position actuator of each arm joint, shape (n,).
        site: tool point site name.
        site_id: tool point site id.
        base_joint_id: id of the first arm joint (its anchor is the shoulder).
        reach: upper bound of the distance shoulder -> tool point [m].
        gripper_joints: finger joints ("" tuple for no gripper).
        gripper_qpos_adr: qpos address of each finger joint.
        gripper_actuator_ids: actuator of each finger joint.
    """

    name: str
    joints: tuple[str, ...]
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    actuator_ids: np.ndarray
    site: str
    site_id: int
    base_joint_id: int
    reach: float
    gripper_joints: tuple[str, ...]
    gripper_qpos_adr: np.ndarray
    gripper_actuator_ids: np.ndarray


def _actuator_of(model: mujoco.MjModel, joint: str) -> int:
    joint_id = model.joint(joint).id
    for actuator_id in range(model.nu):
        if model.actuator_trntype[actuator_id] == mujoco.mjtTrn.mjTRN_JOINT and model.actuator_trnid[actuator_id, 0] == joint_id:
            return actuator_id
    raise UnknownNameError(f"joint {joint!r} has no actuator")


def _reach(model: mujoco.MjModel, joints: Sequence[str], site: str, qpos: np.ndarray) -> float:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    points = [*(data.xanchor[model.joint(j).id].copy() for j in joints), data.site(site).xpos.copy()]
    return float(sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(points)))


def arm_infos(robot: RobotSpec, scene: ArmScene) -> dict[str, ArmInfo]:
    """Every arm of the robot (one per end-effector site), resolved to indices."""
    model = robot.model
    key_qpos = model.key(robot.default_keyframe).qpos.copy()
    infos = {}
    for arm, site in robot.end_effector_sites.items():
        joints = tuple(robot.joint_groups[arm])
        grippers = tuple(scene.grippers.get(arm, ()))
        infos[arm] = ArmInfo(
            name=arm,
            joints=joints,
            qpos_adr=np.array([model.joint(j).qposadr[0] for j in joints], dtype=int),
            dof_adr=np.array([model.joint(j).dofadr[0] for j in joints], dtype=int),
            actuator_ids=np.array([_actuator_of(model, j) for j in joints], dtype=int),
            site=site,
            site_id=int(model.site(site).id),
            base_joint_id=int(model.joint(joints[0]).id),
            reach=_reach(model, joints, site, key_qpos),
            gripper_joints=grippers,
            gripper_qpos_adr=np.array([model.joint(j).qposadr[0] for j in grippers], dtype=int),
            gripper_actuator_ids=np.array([_actuator_of(model, j) for j in grippers], dtype=int),
        )
    return infos


def check_arm_name(infos: dict[str, ArmInfo], arm: str) -> ArmInfo:
    """The named arm.

    Raises:
        UnknownNameError: no such arm; the message lists the arms.
    """
    try:
        return infos[arm]
    except KeyError:
        raise UnknownNameError(f"unknown arm {arm!r}; arms: {', '.join(infos)}") from None


def _subtree_bodies(model: mujoco.MjModel, root: int) -> list[int]:
    bodies = [root]
    for body in range(root + 1, model.nbody):
        parent = int(model.body_parentid[body])
        if parent in bodies:
            bodies.append(body)
    return bodies


def _arm_and_obstacle_geoms(model: mujoco.MjModel, scene: ArmScene, info: ArmInfo) -> tuple[list[int], list[int]]:
    """The arm link geoms checked for collisions (from ``scene.collision_from_joint`` on) and the obstacle geoms."""
    obstacle_geoms = [model.geom(name).id for name in scene.obstacle_geoms]
    for body_name in scene.obstacle_bodies:
        body_id = model.body(body_name).id
        obstacle_geoms += [g for g in range(model.ngeom) if model.geom_bodyid[g] == body_id]
    first = info.joints[min(scene.collision_from_joint, len(info.joints) - 1)]
    bodies = set(_subtree_bodies(model, int(model.jnt_bodyid[model.joint(first).id])))
    arm_geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies]
    return arm_geoms, obstacle_geoms


def build_collision_model(robot: RobotSpec, scene: ArmScene, infos: dict[str, ArmInfo]) -> mujoco.MjModel:
    """The robot's model, recompiled with the arm and obstacle geoms colliding if they are visual-only.

    Compiling them as colliding geoms (rather than flipping ``geom_contype`` in a compiled model)
    gives their meshes the convex hulls MuJoCo's distance queries walk: without one, every query
    visits all of a mesh's vertices (~9,500 for the G1 torso, up to ~70 us a query).

    Raises:
        SimError: the recompiled model does not have the layout of the robot's model.
    """
    model = robot.model
    if not scene.make_visuals_collide:
        return model
    colliding = set()
    for info in infos.values():
        arm_geoms, obstacle_geoms = _arm_and_obstacle_geoms(model, scene, info)
        colliding.update(arm_geoms + obstacle_geoms)
    spec = robot.mjspec.copy()
    for geom_id, geom in enumerate(spec.geoms):
        if geom_id in colliding:
            geom.contype, geom.conaffinity = 1, 1
    compiled = spec.compile()
    same_layout = (
        (compiled.nq, compiled.nv, compiled.ngeom, compiled.nbody) == (model.nq, model.nv, model.ngeom, model.nbody)
        and np.array_equal(compiled.geom_bodyid, model.geom_bodyid) and np.array_equal(compiled.jnt_qposadr, model.jnt_qposadr)
    )
    if not same_layout:
        raise SimError(f"the collision model of {robot.name!r} does not have the layout of its model")
    return compiled


def build_ik_model(
    base: mujoco.MjModel, scene: ArmScene, info: ArmInfo,
) -> tuple[mujoco.MjModel, list[tuple[list[int], list[int]]]]:
    """A private copy of the model for one arm's IK, and that arm's collision pairs.

    Only the arm's joints keep their position limits in the copy: every other DoF is frozen by an
    equality constraint, and a frozen DoF measured a hair outside its range would make mink's
    ConfigurationLimit contradict the freezing constraint.

    Args:
        base: the robot's model, with the arm and obstacle geoms colliding (see :func:`build_collision_model`).
        scene: the robot's arm facts.
        info: the arm.

    Returns:
        The IK model and mink collision pairs (arm link geoms, obstacle geoms).
    """
    model = copy.deepcopy(base)
    arm_joint_ids = {model.joint(j).id for j in info.joints}
    for joint_id in range(model.njnt):
        if joint_id not in arm_joint_ids:
            model.jnt_limited[joint_id] = 0
    arm_geoms, obstacle_geoms = _arm_and_obstacle_geoms(model, scene, info)
    pairs = [(arm_geoms, obstacle_geoms)] if arm_geoms and obstacle_geoms else []
    return model, pairs


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
        model: the IK model (see :func:`build_ik_model`).
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
        self.collision_rows = None if problem.collision_limit is None else _CollisionRows(
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


class _CollisionRows:
    """The active rows of a :class:`mink.CollisionAvoidanceLimit`, on the arm's columns (private).

    Row and bound of a pair are mink's: the contact normal times the difference of the two
    witness points' Jacobians, bounded by ``gain * (distance - minimum) / dt`` (``relaxation``
    once closer than the minimum). A pair farther apart than the detection distance gives no row;
    as in mink, pairs whose bounding spheres are that far apart skip the distance query when there
    are enough pairs for that test to pay (a distance query costs about 1 us).

    Args:
        limit: the mink limit (its pairs and parameters are used as they are).
        data: the IK configuration's data.
        dof_adr: the arm's DoF addresses, shape (n,).
    """

    BROADPHASE_MIN_PAIRS = 16  # as mink: below this, querying every pair is cheaper than the sphere test

    def __init__(self, limit: mink.CollisionAvoidanceLimit, data: mujoco.MjData, dof_adr: np.ndarray) -> None:
        model = limit.model
        self.model, self.data, self.dof_adr = model, data, dof_adr
        self.gain = limit.gain
        self.minimum = limit.minimum_distance_from_collisions
        self.detection = limit.collision_detection_distance
        self.relaxation = limit.bound_relaxation
        pairs = np.array(limit.geom_id_pairs, dtype=int).reshape(-1, 2)
        # (geom1, geom2, body1, body2) of each pair, as Python ints for the per-pair loop.
        self.pairs = [(int(a), int(b), int(model.geom_bodyid[a]), int(model.geom_bodyid[b])) for a, b in pairs]
        # The pairs as cells of a grid (first geoms x second geoms), so the sphere test gathers each
        # geom's position once: the squared reach of each cell (inf: always a candidate, -1: no pair).
        geom1, geom2 = pairs[:, 0], pairs[:, 1]
        self.first, self.second = np.unique(geom1), np.unique(geom2)
        row, column = np.searchsorted(self.first, geom1), np.searchsorted(self.second, geom2)
        reach = model.geom_rbound[geom1] + model.geom_rbound[geom2] + self.detection
        unbounded = (model.geom_rbound[geom1] <= 0.0) | (model.geom_rbound[geom2] <= 0.0)  # planes, height fields
        self.reach_squared = np.full((len(self.first), len(self.second)), -1.0)
        self.reach_squared[row, column] = np.where(unbounded, np.inf, reach * reach)
        self.pair_of_cell = np.full(self.reach_squared.shape, -1, dtype=int)
        self.pair_of_cell[row, column] = np.arange(len(pairs))
        self._fromto = np.empty(6)
        self._normal = np.empty(3)
        self._jac1 = np.empty((3, model.nv))
        self._jac2 = np.empty((3, model.nv))

    def candidates(self) -> list[int]:
        """Indices of the pairs that may be within the detection distance (bounding spheres, unbounded geoms)."""
        if len(self.pairs) < self.BROADPHASE_MIN_PAIRS:
            return list(range(len(self.pairs)))
        xpos = self.data.geom_xpos
        offset = xpos[self.first][:, None, :] - xpos[self.second][None, :, :]
        near = np.einsum("ijk,ijk->ij", offset, offset) <= self.reach_squared
        indices: list[int] = self.pair_of_cell[near].tolist()
        return indices

    def compute(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Rows (m, n) and bounds (m,) of the pairs within the detection distance, for a step of ``dt`` [s]."""
        model, data = self.model, self.data
        fromto, normal, jac1, jac2 = self._fromto, self._normal, self._jac1, self._jac2
        detection = self.detection
        rows: list[np.ndarray] = []
        bounds: list[float] = []
        for index in self.candidates():
            geom1, geom2, body1, body2 = self.pairs[index]
            distance = mujoco.mj_geomDistance(model, data, geom1, geom2, detection, fromto)
            if abs(distance - detection) < 1e-12:
                continue
            np.subtract(fromto[3:], fromto[:3], out=normal)
            mujoco.mju_normalize3(normal)
            mujoco.mj_jac(model, data, jac2, None, fromto[3:], body2)
            mujoco.mj_jac(model, data, jac1, None, fromto[:3], body1)
            jac2 -= jac1
            row = normal @ jac2[:, self.dof_adr]
            rows.append(-row if distance >= 0.0 else row)
            if distance > self.minimum:
                bounds.append(self.gain * (distance - self.minimum) / dt + self.relaxation)
            else:
                bounds.append(self.relaxation)
        if not rows:
            return np.zeros((0, len(self.dof_adr))), np.zeros(0)
        return np.array(rows), np.array(bounds)


def solve_offline(
    problem: IKProblem, target: Pose, position_only: bool, seeds: Sequence[np.ndarray], qpos: np.ndarray
) -> IKResult:
    """Converge an IK problem from each seed in turn until one reaches the target.

    Args:
        problem: an IK problem without velocity limit.
        target: tool goal in the world frame.
        position_only: ignore orientation.
        seeds: arm joint positions to start from [rad].
        qpos: full qpos (nq,) for the other DoFs (floating base, other arm).
    """
    config = problem.config
    fine = (config.position_tolerance * 0.05, config.orientation_tolerance * 0.05)
    best: IKResult | None = None
    for seed in seeds:
        problem.set_configuration(qpos, seed)
        used = problem.iterate(target, position_only, OFFLINE_DT, config.offline_ik_iterations, fine, stall_window=10)
        position_error, orientation_error = problem.errors(target, position_only)
        clearance = problem.clearance()
        on_target = position_error <= config.position_tolerance and orientation_error <= config.orientation_tolerance
        collides = clearance < config.collision_min_distance - 0.002
        if not on_target:
            reason = (
                f"IK converged {position_error * 1000:.1f} mm / {orientation_error:.3f} rad from the target "
                f"(tolerance {config.position_tolerance * 1000:.1f} mm / {config.orientation_tolerance:.3f} rad): "
                "joint limits or collision avoidance block it"
            )
        elif collides:
            reason = f"IK solution puts the arm links {clearance * 1000:.1f} mm from an obstacle (in collision)"
        else:
            reason = ""
        success = not reason
        result = IKResult(problem.info.joints, problem.arm_q, position_error, orientation_error, success, reason, used)
        if success:
            return result
        if best is None or position_error + 0.1 * orientation_error < best.position_error + 0.1 * best.orientation_error:
            best = result
    assert best is not None  # seeds is never empty (checked by callers)
    return best


def workspace_reason(info: ArmInfo, shoulder_world: np.ndarray, target: Pose, table_top_z: float | None) -> str:
    """Why a target is outside the arm's workspace, or "" if it may be inside."""
    distance = float(np.linalg.norm(np.asarray(target.position) - shoulder_world))
    if distance > info.reach:
        return (f"target is outside the workspace: {distance:.3f} m from the first joint of {info.name!r}, "
                f"farther than its reach {info.reach:.3f} m")
    if table_top_z is not None and float(target.position[2]) < table_top_z:
        return (f"target is outside the workspace: z = {float(target.position[2]):.3f} m "
                f"is below the table top z = {table_top_z:.3f} m")
    return ""


class ArmKinematics:
    """The IK model of a robot and an IK problem pair (tracking, offline) per arm.

    Building it compiles the robot's spec once more when its obstacles are visual meshes (the G1:
    about 0.5 s, for their convex hulls; see :func:`build_collision_model`).

    Args:
        robot: the robot scene.
        config: tuning.
    """

    def __init__(self, robot: RobotSpec, config: ArmControllerConfig | None = None) -> None:
        self.robot = robot
        self.config = config or ArmControllerConfig()
        self.scene = robot.arm_scene
        self.arms = arm_infos(robot, self.scene)
        self.posture_qpos = robot.model.key(robot.default_keyframe).qpos.copy()
        self.tracking: dict[str, IKProblem] = {}
        self.offline: dict[str, IKProblem] = {}
        collision_model = build_collision_model(robot, self.scene, self.arms)
        for arm, info in self.arms.items():
            model, pairs = build_ik_model(collision_model, self.scene, info)
            self.tracking[arm] = IKProblem(model, info, pairs, self.posture_qpos, self.config, True)
            self.offline[arm] = IKProblem(model, info, pairs, self.posture_qpos, self.config, False)
        self.model = robot.model
        self._data = mujoco.MjData(self.model)

    def arm(self, name: str) -> ArmInfo:
        """The named arm; raises UnknownNameError listing the arms."""
        return check_arm_name(self.arms, name)

    def shoulder_position(self, arm: str, qpos: np.ndarray) -> np.ndarray:
        """World position of the arm's first joint anchor for a full qpos [m]."""
        self._data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self._data)
        return self._data.xanchor[self.arms[arm].base_joint_id].copy()

    def solve(self, arm: str, qpos: np.ndarray, target: Pose, position_only: bool) -> IKResult:
        """Offline IK from ``qpos`` (nq,) and from the default keyframe's arm posture.

        Raises:
            UnknownNameError: unknown arm.
            InvalidGoalError: malformed pose.
        """
        info = self.arm(arm)
        target = validate_pose(target)
        qpos = np.asarray(qpos, dtype=float)
        reason = workspace_reason(info, self.shoulder_position(arm, qpos), target, self.scene.objects_table_top_z)
        if reason:
            return IKResult(info.joints, qpos[info.qpos_adr].copy(), math.nan, math.nan, False, reason, 0)
        seeds = [qpos[info.qpos_adr], self.posture_qpos[info.qpos_adr]]
        return solve_offline(self.offline[arm], target, position_only, seeds, qpos)


def solve_ik(
    robot: RobotSpec | ArmKinematics,
    data_or_q: mujoco.MjData | np.ndarray,
    arm: str,
    target_pose: Pose,
    position_only: bool,
) -> IKResult:
    """Pure IK query: arm joint positions that put the arm's tool point at ``target_pose``.

    Args:
        robot: the robot scene, or an :class:`ArmKinematics` built from it (reused, faster).
        data_or_q: the current state (its qpos is read, never written), or a full qpos (nq,).
        arm: arm name, e.g. ``"arm"`` (panda) or ``"right_arm"`` (G1).
        target_pose: tool point goal in the world frame.
        position_only: ignore the orientation.

    Returns:
        The solution with its remaining errors; ``success`` is false with a ``reason`` when the
        target is outside the workspace or the IK converges farther than tolerance.

    Raises:
        UnknownNameError: unknown arm (the message lists the arms).
        InvalidGoalError: malformed pose or qpos.
    """
    kinematics = robot if isinstance(robot, ArmKinematics) else ArmKinematics(robot)
    qpos = np.array(data_or_q.qpos if isinstance(data_or_q, mujoco.MjData) else data_or_q, dtype=float).reshape(-1)
    if qpos.shape != (kinematics.model.nq,) or not np.all(np.isfinite(qpos)):
        raise InvalidGoalError(f"qpos must hold {kinematics.model.nq} finite values, got shape {qpos.shape}")
    return kinematics.solve(arm, qpos, target_pose, position_only)
