"""The ``/camera`` node: the camera driver's parameters (``camera_exposure``, ``camera_rate``, image size), live.

``/sim`` renders the robot's camera (``/<camera>/image_raw``, ``/<camera>/camera_info``; see
:mod:`nodes.sim.camera`) from the simulation's own state, because only it holds that state; this node
plays the camera driver: it owns the settings a driver exposes and sends each accepted change to
``/sim`` on a latched topic, so the next frame shows it. ``camera_exposure`` is the exposure time
[ms]: at 10 ms the image shows the scene as lit; longer brightens and saturates, shorter darkens.
"""

from __future__ import annotations

import sys
from typing import Any

import robot_models
from nodes.devices.base import DeviceNode
from nodes.runtime.parameters import ParameterSpec
from nodes.runtime.serve import spin_server
from sim_interfaces.msg import CameraSettings
from sim_ros.camera_settings import (
    DEFAULT_SETTINGS,
    EXPOSURE_RANGE_MS,
    HEIGHT_RANGE_PX,
    NOMINAL_EXPOSURE_MS,
    RATE_RANGE_HZ,
    WIDTH_RANGE_PX,
)
from sim_ros.names import camera_info_topic, camera_settings_topic, image_topic

NODE_NAME = "camera"
SETTINGS = ("camera_exposure", "camera_rate", "image_width", "image_height")


def parameters(robot: str, camera: str) -> tuple[ParameterSpec, ...]:
    exposure, rate, width, height = DEFAULT_SETTINGS
    return (
        ParameterSpec("robot", robot, "robot whose camera is driven", read_only=True),
        ParameterSpec("camera", camera, "the camera driven (its topics: /<camera>/image_raw, /<camera>/camera_info)",
                      read_only=True),
        ParameterSpec("camera_exposure", exposure, f"exposure time [ms]: {NOMINAL_EXPOSURE_MS:g} shows the scene as lit; "
                      "longer is brighter (saturating), shorter darker", *EXPOSURE_RANGE_MS),
        ParameterSpec("camera_rate", rate, "frames per second of sim time, while someone subscribes", *RATE_RANGE_HZ),
        ParameterSpec("image_width", width, "image width [px]", *WIDTH_RANGE_PX),
        ParameterSpec("image_height", height, "image height [px]", *HEIGHT_RANGE_PX),
    )


class CameraNode(DeviceNode):
    """Drives one camera of the robot of ``/sim`` (see the module's text)."""

    def __init__(self, robot: str, camera: str = "", **kwargs: Any) -> None:
        cameras = robot_models.cameras_of(robot)
        if not cameras:
            raise robot_models.RobotModelError(f"robot {robot!r} has no camera")
        names = [c.name for c in cameras]
        super().__init__(NODE_NAME, parameters(robot, camera or names[0]), **kwargs)
        self._camera = str(self.get_parameter("camera").value)
        if self._camera not in names:
            raise robot_models.RobotModelError(f"robot {robot!r} has no camera {self._camera!r}; its cameras: "
                                               f"{', '.join(names)}")
        self.relay(CameraSettings, camera_settings_topic(self._camera), SETTINGS, self._settings)
        self.get_logger().info(f"driving {self._camera} of {robot}: {image_topic(self._camera)}, "
                               f"{camera_info_topic(self._camera)}")

    def _settings(self) -> CameraSettings:
        value = self.get_parameter
        return CameraSettings(
            camera=self._camera, exposure_ms=float(value("camera_exposure").value), rate_hz=float(value("camera_rate").value),
            width=int(value("image_width").value), height=int(value("image_height").value))


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``camera_node`` (asks /sim for its robot)."""
    return spin_server(lambda robot, _scene, overrides: CameraNode(robot, parameter_overrides=overrides), NODE_NAME, args,
                       events=True)


if __name__ == "__main__":
    sys.exit(main())
