"""An arm of a robot, resolved once from names: joints, addresses, actuators, tool site, reach, gripper."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models import ArmScene, RobotSpec
from sim_bridge.errors import UnknownNameError
from sim_bridge.state import Pose


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
