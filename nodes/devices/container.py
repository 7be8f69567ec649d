"""``device_nodes``: every device node of a robot in one process, as a ROS 2 component container holds nodes.

The bring-up runs the devices this way: ``/power``, ``/hand_sensors``, ``/camera`` and ``/head`` (those the robot
has) keep their names, parameters, topics and services, and share one Python interpreter, one ROS context and
one DDS participant. Four processes cost ~0.35 CPU-s each to start (the interpreter, rclpy, the messages) and
each woke on every ``/clock`` message; one process pays that once. ``/power``, ``/camera`` and ``/head`` spin on
the events executor in the main thread; ``/hand_sensors`` (whose calibration service waits for readings) on a
:class:`~nodes.runtime.executor.ServerExecutor` in a second thread. Each node still runs alone as its own
console script (``power_node``, ``hand_sensors``, ``camera_node``, ``head_node``).
"""

from __future__ import annotations

import sys

from rclpy.parameter import Parameter

import robot_models
from nodes.devices import devices_of
from nodes.devices.camera import CameraNode
from nodes.devices.hand_sensors import HandSensorsNode
from nodes.devices.head import HeadNode
from nodes.devices.power import PowerNode
from nodes.runtime.serve import Served, spin_nodes

PROCESS_NAME = "devices"


def device_nodes(robot: str, overrides: list[Parameter]) -> list[Served]:
    """The device nodes of ``robot``, each with whether it spins on the events executor.

    Raises:
        robot_models.RobotModelError: the robot has no device.
    """
    built: list[Served] = []
    for name in devices_of(robot):
        if name == "power":
            built.append((PowerNode(robot, parameter_overrides=overrides), True))
        elif name == "hand_sensors":
            built.append((HandSensorsNode(robot, parameter_overrides=overrides), False))
        elif name == "camera":
            built.append((CameraNode(robot, parameter_overrides=overrides), True))
        else:
            built.append((HeadNode(robot, parameter_overrides=overrides), True))
    if not built:
        raise robot_models.RobotModelError(f"robot {robot!r} has no device (battery, wrist sensors or camera)")
    return built


def help_page(program: str) -> str:
    return f"""\
usage: {program} [-h] [--ros-args -p robot:=NAME ...]

Every device node of the robot of /sim in one process: /power (battery), /hand_sensors (wrist force/torque),
/camera and /head (the head camera and its tilt), those the robot has. Each node keeps its own parameters:
`ros2 param describe /power NAME`; set one node's start-up value with -p power:battery_low_threshold:=25.0.
"""


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``device_nodes`` (asks /sim for its robot unless ``-p robot:=NAME`` is given)."""
    return spin_nodes(lambda robot, _scene, overrides: device_nodes(robot, overrides), PROCESS_NAME, args, help_page)


if __name__ == "__main__":
    sys.exit(main())
