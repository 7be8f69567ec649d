"""Arm kinematics of a robot: an IK problem pair (tracking, offline) per arm, offline solves, ``solve_ik``."""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from robot_models import RobotSpec
from sim_bridge.arm.description import ArmInfo, arm_infos, check_arm_name, workspace_reason
from sim_bridge.arm.ik_model import build_collision_model, build_ik_model
from sim_bridge.arm.ik_problem import OFFLINE_DT, IKProblem
from sim_bridge.arm.poses import validate_pose
from sim_bridge.arm.types import ArmControllerConfig, IKResult
from sim_bridge.errors import InvalidGoalError
from sim_bridge.state import Pose


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


class ArmKinematics:
    """The IK model of a robot and an IK problem pair (tracking, offline) per arm.

    Building it compiles the robot's spec once more when its obstacles are visual meshes, for their
    convex hulls (see :func:`~sim_bridge.arm.ik_model.build_collision_model`). It keeps its IK model,
    not the robot (whose model it needs while it is built, with visuals when the IK avoids visual meshes).

    Args:
        robot: the robot scene.
        config: tuning.
    """

    def __init__(self, robot: RobotSpec, config: ArmControllerConfig | None = None) -> None:
        self.config = config or ArmControllerConfig()
        self.scene = robot.arm_scene
        self.arms = arm_infos(robot, self.scene)
        self.posture_qpos = robot.model.key(robot.default_keyframe).qpos.copy()
        self.tracking: dict[str, IKProblem] = {}
        self.offline: dict[str, IKProblem] = {}
        ik_model, pairs = build_ik_model(build_collision_model(robot, self.scene, self.arms), self.scene, self.arms)
        for arm, info in self.arms.items():
            self.tracking[arm] = IKProblem(ik_model, info, pairs[arm], self.posture_qpos, self.config, True)
            self.offline[arm] = IKProblem(ik_model, info, pairs[arm], self.posture_qpos, self.config, False)
        # The IK model has the robot's kinematics (only its limits and contacts differ): the robot's own
        # model is not kept, so a process may build this from a robot it then lets go.
        self.model = ik_model
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
