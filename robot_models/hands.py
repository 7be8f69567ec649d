"""A robot hand that grasps with its fingers: which joints close it, and where a held object sits in it.

A :class:`HandLayout` is a fact of the robot (its names and poses), read by the core's one-hand grasp
(:mod:`sim_bridge.fetch.one_hand`). Poses and points are in the hand's tool frame: the arm's end-effector
site (:attr:`robot_models.spec.RobotSpec.end_effector_sites`), x along the fingers.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class HandLayout:
    """One hand, for grasps with its fingers.

    Attributes:
        arm: the arm it ends (a joint group and an end-effector site of the robot).
        hand_body: the hand's first body; it and its subtree are the hand (palm and fingers).
        fingers: finger name -> the joints that curl it toward the palm; the first finger opposes the others
            (a thumb): a grasp needs it and one other finger on the object.
        open_pose: joint -> angle [rad] of the open hand ready to close around an object (every hand joint).
        closed_pose: joint -> angle [rad] of the fingers fully curled (a fist): they close toward it.
        palm_normal_in_tool: unit vector from the palm into what it holds, tool frame.
        grasp_point_in_tool: where a held small object's centre sits, tool frame [m] (between the opposing
            finger and the others, clear of the palm face).
    """

    arm: str
    hand_body: str
    fingers: Mapping[str, tuple[str, ...]]
    open_pose: Mapping[str, float]
    closed_pose: Mapping[str, float]
    palm_normal_in_tool: Vec3
    grasp_point_in_tool: Vec3

    def __post_init__(self) -> None:
        if len(self.fingers) < 2:
            raise ValueError(f"hand of {self.arm!r}: a grasp needs an opposing finger and another, got {list(self.fingers)}")
        curled = {joint for joints in self.fingers.values() for joint in joints}
        missing = curled - set(self.closed_pose) | set(self.closed_pose) - set(self.open_pose)
        if missing:
            raise ValueError(f"hand of {self.arm!r}: joints without an open and a closed angle: {sorted(missing)}")
        if abs(float(np.linalg.norm(self.palm_normal_in_tool)) - 1.0) > 1e-9:
            raise ValueError(f"hand of {self.arm!r}: the palm normal must be a unit vector, got {self.palm_normal_in_tool}")
