"""Both palms on a box: where the hands go to squeeze it, and how hard they measurably squeeze.

The palms are the robot's ``palms`` sites (:attr:`~robot_models.spec.RobotSpec.palms`): the centre of
each palm's contact face, z along its outward normal. A grip puts the two faces on the box's +-y
faces, their x axes along the box's x axis, at its centre; the squeeze depth ``depth`` moves a face
that far past the box's surface (negative: a clearance). The hand (tool site) targets that the arm
controller tracks follow from each palm site's fixed pose in its hand's body.

The grip force of a hand is measured: the sum of the normal forces of the contacts between the
hand's body subtree and the object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models import RobotSpec
from sim_bridge.arm.poses import mat_to_quat, quat_to_mat
from sim_bridge.arm.types import ArmStatus
from sim_bridge.entities import descends
from sim_bridge.errors import InvalidGoalError, UnknownNameError
from sim_bridge.fetch.contacts import contacts_on, normal_force, solve_contact_forces
from sim_bridge.state import Pose


def yaw_matrix(yaw: float) -> np.ndarray:
    """Rotation about world z by ``yaw`` [rad], shape (3, 3)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Palm:
    """One palm: its arm, side and the fixed transform from its hand's tool site.

    Attributes:
        arm: the arm's name.
        side: +1 for the palm on the robot's left (it meets the box's +y face), -1 on its right.
        position_in_tool: palm site position in the tool site frame [m], shape (3,).
        rotation_in_tool: palm site orientation in the tool site frame, shape (3, 3).
        bodies: the hand's bodies (the tool site's body and its subtree), whose contacts are the grip.
    """

    arm: str
    side: float
    position_in_tool: np.ndarray
    rotation_in_tool: np.ndarray
    bodies: frozenset[int]


def palms_of(robot: RobotSpec) -> tuple[Palm, Palm]:
    """The robot's two palms, left first, read from its model at its default keyframe.

    Raises:
        InvalidGoalError: the robot does not have exactly two palms (``RobotSpec.palms``).
    """
    if len(robot.palms) != 2:
        raise InvalidGoalError(f"robot {robot.name!r} has no two palms to squeeze an object between "
                               f"(palms: {', '.join(robot.palms) or 'none'})")
    model = robot.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(robot.default_keyframe).id)
    mujoco.mj_kinematics(model, data)
    base = data.body(robot.base_body)
    base_rotation = base.xmat.reshape(3, 3)
    found = []
    for arm, palm_site in robot.palms.items():
        tool, palm = data.site(robot.end_effector_sites[arm]), data.site(palm_site)
        tool_rotation = tool.xmat.reshape(3, 3)
        side = 1.0 if float((base_rotation.T @ (palm.xpos - base.xpos))[1]) > 0.0 else -1.0
        hand = int(model.site_bodyid[model.site(palm_site).id])
        bodies = frozenset(b for b in range(model.nbody) if descends(model, b, hand))
        found.append(Palm(arm, side, tool_rotation.T @ (palm.xpos - tool.xpos), tool_rotation.T @ palm.xmat.reshape(3, 3),
                          bodies))
    left, right = sorted(found, key=lambda p: -p.side)
    if left.side == right.side:
        raise InvalidGoalError(f"robot {robot.name!r}: both palms are on the same side")
    return left, right


def set_palm_hand_pose(robot: RobotSpec, model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Command the hands' servos to the pose their palms squeeze in (``RobotSpec.palm_hand_pose``); the
    targets stay until something else commands those joints.

    Raises:
        UnknownNameError: a joint of the pose has no actuator of its name.
    """
    for joint, angle in robot.palm_hand_pose.items():
        actuator = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, joint)
        if actuator < 0:
            raise UnknownNameError(f"no actuator for the hand joint {joint!r}")
        data.ctrl[actuator] = angle




def tool_target(palm: Palm, center: np.ndarray, yaw: float, half_width: float, depth: float, pitch: float = 0.0) -> Pose:
    """The tool pose that puts ``palm``'s face on the box side: box centre ``center`` (world [m]), yaw
    [rad], half width along its y axis [m], the face ``depth`` [m] past the surface (negative: short of it),
    the palm's x axis (along the hand) pitched ``pitch`` [rad] down from the box's x axis (a turn about
    the face's normal: the face stays on the side)."""
    box = yaw_matrix(yaw)
    normal = -palm.side * box[:, 1]  # from the palm into the box
    face = np.asarray(center, dtype=float) - normal * (half_width - depth)
    along = math.cos(pitch) * box[:, 0] - math.sin(pitch) * box[:, 2]
    palm_rotation = np.column_stack([along, np.cross(normal, along), normal])
    tool_rotation = palm_rotation @ palm.rotation_in_tool.T
    return Pose(face - tool_rotation @ palm.position_in_tool, mat_to_quat(tool_rotation))


def grip_forces(model: mujoco.MjModel, data: mujoco.MjData, palms: tuple[Palm, Palm], body: int,
                solve: bool = False) -> tuple[float, float]:
    """Normal contact force [N] of each palm's hand (left, right) on the object ``body``.

    Args:
        solve: the contacts are those of the current positions but the constraint forces are not yet
            solved for them (inside the control step, between ``mj_step1`` and ``mj_step2``): solve them
            first, when a hand touches the object (``mj_step2`` solves them again with the new controls).
    """
    def side_of(other: int) -> int | None:
        return next((side for side, palm in enumerate(palms) if other in palm.bodies), None)

    touching = contacts_on(model, data, body, side_of)
    if not touching:
        return 0.0, 0.0
    if solve:
        solve_contact_forces(model, data)
    totals = [0.0, 0.0]
    wrench = np.zeros(6)
    for index, side in touching:
        totals[side] += normal_force(model, data, index, wrench)
    return totals[0], totals[1]


def yaw_of(quat_wxyz: np.ndarray) -> float:
    """Yaw of a rotation's x axis about world z [rad]."""
    matrix = quat_to_mat(quat_wxyz)
    return math.atan2(matrix[1, 0], matrix[0, 0])


def tilt_of(quat_wxyz: np.ndarray) -> float:
    """Angle between a body's z axis and world z [rad]."""
    return math.acos(min(1.0, max(-1.0, float(quat_to_mat(quat_wxyz)[2, 2]))))


def in_palms(model: mujoco.MjModel, data: mujoco.MjData, palms: tuple[Palm, Palm], object_name: str,
             min_force_n: float) -> bool:
    """Whether both palms press on the object with at least ``min_force_n`` [N] each (False for an unknown name)."""
    try:
        body = int(model.body(object_name).id)
    except KeyError:
        return False
    return min(grip_forces(model, data, palms, body)) >= min_force_n


def squeeze_depths(palms: tuple[Palm, Palm], statuses: list[ArmStatus], yaw: float) -> list[float]:
    """The squeeze depth [m] of a grip that holds on its arms' held joint targets, for a new grip to take it
    over: how far the held (commanded) palm faces lie past the measured ones along the grip's normal (yaw [rad]),
    the same for both palms (their mean: arms that sag sideways together shift both faces one way, which is
    no squeeze)."""
    box = yaw_matrix(yaw)
    depths = []
    for palm, status in zip(palms, statuses, strict=True):
        normal = -palm.side * box[:, 1]
        held, tool = (pose.position + quat_to_mat(pose.orientation_wxyz) @ palm.position_in_tool
                      for pose in (status.reference_pose, status.tool_pose))
        depths.append(float((held - tool) @ normal))
    return [sum(depths) / 2.0] * 2
