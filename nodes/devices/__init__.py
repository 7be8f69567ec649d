"""Device nodes: battery (/power), head, camera and hand sensors, each a small driver over a stream of /sim."""

from __future__ import annotations

import robot_models


def devices_of(robot: str) -> list[str]:
    """The device nodes ``robot`` has, by node name (no model is built, nothing of ROS is imported)."""
    sensors, cameras = robot_models.sensors_of(robot), robot_models.cameras_of(robot)
    names = ["power"] if sensors.battery is not None else []
    names += ["hand_sensors"] if sensors.wrists else []
    names += ["camera"] if cameras else []
    names += ["head"] if any(camera.tilt_joint is not None for camera in cameras) else []
    return names
