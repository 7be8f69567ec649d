"""The Panda's sensors and cameras as layouts (names, frames), without MuJoCo.

:mod:`robot_models.panda` puts them in the model; the registry hands them to nodes that need only
their names (``robot_models.sensors_of``, ``robot_models.cameras_of``).
"""

from __future__ import annotations

import robot_models.panda_constants as names
from robot_models.cameras import CameraLayout
from robot_models.sensors import SensorLayout, WristLayout

SENSORS = SensorLayout(wrists=(WristLayout("wrist", "arm", names.WRIST_FT_SITE, names.HAND_BODY),))
CAMERAS = (
    CameraLayout(name=names.SCENE_CAMERA, mj_camera=names.SCENE_CAMERA, optical_frame=names.SCENE_CAMERA_OPTICAL_FRAME,
                 fovy_deg=45.0),
)
