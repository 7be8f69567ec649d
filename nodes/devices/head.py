"""The ``/head`` node: ``head_tilt_angle`` [rad] points the G1's head camera, live.

The G1 has no neck: its head camera sits on a tilt mount whose servo runs in the simulation. This
node owns the tilt as a parameter (0.0 looks straight ahead, 0.2 is 0.2 rad down; the range is the
mount's) and sends each accepted value to ``/sim`` on a latched topic. The mount then turns under
physics, so the camera's image and its frames in /tf follow within a fraction of a second; the
measured angle is ``head_camera_tilt_joint`` on ``/joint_states``.
"""

from __future__ import annotations

import sys
from typing import Any

from std_msgs.msg import Float64

import robot_models
from nodes.devices.base import DeviceNode
from nodes.runtime.parameters import ParameterSpec
from nodes.runtime.serve import spin_server
from robot_models.cameras import CameraLayout
from sim_ros.names import camera_tilt_topic

NODE_NAME = "head"


def tilting_camera(robot: str) -> CameraLayout:
    """The robot's camera on a tilt mount.

    Raises:
        robot_models.RobotModelError: the robot has none.
    """
    for camera in robot_models.cameras_of(robot):
        if camera.tilt_joint is not None:
            return camera
    raise robot_models.RobotModelError(f"robot {robot!r} has no camera on a tilt mount (no head to point)")


class HeadNode(DeviceNode):
    """Points the head camera (see the module's text)."""

    def __init__(self, robot: str, **kwargs: Any) -> None:
        camera = tilting_camera(robot)
        low, high = camera.tilt_range_rad
        super().__init__(NODE_NAME, (
            ParameterSpec("robot", robot, "robot whose head is pointed", read_only=True),
            ParameterSpec("head_tilt_angle", float(camera.default_tilt_rad),
                          f"pitch of the head camera [rad]: 0.0 straight ahead, positive looks down (e.g. 0.2); "
                          f"the tilt mount allows {low:g} to {high:g}", low, high),
        ), **kwargs)
        self.relay(Float64, camera_tilt_topic(camera.name), ("head_tilt_angle",), lambda: Float64(data=self._tilt()))
        self.get_logger().info(f"pointing {camera.name} of {robot}: head_tilt_angle {self._tilt():g} rad")

    def _tilt(self) -> float:
        return float(self.get_parameter("head_tilt_angle").value)


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``head_node`` (asks /sim for its robot)."""
    return spin_server(lambda robot, _scene, overrides: HeadNode(robot, parameter_overrides=overrides), NODE_NAME, args,
                       events=True)


if __name__ == "__main__":
    sys.exit(main())
