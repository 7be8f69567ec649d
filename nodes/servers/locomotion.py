"""The ``/locomotion`` node: Walk and NavigateToPose action servers and the /reset_pose service for the G1.

Both run as skills inside ``/sim``'s control step (:mod:`sim_bridge.skills.locomotion`): this node
validates, relays and owns the parameters. ``walking_speed`` sets the pace of both actions; a change
reaches running goals at once. One goal on the legs at a time: a new goal preempts the running one.
"""

from __future__ import annotations

import sys
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

import robot_models
from nodes.runtime.parameters import ParameterSpec, StartupError, declare
from nodes.runtime.serve import SCENE_PARAMETER, spin_server
from nodes.runtime.startup import help_text
from nodes.servers.actions import LOCOMOTION_ACTIONS
from nodes.servers.reset_pose import ResetPoseService
from nodes.servers.server import end_goals_before_exit, skill_servers

NODE_NAME = "locomotion"
ACTIONS = LOCOMOTION_ACTIONS  # skill -> the action that serves it
SETTINGS = ("walking_speed", "max_yaw_rate", "obstacle_detection_threshold", "robot_radius", "xy_goal_tolerance",
            "yaw_goal_tolerance", "replan_distance")


def parameters(robot: robot_models.RobotSpec) -> tuple[ParameterSpec, ...]:
    """The node's parameters; the walking speed's default and range come from the robot's spec."""
    assert robot.walking is not None
    low, high = robot.walking.speed_range_mps
    return (
        ParameterSpec("walking_speed", robot.walking.default_speed_mps,
                      "pace of Walk and NavigateToPose [m/s]; changes apply to running goals", low, high),
        ParameterSpec("max_yaw_rate", 0.6, "turning rate limit while navigating [rad/s]", 0.1, 1.0),
        ParameterSpec("obstacle_detection_threshold", 0.15, "clearance kept from obstacles beyond the robot radius [m]",
                      0.0, 1.0),
        ParameterSpec("robot_radius", 0.30, "footprint radius used to inflate obstacles [m]", 0.1, 1.0),
        ParameterSpec("xy_goal_tolerance", 0.15, "NavigateToPose position tolerance [m]", 0.03, 1.0),
        ParameterSpec("yaw_goal_tolerance", 0.15, "NavigateToPose heading tolerance [rad]", 0.03, 1.0),
        ParameterSpec("feedback_rate", 5.0, "action feedback rate [Hz of sim time]", 1.0, 50.0),
        ParameterSpec("replan_distance", 0.6, "NavigateToPose replans when this far off the path [m]", 0.2, 3.0),
    )


class LocomotionServer(Node):
    """Serves ``/walk`` and ``/navigate_to_pose`` for the G1 of ``/sim``."""

    def __init__(self, robot: str, scene: str = "", **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        # The scene's objects: goals may name them as frames. The light model: goals are validated, not simulated.
        spec = robot_models.load(robot, scene or None, visuals=False)
        if spec.walking is None:
            walkers = [name for name in robot_models.ROBOT_NAMES if robot_models.walks(name)]
            raise StartupError(f"robot {robot!r} cannot walk; walking robots: {', '.join(walkers)}")
        declare(self, (ParameterSpec("robot", robot, "robot whose legs are served", read_only=True),
                       ParameterSpec("scene", scene, "scene of /sim (its objects); empty = the robot's default", read_only=True),
                       *parameters(spec)))
        self._servers = skill_servers(self, spec, ACTIONS,
                                      self._settings, lambda: 1.0 / self._param("feedback_rate"))
        self.add_post_set_parameters_callback(self._on_parameters)
        self._reset_pose = ResetPoseService(self)  # /reset_pose: the ResetPose skill, answered when the pose is reached
        self.get_logger().info(f"serving /walk, /navigate_to_pose and /reset_pose for {robot}")

    def _param(self, name: str) -> float:
        return float(self.get_parameter(name).value)

    def _settings(self) -> dict[str, float]:
        return {name: self._param(name) for name in SETTINGS}

    def _on_parameters(self, changed: list[Parameter]) -> SetParametersResult:
        if any(p.name in SETTINGS for p in changed):
            for server in self._servers.values():
                server.update_settings()
        return SetParametersResult(successful=True)


def help_page(program: str) -> str:
    """``locomotion_server --help``: what it serves and its parameters (ranges of the G1)."""
    robot = robot_models.load(robot_models.G1, visuals=False)
    specs = (ParameterSpec("robot", "", "robot of the running /sim (empty = ask /sim)", read_only=True), SCENE_PARAMETER,
             *parameters(robot))
    return help_text(program, NODE_NAME, """\
The /locomotion node: the Walk (/walk) and NavigateToPose (/navigate_to_pose) action servers of a
walking robot, and the /reset_pose service (std_srvs/Trigger). All run as skills inside /sim's
control step; start the sim node first (it waits for /sim up to 30 s and asks it which robot it
simulates).""", specs)


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``locomotion_server`` (asks /sim for its robot)."""
    return spin_server(lambda robot, scene, overrides: LocomotionServer(robot, scene, parameter_overrides=overrides),
                       NODE_NAME, args, help_page, end_goals_before_exit)


if __name__ == "__main__":
    sys.exit(main())
