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

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64

import robot_models
from nodes.common import spin_server
from nodes.parameters import ParameterSpec, declare
from nodes.sim_camera import tilt_topic
from nodes.sim_sensors import LATCHED
from robot_models.cameras import CameraLayout

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


class HeadNode(Node):
    """Points the head camera (see the module's text)."""

    def __init__(self, robot: str, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        camera = tilting_camera(robot)
        low, high = camera.tilt_range_rad
        declare(self, (
            ParameterSpec("robot", robot, "robot whose head is pointed", read_only=True),
            ParameterSpec("head_tilt_angle", float(camera.default_tilt_rad),
                          f"pitch of the head camera [rad]: 0.0 straight ahead, positive looks down (e.g. 0.2); "
                          f"the tilt mount allows {low:g} to {high:g}", low, high),
        ))
        self._camera = camera
        self._publisher = self.create_publisher(Float64, tilt_topic(camera.name), LATCHED)
        self.add_post_set_parameters_callback(self._on_parameters)
        self._send()
        self.get_logger().info(f"pointing {camera.name} of {robot}: head_tilt_angle {self._tilt():g} rad")

    def _tilt(self) -> float:
        return float(self.get_parameter("head_tilt_angle").value)

    def _send(self) -> None:
        self._publisher.publish(Float64(data=self._tilt()))

    def _on_parameters(self, changed: list[Parameter]) -> SetParametersResult:
        if any(p.name == "head_tilt_angle" for p in changed):
            self._send()
        return SetParametersResult(successful=True)


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``head_node`` (asks /sim for its robot)."""
    return spin_server(lambda robot, overrides: HeadNode(robot, parameter_overrides=overrides), NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
