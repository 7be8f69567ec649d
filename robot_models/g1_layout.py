"""The G1's sensors and cameras as layouts (names, frames, ranges, its battery pack), without MuJoCo.

:mod:`robot_models.g1` puts them in the model; the registry hands them to nodes that need only
their names (``robot_models.sensors_of``, ``robot_models.cameras_of``), which then import neither
mujoco nor the robot's meshes.
"""

from __future__ import annotations

import robot_models.g1_constants as names
from robot_models.cameras import CameraLayout
from robot_models.sensors import BatteryLayout, FootLayout, ImuLayout, SensorLayout, WristLayout

SENSORS = SensorLayout(
    imu=ImuLayout(frame=names.IMU_FRAME, body=names.ROOT_BODY, position_in_body=names.IMU_SITE_IN_PELVIS),
    feet=(FootLayout("left_foot", names.LEFT_SOLE_SITE, names.LEFT_FOOT_BODY, names.LEFT_SOLE_GEOM),
          FootLayout("right_foot", names.RIGHT_SOLE_SITE, names.RIGHT_FOOT_BODY, names.RIGHT_SOLE_GEOM)),
    wrists=(WristLayout("left_wrist", "left_arm", names.LEFT_WRIST_FT_SITE, names.LEFT_HAND_BODY),
            WristLayout("right_wrist", "right_arm", names.RIGHT_WRIST_FT_SITE, names.RIGHT_HAND_BODY)),
    # The G1's 13-cell Li-ion pack: 9 Ah at 48 V nominal, 54.6 V full; ~60 W for its computers at rest.
    battery=BatteryLayout(capacity_wh=432.0, idle_power_w=60.0, voltage_full_v=54.6, voltage_empty_v=42.0),
)

CAMERAS = (
    CameraLayout(
        name=names.HEAD_CAMERA,
        mj_camera=names.HEAD_CAMERA,
        optical_frame=names.HEAD_CAMERA_OPTICAL_FRAME,
        fovy_deg=42.5,  # the D435's colour camera: 69 x 42.5 deg
        tilt_joint=names.HEAD_CAMERA_TILT_JOINT,
        # Up to 0.5 rad up (the head's front cover); down to 0.9 rad, past the real D435's fixed 0.83 rad
        # (the floor from ~0.5 m ahead of the feet).
        tilt_range_rad=(-0.5, 0.9),
        default_tilt_rad=0.0,  # straight ahead
    ),
)
