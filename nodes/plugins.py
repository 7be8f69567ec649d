"""ROS side of the in-loop controllers: routes /cmd_vel and arm commands into the simulation.

The controllers themselves live in ``sim_bridge`` and run inside the control step; this module
only converts messages, applies the command timeout, and publishes the controllers' state.
"""

from __future__ import annotations

import threading

from geometry_msgs.msg import Twist
from rclpy.node import Node
from rclpy.parameter import Parameter

from sim_bridge import Simulation


class InLoopPlugins:
    """Connects the simulation's controller slots to topics, for one robot.

    Args:
        node: the sim node (publishers and subscriptions are created on it).
        sim: the simulation whose controller slots are used.
        lock: the lock that guards ``sim`` (held by the caller in the ``before_step`` and
            ``publish_state`` hooks; taken here by message callbacks).
    """

    def __init__(self, node: Node, sim: Simulation, lock: threading.RLock) -> None:
        self._node = node
        self._sim = sim
        self._lock = lock
        self._cmd_vel = (0.0, 0.0, 0.0)
        self._cmd_vel_time = -float("inf")
        self._warned_no_locomotion = False

    def on_cmd_vel(self, msg: Twist) -> None:
        with self._lock:
            self._cmd_vel = (msg.linear.x, msg.linear.y, msg.angular.z)
            self._cmd_vel_time = self._sim.time
        if not self._warned_no_locomotion:
            self._warned_no_locomotion = True
            self._node.get_logger().warning(
                f"/cmd_vel received but robot {self._sim.robot.name!r} has no locomotion controller; ignored"
            )

    def before_step(self, now: float) -> None:
        """Called under the lock before each stretch of stepping."""

    def publish_state(self, now: float) -> None:
        """Called under the lock when controller state topics are due."""

    def on_parameters(self, parameters: list[Parameter]) -> None:
        """Called under the lock after parameters of the sim node changed."""

    def on_reset(self) -> None:
        self._cmd_vel = (0.0, 0.0, 0.0)
        self._cmd_vel_time = -float("inf")

    def on_fault(self, reason: str) -> None:
        self.on_reset()
