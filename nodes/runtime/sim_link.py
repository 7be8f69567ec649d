"""How a node other than ``/sim`` relates to it: sim time by default, and the robot it simulates."""

from __future__ import annotations

from rcl_interfaces.srv import GetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from sim_ros.names import SIM_NODE

SIM_WAIT_LOG_S = 10.0  # a server waiting for /sim says so this often


def sim_time_overrides(args: list[str] | None) -> list[Parameter]:
    """``use_sim_time`` true unless the command line sets it (project convention: sim time everywhere)."""
    given = any("use_sim_time:=" in arg for arg in (args or []))
    return [] if given else [Parameter("use_sim_time", value=True)]


def robot_of_sim(node: Node, timeout_s: float = 30.0) -> tuple[str, str]:
    """Ask ``/sim`` which robot it simulates and in which scene (its read-only ``robot`` and ``scene``
    parameters; the scene is "" for the robot's default), waiting for /sim to come.

    A server started before the sim waits for it as long as it takes (Ctrl-C stops it), and says so
    every ``SIM_WAIT_LOG_S``. Call from ``main`` before spinning, never from a callback.

    Raises:
        RuntimeError: /sim is there but did not answer within ``timeout_s``.
    """
    client = node.create_client(GetParameters, f"{SIM_NODE}/get_parameters")
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        waited = 0.0
        while not client.wait_for_service(timeout_sec=SIM_WAIT_LOG_S):
            waited += SIM_WAIT_LOG_S
            node.get_logger().warning(f"waiting for /{SIM_NODE} ({waited:.0f} s so far): start the sim node, or pass "
                                      "-p robot:=NAME to serve without asking it")
        if waited:
            node.get_logger().info(f"/{SIM_NODE} is up after {waited:.0f} s")
        future = client.call_async(GetParameters.Request(names=["robot", "scene"]))
        executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        if not future.done() or len(future.result().values) != 2:
            raise RuntimeError(f"/{SIM_NODE} did not report its robot and scene parameters")
        robot, scene = future.result().values
        return str(robot.string_value), str(scene.string_value)
    finally:
        executor.remove_node(node)
        node.destroy_client(client)
