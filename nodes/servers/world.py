"""A server follows the world ``/sim`` loads: it validates goals on the scene that runs (see :mod:`nodes.sim.world`)."""

from __future__ import annotations

import gc
from collections.abc import Callable

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node

import robot_models
from nodes.runtime.parameters import report_read_only
from robot_models import RobotSpec
from sim_ros.names import LATCHED, WORLD_TOPIC
from simulation_interfaces.msg import WorldResource


def follow_world(node: Node, robot: RobotSpec, on_scene: Callable[[RobotSpec], None]) -> None:
    """When ``/sim`` announces another scene of ``robot`` on ``~/world``, build its light model (objects, tables)
    and hand it to ``on_scene``; the node's read-only ``scene`` parameter then names it."""
    current = [robot.scene]

    def on_world(message: WorldResource) -> None:
        scene = message.name
        if not scene or scene == current[0] or scene not in robot_models.scenes_of(robot.name):
            return
        spec = robot_models.load(robot.name, scene, visuals=False)
        on_scene(spec)
        current[0] = scene
        gc.collect()  # the old model is in reference cycles: freed now, not at the next full collection
        if node.has_parameter("scene"):
            report_read_only(node, "scene", scene)  # it says what runs
        node.get_logger().info(f"/sim loaded the scene {scene!r}: goals are validated on it")

    node.create_subscription(WorldResource, WORLD_TOPIC, on_world, LATCHED, callback_group=MutuallyExclusiveCallbackGroup())
