"""The G1's Dex3-1 hands as grasping hands (:class:`~robot_models.hands.HandLayout`): a small object held
between the thumb and the index and middle fingers.

In the wrist yaw link's frame (the tool frame's axes; the tool site sits 8.5 cm along x, at the palm's
centre) the thumb's root is at x = 0.067 m and it stands out of the palm face (y = +-0.0175 m, the
side the fingers close to) along the palm normal; the index (z = +0.0285 m) and the middle finger
(z = -0.0285 m) start at x = 0.119 m and curl toward the palm normal. An object of 5-6 cm sits in front
of the palm between the thumb (behind it, along x) and the two fingers (ahead of it and over it): its
centre 2 cm ahead of the palm's centre, 5 cm out of the palm (5 mm clear of the face), between the two
fingers. Open, the thumb swings 0.5 rad back toward the wrist so the object slides in past it.
"""

from __future__ import annotations

from typing import Final

import robot_models.g1_constants as names
from robot_models.hands import HandLayout

# In the order of names.LEFT_HAND_JOINTS; the right hand mirrors them (names.HAND_MIRROR).
LEFT_HAND_GRASP_OPEN: Final = (0.0, -0.5, 0.0, 0.0, 0.0, 0.0, 0.0)
GRASP_POINT_IN_RIGHT_TOOL: Final = (0.02, 0.055, -0.01)  # [m]; the left hand's mirrors y


def _pose(joints: tuple[str, ...], angles: tuple[float, ...], mirrored: bool) -> dict[str, float]:
    signs = names.HAND_MIRROR if mirrored else (1.0,) * len(joints)
    return {joint: sign * angle for joint, sign, angle in zip(joints, signs, angles, strict=True)}


def _hand(side: str) -> HandLayout:
    right = side == "right"
    joints = names.RIGHT_HAND_JOINTS if right else names.LEFT_HAND_JOINTS
    _thumb_0, thumb_1, thumb_2, middle_0, middle_1, index_0, index_1 = joints
    x, y, z = GRASP_POINT_IN_RIGHT_TOOL
    return HandLayout(
        arm=f"{side}_arm",
        hand_body=names.RIGHT_HAND_BODY if right else names.LEFT_HAND_BODY,
        fingers={"thumb": (thumb_1, thumb_2), "index": (index_0, index_1), "middle": (middle_0, middle_1)},
        open_pose=_pose(joints, LEFT_HAND_GRASP_OPEN, right),
        closed_pose=_pose(joints, names.LEFT_HAND_CLOSED, right),
        palm_normal_in_tool=(0.0, 1.0 if right else -1.0, 0.0),
        grasp_point_in_tool=(x, y if right else -y, z),
    )


HANDS: Final = {"left_arm": _hand("left"), "right_arm": _hand("right")}
