"""Every MJCF name of the Unitree G1 (29 DoF, with Dex3-1 hands) model, in one place.

Names come from example-robot-data's ``g1_29dof_with_hand_rev_1_0.urdf``; the sites, the floor, the
sole geoms and the hands' contact geoms are added by :mod:`robot_models.g1`.
"""

from __future__ import annotations

from typing import Final

ROBOT_NAME: Final = "g1"
URDF_RELATIVE_PATH: Final = "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf"

ROOT_BODY: Final = "pelvis"
TORSO_BODY: Final = "torso_link"
FLOOR_GEOM: Final = "floor"

LEFT_LEG_JOINTS: Final = (
    "left_hip_pitch_joint",
    "left_hip_roll_joint",
    "left_hip_yaw_joint",
    "left_knee_joint",
    "left_ankle_pitch_joint",
    "left_ankle_roll_joint",
)
RIGHT_LEG_JOINTS: Final = tuple(name.replace("left_", "right_") for name in LEFT_LEG_JOINTS)
KNEE_JOINTS: Final = ("left_knee_joint", "right_knee_joint")
WAIST_JOINTS: Final = ("waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint")
LEFT_ARM_JOINTS: Final = (
    "left_shoulder_pitch_joint",
    "left_shoulder_roll_joint",
    "left_shoulder_yaw_joint",
    "left_elbow_joint",
    "left_wrist_roll_joint",
    "left_wrist_pitch_joint",
    "left_wrist_yaw_joint",
)
RIGHT_ARM_JOINTS: Final = tuple(name.replace("left_", "right_") for name in LEFT_ARM_JOINTS)
BODY_JOINTS: Final = LEFT_LEG_JOINTS + RIGHT_LEG_JOINTS + WAIST_JOINTS + LEFT_ARM_JOINTS + RIGHT_ARM_JOINTS
# The Dex3-1 hands: thumb 3, middle 2, index 2 joints each; 0 is the open hand (fingers straight, thumb out).
LEFT_HAND_JOINTS: Final = (
    "left_hand_thumb_0_joint",  # the thumb's swing about the palm's y axis
    "left_hand_thumb_1_joint",
    "left_hand_thumb_2_joint",
    "left_hand_middle_0_joint",
    "left_hand_middle_1_joint",
    "left_hand_index_0_joint",
    "left_hand_index_1_joint",
)
RIGHT_HAND_JOINTS: Final = tuple(name.replace("left_", "right_") for name in LEFT_HAND_JOINTS)
HAND_JOINTS: Final = LEFT_HAND_JOINTS + RIGHT_HAND_JOINTS
HEAD_CAMERA_TILT_JOINT: Final = "head_camera_tilt_joint"  # the head camera's tilt mount (not in the URDF)
HEAD_JOINTS: Final = (HEAD_CAMERA_TILT_JOINT,)
ALL_JOINTS: Final = BODY_JOINTS + HAND_JOINTS + HEAD_JOINTS  # every actuated joint, in actuator order

# Hand poses [rad], in the order of LEFT_HAND_JOINTS. The right hand mirrors the left one about the
# sagittal plane: its joints turn the other way except the thumb's swing (HAND_MIRROR). Closed: a fist
# (the thumb folded across the index and middle fingers); the servos squeeze toward it with a bounded torque.
LEFT_HAND_OPEN: Final = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
LEFT_HAND_CLOSED: Final = (0.0, 0.9, 1.5, -1.4, -1.5, -1.4, -1.5)
HAND_MIRROR: Final = (1.0, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0)
HAND_OPEN_POSE: Final = {
    **dict(zip(LEFT_HAND_JOINTS, LEFT_HAND_OPEN, strict=True)),
    **{joint: sign * angle for joint, sign, angle in zip(RIGHT_HAND_JOINTS, HAND_MIRROR, LEFT_HAND_OPEN, strict=True)},
}
HAND_CLOSED_POSE: Final = {
    **dict(zip(LEFT_HAND_JOINTS, LEFT_HAND_CLOSED, strict=True)),
    **{joint: sign * angle for joint, sign, angle in zip(RIGHT_HAND_JOINTS, HAND_MIRROR, LEFT_HAND_CLOSED, strict=True)},
}
# Palms ready to squeeze a flat side (the tables scene's palm pads, robot_models.g1_palms): the fingers
# straight (behind the palm face) and the thumb swung up and curled along the palm's upper edge. Open,
# the thumb stands 11 cm proud of the palm face, straight into what the palm pushes; tucked, 4.8 cm
# (its root, at the palm face, keeps it at least 3 cm proud in any pose).
LEFT_HAND_PALM: Final = (-1.0, 1.0, 1.5, 0.0, 0.0, 0.0, 0.0)
HAND_PALM_POSE: Final = {
    **dict(zip(LEFT_HAND_JOINTS, LEFT_HAND_PALM, strict=True)),
    **{joint: sign * angle for joint, sign, angle in zip(RIGHT_HAND_JOINTS, HAND_MIRROR, LEFT_HAND_PALM, strict=True)},
}

