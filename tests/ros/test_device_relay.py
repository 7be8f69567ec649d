"""A device node's accepted change reaches a running /sim: the answer waits until /sim listens on the settings topic.

A lock-stepped scenario tilting the head right after a bring-up started once ran its 3 s of sim time before /sim
had matched /head's tilt topic (slow discovery on a loaded machine), so the mount never moved. Here /head runs in
this process, with a node named ``sim`` beside it (the same participant: each knows the other at once) whose
subscription is made only after the change was asked for, and is volatile: it gets the tilt only if /head
published it after the match.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from std_msgs.msg import Float64

import robot_models
from nodes.devices.base import SIM_MATCH_WALL_S
from nodes.devices.head import HeadNode
from sim_ros.names import camera_tilt_topic

WAIT_S = 30.0  # [s] wall: a deadline for what must happen (never reached when it works)


def _tilt_topic() -> str:
    return camera_tilt_topic(next(c.name for c in robot_models.cameras_of("g1") if c.tilt_joint is not None))


def _set_tilt_in_a_thread(head: HeadNode, angle: float) -> tuple[threading.Thread, list[bool]]:
    answers: list[bool] = []
    thread = threading.Thread(target=lambda: answers.append(
        head.set_parameters([Parameter("head_tilt_angle", value=angle)])[0].successful))
    thread.start()
    return thread, answers


@pytest.fixture
def ros() -> Iterator[tuple[rclpy.Context, list[Node]]]:
    """A context of the test's own, and a list for the nodes made in it.

    The nodes are destroyed before the context ends. A node left to the garbage collector keeps its latched
    writer in the graph, and the next test's listener got that test's tilt too (one run in seventeen).
    """
    context = rclpy.Context()
    rclpy.init(context=context)
    nodes: list[Node] = []
    yield context, nodes
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=context)


def test_a_change_waits_for_a_running_sim_to_listen_and_then_reaches_it(ros):
    context, nodes = ros
    head = HeadNode("g1", context=context)
    sim = Node("sim", context=context)
    nodes += [head, sim]
    thread, answers = _set_tilt_in_a_thread(head, 0.3)
    thread.join(timeout=0.2 * SIM_MATCH_WALL_S)
    assert thread.is_alive(), "the change was answered while /sim did not listen yet"

    heard: list[float] = []
    sim.create_subscription(Float64, _tilt_topic(), lambda msg: heard.append(msg.data), QoSProfile(depth=10))
    thread.join(timeout=WAIT_S)
    assert answers == [True]
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(sim)
    executor.spin_until_future_complete(_when(lambda: 0.3 in heard, executor), timeout_sec=WAIT_S)
    assert 0.3 in heard, f"/sim (subscribed after the change was asked for) did not get it: {heard}"


def test_without_a_running_sim_a_change_is_answered_at_once_and_kept_for_a_sim_that_starts_later(ros):
    context, nodes = ros
    head = HeadNode("g1", context=context)
    nodes.append(head)
    thread, answers = _set_tilt_in_a_thread(head, 0.2)
    thread.join(timeout=WAIT_S)
    assert answers == [True]
    later = Node("later_listener", context=context)  # latched: a /sim starting later takes the latest value
    nodes.append(later)
    heard: list[float] = []
    later.create_subscription(Float64, _tilt_topic(), lambda msg: heard.append(msg.data),
                              QoSProfile(depth=1, durability=rclpy.qos.DurabilityPolicy.TRANSIENT_LOCAL))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(later)
    executor.spin_until_future_complete(_when(lambda: bool(heard), executor), timeout_sec=WAIT_S)
    assert heard == [0.2], "the latest value, once (only this test's /head runs: the last test's nodes are gone)"


def _when(condition, executor: SingleThreadedExecutor) -> rclpy.task.Future:
    """A future done once ``condition()`` holds, looked at every 10 ms of wall time by a timer of the executor's node."""
    future = rclpy.task.Future()

    def check() -> None:
        if condition() and not future.done():
            future.set_result(True)

    next(iter(executor.get_nodes())).create_timer(0.01, check)
    return future
