"""How a node other than ``/sim`` relates to it: sim time by default, and the robot it simulates."""

from __future__ import annotations

from collections.abc import Sequence

from rcl_interfaces.srv import GetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.time_source import CLOCK_TOPIC
from rosgraph_msgs.msg import Clock

from sim_ros.names import SIM_NODE

SIM_WAIT_LOG_S = 10.0  # a server waiting for /sim says so this often


def sim_time_overrides(args: list[str] | None) -> list[Parameter]:
    """``use_sim_time`` true unless the command line sets it (project convention: sim time everywhere)."""
    given = any("use_sim_time:=" in arg for arg in (args or []))
    return [] if given else [Parameter("use_sim_time", value=True)]


def share_sim_clock(nodes: Sequence[Node]) -> None:
    """Drive the sim-time clocks of several nodes of one process from one ``/clock`` subscription.

    Each rclpy node on sim time subscribes to ``/clock`` on its own, so /sim writes every message to each of them and
    the process handles it once per node. Here the first node's subscription feeds every node's time source (as
    rclpy's would: each node keeps its clock, its ``use_sim_time`` parameter and what setting it does) and the
    nodes' own subscriptions are dropped. Does nothing unless two or more of the nodes are on sim time.
    """
    # rclpy keeps a node's TimeSource in Node._time_source (no public accessor in the pinned rclpy 7.1.6).
    sources = [node._time_source for node in nodes]
    if sum(source.ros_time_is_active for source in sources) < 2:
        return
    for source in sources:
        # Lets go of the node: no /clock subscription of its own, now or when use_sim_time is set again later
        # (its clocks and its parameter callback stay; the shared subscription below keeps their time).
        source.detach_node()

    def on_clock(message: Clock) -> None:
        for source in sources:
            source.clock_callback(message)

    nodes[0].create_subscription(Clock, CLOCK_TOPIC, on_clock, QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))


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