LEFT_FOOT_BODY: Final = "left_ankle_roll_link"
RIGHT_FOOT_BODY: Final = "right_ankle_roll_link"
LEFT_SOLE_SITE: Final = "left_sole"
RIGHT_SOLE_SITE: Final = "right_sole"
LEFT_SOLE_GEOM: Final = "left_sole_box"
RIGHT_SOLE_GEOM: Final = "right_sole_box"
FEET_SITES: Final = (LEFT_SOLE_SITE, RIGHT_SOLE_SITE)
IMU_SITE: Final = "imu"

# The hand's first body: the URDF's palm link is fixed to the wrist's yaw link and fused into it.
LEFT_HAND_BODY: Final = "left_wrist_yaw_link"
RIGHT_HAND_BODY: Final = "right_wrist_yaw_link"
LEFT_HAND_SITE: Final = "left_hand"
RIGHT_HAND_SITE: Final = "right_hand"

STAND_KEYFRAME: Final = "stand"

# Sole box in the ankle-roll link frame [m]: centre and half sizes. The URDF's contact spheres sit
# at x in [-0.05, 0.12], y in +-0.03, z = -0.035 (bottom); a real G1 sole is about 0.20 x 0.07 m.
SOLE_CENTER_IN_FOOT: Final = (0.035, 0.0, -0.030)
SOLE_HALF_SIZE: Final = (0.100, 0.035, 0.005)
SOLE_SITE_IN_FOOT: Final = (0.035, 0.0, -0.035)
# The hand sites (the arms' end effectors) at the palm's centre, in the wrist yaw link's frame (x along
# the hand, toward the fingers); the palm spans x 0.042..0.129 m there, the fingers' roots are at x 0.119 m.
HAND_SITE_IN_WRIST: Final = (0.085, 0.0, 0.0)

# Body shell: primitive collision geoms that touch only the floor and obstacles (never each
# other, never the soles), so a fallen robot lies on the floor instead of sinking through it.
# (geom name, body, shape, size [m], from/centre [m], to [m] or None), in the body's frame; a
# capsule runs from -> to, a sphere sits at its centre. Standing or walking, none touches the floor.
SHELL_CONTYPE: Final = 2  # bit of the shell geoms; the floor and obstacles accept it (conaffinity)
Vec3 = tuple[float, float, float]
BODY_SHELL: Final[tuple[tuple[str, str, str, float, Vec3, Vec3 | None], ...]] = (
    ("pelvis_shell", "pelvis", "sphere", 0.08, (0.0, 0.0, 0.0), None),
    ("torso_shell", "torso_link", "capsule", 0.09, (0.0, 0.0, 0.06), (0.0, 0.0, 0.24)),
    ("head_shell", "torso_link", "sphere", 0.08, (0.0, 0.0, 0.40), None),
    ("left_thigh_shell", "left_hip_yaw_link", "capsule", 0.05, (0.0, 0.0, 0.04), (-0.078, 0.002, -0.177)),
    ("right_thigh_shell", "right_hip_yaw_link", "capsule", 0.05, (0.0, 0.0, 0.04), (-0.078, -0.002, -0.177)),
    ("left_shin_shell", "left_knee_link", "capsule", 0.045, (0.0, 0.0, 0.0), (0.0, 0.0, -0.19)),
    ("right_shin_shell", "right_knee_link", "capsule", 0.045, (0.0, 0.0, 0.0), (0.0, 0.0, -0.19)),
    ("left_upper_arm_shell", "left_shoulder_yaw_link", "capsule", 0.04, (0.0, 0.0, 0.0), (0.016, 0.0, -0.081)),
    ("right_upper_arm_shell", "right_shoulder_yaw_link", "capsule", 0.04, (0.0, 0.0, 0.0), (0.016, 0.0, -0.081)),
    ("left_forearm_shell", "left_elbow_link", "capsule", 0.035, (0.0, 0.0, 0.0), (0.1, 0.002, -0.01)),
    ("right_forearm_shell", "right_elbow_link", "capsule", 0.035, (0.0, 0.0, 0.0), (0.1, -0.002, -0.01)),
    ("left_hand_shell", "left_wrist_yaw_link", "sphere", 0.04, (0.06, 0.0, 0.0), None),
    ("right_hand_shell", "right_wrist_yaw_link", "sphere", 0.04, (0.06, 0.0, 0.0), None),
)

