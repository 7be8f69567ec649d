"""Every MJCF name of the Franka Panda scene, in one place.

Joint and body names come from example-robot-data's ``panda.urdf``; the table, boxes, sites
and actuators are added by :mod:`robot_models.panda`.
"""

from __future__ import annotations

from typing import Final

ROBOT_NAME: Final = "panda"
URDF_RELATIVE_PATH: Final = "panda_description/urdf/panda.urdf"

ROOT_BODY: Final = "panda_link0"
ARM_JOINTS: Final = tuple(f"panda_joint{i}" for i in range(1, 8))
FINGER_JOINTS: Final = ("panda_finger_joint1", "panda_finger_joint2")
ALL_JOINTS: Final = ARM_JOINTS + FINGER_JOINTS
HAND_BODY: Final = "panda_hand"
LEFT_FINGER_BODY: Final = "panda_leftfinger"
RIGHT_FINGER_BODY: Final = "panda_rightfinger"
TCP_SITE: Final = "tcp"
TCP_IN_HAND: Final = (0.0, 0.0, 0.1034)
WRIST_FT_SITE: Final = "panda_wrist_ft"  # force/torque sensor at the flange, between the hand and link 7

TABLE_BODY: Final = "table"
TABLE_GEOM: Final = "table_top"
FLOOR_GEOM: Final = "floor"
# The arm's base stands on the table top at the world origin; the table top is z = 0.
TABLE_CENTER: Final = (0.45, 0.0, -0.375)
TABLE_HALF_SIZE: Final = (0.45, 0.55, 0.375)
TABLE_TOP_Z: Final = 0.0

BOX_NAMES: Final = ("box_0", "box_1", "box_2")
BOX_HALF_SIZE: Final = 0.02
BOX_MASS: Final = 0.05
BOX_HOME_POSITIONS: Final = ((0.5, -0.15, 0.02), (0.5, 0.0, 0.02), (0.5, 0.15, 0.02))
BOX_COLORS: Final = ((0.85, 0.2, 0.2, 1.0), (0.2, 0.7, 0.25, 1.0), (0.2, 0.35, 0.85, 1.0))

HOME_KEYFRAME: Final = "home"
HOME_ARM_QPOS: Final = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
FINGER_OPEN: Final = 0.04

# A fixed scene camera in front of the table, off to the robot's right, looking down at the boxes.
SCENE_CAMERA: Final = "scene_camera"  # ROS name (topics /scene_camera/...) and the MuJoCo camera's name
SCENE_CAMERA_OPTICAL_FRAME: Final = "scene_camera_optical_frame"
SCENE_CAMERA_POSITION: Final = (1.55, -0.7, 0.75)  # the lens, world frame [m]
SCENE_CAMERA_TARGET: Final = (0.4, 0.0, 0.15)  # the point on the optical axis at the image centre, world [m]

SCENES: Final = ("table",)
DEFAULT_SCENE: Final = "table"
