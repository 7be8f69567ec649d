"""The G1's walking facts for :mod:`sim_bridge.locomotion`: its names, walking crouch, step geometry and limits."""

from __future__ import annotations

import math
from types import MappingProxyType
from typing import Final

from robot_models import g1_constants as names
from robot_models.biped import BipedDescription, StepLimits
from robot_models.spec import WalkingLimits

WALKING: Final = WalkingLimits(
    speed_range_mps=(0.05, 0.8),  # the top speed is the gait's max_forward_speed
    default_speed_mps=0.3,
    max_walk_distance_m=100.0,
    fall_height_m=0.45,  # the pelvis stands at 0.76 m in the stand keyframe
    fall_tilt_rad=math.radians(50.0),
)

LEG_JOINTS: Final = names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS
# Walking posture: a deeper crouch than the stand keyframe gives more reach [rad], by joint kind.
WALK_CROUCH: Final = {"hip_pitch": -0.5, "knee": 1.0, "ankle_pitch": -0.5}

BIPED: Final = BipedDescription(
    base_body=names.ROOT_BODY,
    torso_body=names.TORSO_BODY,
    foot_bodies=(names.LEFT_FOOT_BODY, names.RIGHT_FOOT_BODY),
    sole_sites=(names.LEFT_SOLE_SITE, names.RIGHT_SOLE_SITE),
    sole_center_in_foot=names.SOLE_CENTER_IN_FOOT,
    sole_half_size=names.SOLE_HALF_SIZE,
    leg_joints=LEG_JOINTS,
    knee_joints=names.KNEE_JOINTS,
    waist_joints=names.WAIST_JOINTS,
    # The arms, the hands and the head camera's tilt mount stay on their position servos while walking.
    servo_joints=names.LEFT_ARM_JOINTS + names.RIGHT_ARM_JOINTS + names.HAND_JOINTS + names.HEAD_JOINTS,
    walk_posture=MappingProxyType({
        joint: angle for joint in LEG_JOINTS for kind, angle in WALK_CROUCH.items() if joint.endswith(f"_{kind}_joint")
    }),
    stand_keyframe=names.STAND_KEYFRAME,
    half_step_width_m=0.1185,
    reach_forward_m=(-0.20, 0.45),
    reach_outward_m=(0.15, 0.48),
    steps=StepLimits(forward_m=0.40, backward_m=0.18, lateral_m=0.18, turn_rad=0.45, advance_rate_mps=1.20),
    fall_height_m=WALKING.fall_height_m,
    fall_tilt_rad=WALKING.fall_tilt_rad,
)