# The hands' contact geoms for grasping: primitives on the palm and the finger links, stiff and with
# friction (condim 4). They are of HAND_CONTYPE and accept contype 1 (conaffinity 1): they touch the
# floor, obstacles and any object of contype 1, never the body shell or each other.
# (geom name, body, shape, size [m], from/centre [m], to [m] or None) of the left hand, in the body's
# frame; a box's size is its half sizes, a capsule's its radius (first entry). The right hand mirrors
# them (y -> -y, names left_ -> right_). The palm box is the palm's extent (its grasping face is at
# y = -0.017 m on the left hand, the side the fingers close to); capsules run along each finger link.
HAND_CONTYPE: Final = 4
LEFT_HAND_PADS: Final[tuple[tuple[str, str, str, Vec3, Vec3, Vec3 | None], ...]] = (
    ("left_palm_pad", "left_wrist_yaw_link", "box", (0.0435, 0.021, 0.044), (0.085, 0.0035, 0.0), None),
    ("left_thumb_proximal_pad", "left_hand_thumb_1_link", "capsule", (0.011, 0.0, 0.0), (0.0, -0.008, 0.0),
     (0.0, -0.042, 0.0)),
    ("left_thumb_distal_pad", "left_hand_thumb_2_link", "capsule", (0.009, 0.0, 0.0), (0.0, -0.006, 0.0),
     (0.0, -0.040, 0.0)),
    ("left_middle_proximal_pad", "left_hand_middle_0_link", "capsule", (0.012, 0.0, 0.0), (0.008, 0.0, 0.0),
     (0.043, 0.0, 0.0)),
    ("left_middle_distal_pad", "left_hand_middle_1_link", "capsule", (0.009, 0.0, 0.0), (0.006, 0.0, 0.0),
     (0.041, 0.0, 0.0)),
    ("left_index_proximal_pad", "left_hand_index_0_link", "capsule", (0.012, 0.0, 0.0), (0.008, 0.0, 0.0),
     (0.043, 0.0, 0.0)),
    ("left_index_distal_pad", "left_hand_index_1_link", "capsule", (0.009, 0.0, 0.0), (0.006, 0.0, 0.0),
     (0.041, 0.0, 0.0)),
)


def _mirrored(point: Vec3) -> Vec3:
    return (point[0], -point[1], point[2])


RIGHT_HAND_PADS: Final = tuple(
    (name.replace("left_", "right_"), body.replace("left_", "right_"), shape, size, _mirrored(start),
     None if end is None else _mirrored(end))
    for name, body, shape, size, start, end in LEFT_HAND_PADS
)
HAND_PADS: Final = LEFT_HAND_PADS + RIGHT_HAND_PADS
IMU_SITE_IN_PELVIS: Final = (0.04525, 0.0, -0.08339)
IMU_FRAME: Final = "imu_in_pelvis"  # the URDF's link name of the pelvis IMU (a site here)
LEFT_WRIST_FT_SITE: Final = "left_wrist_ft"  # force/torque sensors between each hand and its arm
RIGHT_WRIST_FT_SITE: Final = "right_wrist_ft"

# Head camera on a tilt mount (the G1 has no neck). The mount's pivot is where the URDF puts the real
# G1's RealSense D435 (``d435_joint``: torso_link (0.0576, 0.0175, 0.4299), pitched 0.83 rad down,
# behind the head's front cover); the hinge pitches about the mount's y axis, + = looking down, 0 =
# level with the torso. The lens (the optical frame's origin) is at the front face of a 25 mm deep
# camera body centred on the pivot.
HEAD_CAMERA: Final = "head_camera"  # ROS name (topics /head_camera/...) and the MuJoCo camera's name
HEAD_CAMERA_LINK: Final = "head_camera_link"
HEAD_CAMERA_OPTICAL_FRAME: Final = "head_camera_optical_frame"
HEAD_CAMERA_GEOM: Final = "head_camera_housing"
D435_BODY: Final = "d435_link"  # the URDF's (jointless) frame of the real camera; the pivot's position is read from it
HEAD_LINK_BODY: Final = "head_link"  # the URDF's head (fused into torso_link); the mount's mass is taken out of it
HEAD_CAMERA_LENS_IN_MOUNT: Final = (0.0125, 0.0, 0.0)
HEAD_CAMERA_HOUSING_HALF_SIZE: Final = (0.0125, 0.045, 0.0125)  # a D435: 90 x 25 x 25 mm

# Scenes. "open": the robot on an empty floor. "course": a few static boxes to walk around,
# as (name, centre x, centre y, half size x, half size y, height) [m]. "tables": two tables and objects
# to carry (robot_models.g1_tables).
TABLES_SCENE: Final = "tables"
SCENES: Final = ("open", "course", TABLES_SCENE)
DEFAULT_SCENE: Final = "open"
COURSE_OBSTACLES: Final = (
    ("obstacle_wall", 1.6, 0.0, 0.15, 0.9, 0.8),
    ("obstacle_block", 3.2, 1.4, 0.4, 0.4, 0.6),
    ("obstacle_pillar", 3.0, -1.6, 0.25, 0.25, 1.2),
)
